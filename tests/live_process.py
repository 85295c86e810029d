"""`c2n live` in a child process, for the tests that stop, kill or hang it up."""

import signal
import subprocess
import sys
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import IO

import pytest

from tests.simulated import REPO


def foreground() -> None:
    """A child's ``preexec_fn``: the signals a terminal sends at their defaults and none blocked,
    whatever started the suite — `nohup` and a shell's background job pass SIGHUP and SIGINT on
    ignored, and a child would then run on where a test stops it by them."""
    for name in ("SIGINT", "SIGTERM", "SIGHUP"):
        if hasattr(signal, name):
            signal.signal(getattr(signal, name), signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_SETMASK, set())


def _foreground_then(before: Callable[[], object] | None) -> Callable[[], None]:
    def preexec() -> None:
        foreground()
        if before is not None:
            before()

    return preexec


def start_live(
    tmp_path: Path,
    raw_format: str,
    before: Callable[[], object] | None = None,
    stdout: IO[bytes] | int = subprocess.DEVNULL,
) -> tuple[subprocess.Popen[bytes], Path, Path]:
    """`c2n live` in a child process (``tests/live_child.py``) with its own traffic: the child,
    its record folder and the file of frames it sent. ``before`` runs in the child before it
    starts (a signal ignored as `nohup` does)."""
    record, sent = tmp_path / "sessions", tmp_path / "sent.txt"
    child = subprocess.Popen(
        [
            sys.executable,
            str(REPO / "tests" / "live_child.py"),
            f"kill-{uuid.uuid4().hex}",
            str(record),
            str(sent),
            raw_format,
        ],
        cwd=REPO,
        stdout=stdout,
        stderr=subprocess.PIPE,
        preexec_fn=_foreground_then(before),
    )
    return child, record, sent


def wait_for_lines(path: Path, n: int, child: subprocess.Popen[bytes], timeout_s: float = 60.0) -> None:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if path.exists() and path.read_bytes().count(b"\n") >= n:
            return
        assert child.poll() is None, child.stderr.read().decode() if child.stderr else ""
        time.sleep(0.02)
    pytest.fail(f"the live process sent fewer than {n} frames in {timeout_s} s")
