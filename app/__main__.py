"""``python -m app`` is the ``c2n`` command."""

from app.cli import entry

entry()
