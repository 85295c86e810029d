"""Where the real third-party test data lives (``data/real/``: public logs and DBCs).

The files are used where they are and never copied into the repository. Tests that need them
skip themselves, with one reason, only when no data folder is found at all; a folder that exists
but lacks a file the tests expect is a failure, not a skip.
"""

import os
from pathlib import Path

import pytest

ENV_VAR = "C2N_REAL_DATA"
REPO_ROOT = Path(__file__).resolve().parent.parent
SKIP_REASON = f"third-party data not found (set {ENV_VAR})"


def find_real_data() -> Path | None:
    """The first existing of $C2N_REAL_DATA, <repo>/../shared/data/real, /work/shared/data/real."""
    candidates: list[Path] = []
    env = os.environ.get(ENV_VAR)
    if env:
        candidates.append(Path(env).expanduser())
    candidates += [REPO_ROOT.parent / "shared" / "data" / "real", Path("/work/shared/data/real")]
    return next((path.resolve() for path in candidates if path.is_dir()), None)


REAL_DATA: Path | None = find_real_data()

needs_real_data = pytest.mark.skipif(REAL_DATA is None, reason=SKIP_REASON)
"""Mark a test (or a whole module with ``pytestmark``) that reads the real data."""


def real_path(*parts: str) -> Path:
    """A file of the real data: skips if there is no data folder, fails if the file is missing."""
    if REAL_DATA is None:
        pytest.skip(SKIP_REASON)
    path = REAL_DATA.joinpath(*parts)
    if not path.exists():
        pytest.fail(f"{path}: missing from the real data folder {REAL_DATA} (see its README.md)")
    return path
