"""The console goes away — the terminal closed, an ssh session dropped, a pipe's reader gone, a
full disk behind `> out.txt` — and the work it describes goes on: a live session records to its
end and is finished; the words that could not be shown are one line, not a traceback."""

import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import can
import pytest

from app.cli import main
from app.sim.simulated_drive import write_drive
from tests.live_process import foreground, start_live, wait_for_lines
from tests.simulated import cached_drive


def _stopped(child: "subprocess.Popen[bytes]", sent: Path, signum: int) -> int:
    try:
        wait_for_lines(sent, 2000, child)
        child.send_signal(signum)
        return child.wait(timeout=30)
    finally:
        child.kill()
        child.wait()


def _session(record: Path, raw_format: str) -> tuple[dict[str, Any], list[can.Message], Path]:
    [session] = list(record.glob("20*"))
    summary = json.loads((session / "summary.json").read_text())
    return summary, list(can.LogReader(session / f"frames{raw_format}")), session


def test_a_closed_terminal_finishes_the_session(tmp_path: Path) -> None:
    """SIGHUP (the terminal window closed, an ssh session dropped) ends `c2n live` as Ctrl-C
    does: every file finished, an ASC's last line written, the summary counting what is on the
    disk (it was killed: no summary, the ASC without its end)."""
    child, record, sent = start_live(tmp_path, ".asc")
    assert _stopped(child, sent, signal.SIGHUP) == 0
    summary, recorded, session = _session(record, ".asc")
    assert summary["frames"]["total"] == len(recorded) >= 2000
    assert (session / "frames.asc").read_text().rstrip().endswith("End TriggerBlock")


def test_under_nohup_a_hangup_does_not_end_the_session(tmp_path: Path) -> None:
    """`nohup c2n live …`: a hangup inherited ignored is the user's word that the session outlives
    its terminal — it goes on recording (it ended at the hangup)."""
    child, record, sent = start_live(
        tmp_path, ".log", before=lambda: signal.signal(signal.SIGHUP, signal.SIG_IGN)
    )
    try:
        wait_for_lines(sent, 1000, child)
        child.send_signal(signal.SIGHUP)
        wait_for_lines(sent, 3000, child)  # still running: it fails here if the hangup ended it
    except BaseException:
        child.kill()
        child.wait()
        raise
    assert _stopped(child, sent, signal.SIGTERM) == 0
    summary, recorded, _ = _session(record, ".log")
    assert summary["frames"]["total"] == len(recorded) >= 3000


def test_a_console_that_fails_does_not_stop_the_recording(tmp_path: Path) -> None:
    """Standard output on a full disk (`/dev/full`: every write fails, as a vanished terminal's
    do): the session records until it is stopped, its summary says the console went away, the
    exit code is 1. It failed at its first line with a traceback, nothing recorded."""
    with open("/dev/full", "wb") as full:
        child, record, sent = start_live(tmp_path, ".log", stdout=full)
        code = _stopped(child, sent, signal.SIGTERM)
    stderr = child.stderr.read().decode() if child.stderr else ""
    assert code == 1, stderr
    assert "Traceback" not in stderr
    assert "standard output: cannot write (No space left on device)" in stderr
    summary, recorded, _ = _session(record, ".log")
    assert summary["frames"]["total"] == len(recorded) >= 2000
    assert any("the console went away during the session" in w for w in summary["warnings"])


class _Failing:
    """A standard output whose writes fail with ``error``."""

    encoding = "utf-8"

    def __init__(self, error: int) -> None:
        self.error = error

    def write(self, text: str) -> int:
        raise OSError(self.error, "failed")

    def flush(self) -> None:
        pass

    def isatty(self) -> bool:
        return False


@pytest.mark.parametrize(("error", "code", "said"), [(errno.EIO, 1, True), (errno.EPIPE, 0, False)])
def test_analyze_says_once_that_its_words_were_lost(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    error: int,
    code: int,
    said: bool,
) -> None:
    """`c2n analyze d.log > /dev/full`, or on a terminal gone: the analysis ends, exit 1 and one
    line on stderr (a traceback). `| head -1`: the reader wanted no more — no word, the exit
    code the analysis's. The --json file is written either way."""
    log = tmp_path / "d.log"
    write_drive(cached_drive("constant_radius", 7), log)
    out = tmp_path / "s.json"
    monkeypatch.setattr(sys, "stdout", _Failing(error))
    assert main(["analyze", str(log), "--json", str(out)]) == code
    assert json.loads(out.read_text())["c2n"] is not None
    stderr = capsys.readouterr().err
    assert ("c2n: error: standard output: cannot write" in stderr) is said
    assert "Traceback" not in stderr


def test_json_to_a_standard_output_closed_from_the_start(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """`c2n analyze d.log --json - 1>&-`: Python has no sys.stdout; one line, exit 1 (it was an
    AttributeError's traceback)."""
    log = tmp_path / "d.log"
    write_drive(cached_drive("constant_radius", 7), log)
    monkeypatch.setattr(sys, "stdout", None)
    assert main(["analyze", str(log), "--json", "-"]) == 1
    assert "standard output is closed" in capsys.readouterr().err


def test_a_closed_terminal_ends_a_demo_and_removes_its_folder(tmp_path: Path) -> None:
    """`c2n demo` hung up: its temporary folder goes, as on Ctrl-C (it was left behind)."""
    child = subprocess.Popen(
        [sys.executable, "-m", "app", "demo", "--speedup", "1"],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        preexec_fn=foreground,
        env={**os.environ, "TMPDIR": str(tmp_path)},
    )
    try:
        deadline = time.monotonic() + 60
        while not list(tmp_path.glob("c2n-demo-*")) and time.monotonic() < deadline:
            assert child.poll() is None
            time.sleep(0.05)
        assert list(tmp_path.glob("c2n-demo-*"))
        child.send_signal(signal.SIGHUP)
        child.wait(timeout=30)
    finally:
        child.kill()
        child.wait()
    assert not list(tmp_path.glob("c2n-demo-*"))
