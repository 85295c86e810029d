"""Recording in `c2n live`: nothing lost on a clean stop or a crash."""

import io
import json
import os
import shutil
import signal
import time
from pathlib import Path

import can
import pytest

from app.cli import main
from app.config import load_config
from app.sinks.recorder import SessionRecorder
from tests.live_process import start_live, wait_for_lines
from tests.simulated import cached_drive

FLUSH_DEADLINE_S = 0.1  # every frame sent this long before a crash must be on disk


@pytest.mark.parametrize("raw_format", [".log", ".asc", ".blf"])
def test_sigkill_loses_no_frame_sent_100ms_before_it(tmp_path: Path, raw_format: str) -> None:
    child, record, sent_file = start_live(tmp_path, raw_format)
    try:
        wait_for_lines(sent_file, 3000, child)
        killed_at = time.monotonic()
        os.kill(child.pid, signal.SIGKILL)
    finally:
        child.kill()
        child.wait()
    sent_times = [float(line.split()[1]) for line in sent_file.read_text().splitlines() if " " in line]
    must_have = sum(t < killed_at - FLUSH_DEADLINE_S for t in sent_times)
    [session] = list(record.glob("20*"))
    recorded = list(can.LogReader(session / f"frames{raw_format}"))
    expected = cached_drive("constant_radius", 41, 15.1).messages
    assert must_have >= 2500
    assert len(recorded) >= must_have
    # what is on disk is exactly the frames sent, in order: nothing lost, nothing garbled
    got = [(m.arbitration_id, bytes(m.data)) for m in recorded]
    assert got == [(m.arbitration_id, bytes(m.data)) for m in expected[: len(recorded)]]
    assert (session / "config" / "mondeo.toml").exists()
    assert (session / "events.csv").read_text().startswith("t,event,")


def test_analyze_accepts_the_log_of_a_killed_session(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    child, record, sent_file = start_live(tmp_path, ".log")
    try:
        wait_for_lines(sent_file, 2000, child)
        os.kill(child.pid, signal.SIGKILL)
    finally:
        child.kill()
        child.wait()
    [session] = list(record.glob("20*"))
    recorded = list(can.LogReader(session / "frames.log"))
    out = tmp_path / "summary.json"
    assert main(["analyze", str(session / "frames.log"), "--json", str(out)]) == 0
    summary = json.loads(out.read_text())
    assert summary["frames"]["total"] == len(recorded) > 0
    assert not any("stopped after frame" in w for w in summary["warnings"])


def stop_live(tmp_path: Path, raw_format: str, signum: int) -> tuple[Path, list[can.Message]]:
    """Start `c2n live`, send ``signum`` once 2000 frames were sent; check it ended with exit code 0
    and that the summary counts exactly the frames recorded (at least 2000). The session folder
    and the recorded frames."""
    child, record, sent_file = start_live(tmp_path, raw_format)
    try:
        wait_for_lines(sent_file, 2000, child)
        child.send_signal(signum)
        assert child.wait(timeout=30) == 0
    finally:
        child.kill()
        child.wait()
    [session] = list(record.glob("20*"))
    summary = json.loads((session / "summary.json").read_text())
    recorded = list(can.LogReader(session / f"frames{raw_format}"))
    assert summary["frames"]["total"] == len(recorded) >= 2000
    return session, recorded


def test_sigterm_finishes_every_file(tmp_path: Path) -> None:
    session, recorded = stop_live(tmp_path, ".blf", signal.SIGTERM)
    with can.BLFReader(session / "frames.blf") as reader:  # the header is finished too
        assert reader.object_count == len(recorded)


@pytest.mark.parametrize("raw_format", [".log", ".asc", ".blf"])
@pytest.mark.parametrize(
    "channel",
    ["can0", "vcan70000", "kill-3f9a1234567890", 3, None, "Serial interface: loop://", "my chan", "", " "],
)
def test_any_channel_name_records_every_frame(tmp_path: Path, raw_format: str, channel: object) -> None:
    """A bus's channel name ends up in the log; one whose number does not fit the format's channel
    field (BLF's is 16 bits) must not stop the recording, and one with spaces (python-can's serial
    interface names its frames' channel by its description) must not make a candump log
    unreadable."""
    config = load_config()
    recorder = SessionRecorder(tmp_path / "session", config, raw_format)
    sent = cached_drive("constant_radius", 41, 15.1).messages[:500]
    for message in sent:
        recorder.on_frame(
            can.Message(
                timestamp=message.timestamp,
                arbitration_id=message.arbitration_id,
                data=message.data,
                is_extended_id=message.is_extended_id,
                channel=channel,
            )
        )
    recorder.close()
    recorded = list(can.LogReader(recorder.raw_path))
    assert [(m.arbitration_id, bytes(m.data)) for m in recorded] == [
        (m.arbitration_id, bytes(m.data)) for m in sent
    ]


def test_candump_lines_are_python_cans_own_bytes(tmp_path: Path) -> None:
    """The recorder's candump writer writes what python-can's CanutilsLogWriter writes, for every
    kind of frame: 11- and 29-bit, rx and tx, channel names, numbers and none, error, remote and
    CAN FD frames, and a timestamp before the first (python-can writes the first one's time)."""
    frames = [
        can.Message(timestamp=100.25, arbitration_id=0x7E5, data=bytes(range(8)), channel="can0"),
        can.Message(timestamp=100.5, arbitration_id=0x1ABCDEF, is_extended_id=True, data=b"\x01", channel=1),
        can.Message(timestamp=100.75, arbitration_id=0x123, data=b"", channel=None, is_rx=False),
        can.Message(timestamp=101.0, arbitration_id=0x7E5, data=bytes(8), channel="7"),
        can.Message(timestamp=99.0, arbitration_id=0x7E5, data=bytes(8), channel="vcan0"),  # time went back
        can.Message(timestamp=101.5, is_error_frame=True, channel="can0"),
        can.Message(timestamp=102.0, arbitration_id=0x7E0, is_remote_frame=True, dlc=8, channel="can0"),
        can.Message(timestamp=102.5, arbitration_id=0x300, is_fd=True, bitrate_switch=True, data=bytes(12)),
        can.Message(timestamp=103.123456789, arbitration_id=0x7E5, data=b"\xff" * 8, channel="can0"),
    ]
    recorder = SessionRecorder(tmp_path / "session", load_config(), ".log")
    for message in frames * 3:  # the second and third times through the cached heads
        recorder.on_frame(message)
    recorder.close()
    reference = io.StringIO()
    writer = can.CanutilsLogWriter(reference)
    for message in frames * 3:
        writer.on_message_received(message)
    assert recorder.raw_path.read_text() == reference.getvalue()
    assert reference.getvalue().count("\n") == 27


@pytest.mark.parametrize("raw_format", [".log", ".blf"])
def test_a_session_folder_deleted_while_recording_is_said_and_not_made_again(
    tmp_path: Path, raw_format: str
) -> None:
    """`rm -rf c2n-sessions/*` while a session records: the recorder says its log was deleted (the
    session said "saved in" it, and its summary made the folder again, holding nothing but a
    summary of frames that were gone)."""
    from app.sinks.summary import build
    from tests.simulated import run_pipeline

    config = load_config()
    drive = cached_drive("constant_radius", 41, 15.1)
    recorder = SessionRecorder(tmp_path / "session", config, raw_format)
    said: list[str] = []
    recorder.on_problem = said.append
    for msg in drive.messages[:200]:
        recorder.on_frame(msg)
    recorder.flush()
    assert said == []
    shutil.rmtree(tmp_path / "session")
    for msg in drive.messages[200:400]:
        recorder.on_frame(msg)
    recorder.flush()
    recorder.close()
    [problem] = said
    assert "deleted while the session recorded it" in problem and recorder.problem == problem
    recorder.write_summary(build(run_pipeline(config, drive).snapshot(), config, ["drive"]))
    assert not (tmp_path / "session").exists()
