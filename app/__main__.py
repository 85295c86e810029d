"""``python -m app`` is the ``c2n`` command."""

import sys

from app.cli import main

sys.exit(main())
