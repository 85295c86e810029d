"""Several logs given to `c2n analyze` as one drive: a recording split in files goes on where
the last stopped; files that do not are separate recordings, and separate drives that disagree
have no one C2n."""

import json
from pathlib import Path

import can
import pytest

from app.config import load_config
from app.results.log_clock import sensor_messages
from app.sim.simulated_drive import SimulatedDrive
from tests.simulated import cached_drive
from tests.test_reliability_inputs import run_cli


def _write(path: Path, messages: list[can.Message], shift_s: float = 0.0) -> Path:
    return _one_file(path, (messages, shift_s))


def _analysed(tmp_path: Path, logs: list[Path]) -> tuple[int, dict | None, str]:
    out = tmp_path / "s.json"
    code, _, err = run_cli(["analyze", *map(str, logs), "--json", str(out)])
    return code, json.loads(out.read_text()) if out.exists() else None, err


def _drive(c2n: float, seed: int) -> SimulatedDrive:
    return cached_drive("constant_radius", seed, c2n)


def test_two_tyre_sets_given_as_one_drive_have_no_one_c2n(tmp_path: Path) -> None:
    """Drives of 14.9 and 16.0, the second an hour later, given without --pool: refused, each
    one's result named (they read 15.40 [15.17, 15.64] as one, outside both, without a word)."""
    first = _write(tmp_path / "a.log", _drive(14.9, 1).messages)
    later = _write(tmp_path / "b.log", _drive(16.0, 2).messages, shift_s=3600.0)
    code, result, err = _analysed(tmp_path, [first, later])
    assert code == 1 and result is None
    assert f"the drives disagree, each alone: {first} " in err and "analyse each alone, or --pool" in err


def test_separate_recordings_that_agree_are_run_on_as_one_and_said_so(tmp_path: Path) -> None:
    """Two drives of one tyre an hour apart: a result, and a note that they are separate
    recordings run on as one (one ψ0 and yaw bias), pointing to --pool."""
    first = _write(tmp_path / "a.log", _drive(15.1, 1).messages)
    later = _write(tmp_path / "b.log", _drive(15.1, 2).messages, shift_s=3600.0)
    code, result, err = _analysed(tmp_path, [first, later])
    assert code == 0 and result is not None and result["c2n"] is not None, err
    [note] = [w for w in result["warnings"] if "separate recordings" in w]
    assert " s after a.log ends: separate recordings, run on as one drive" in note and "--pool" in note


def test_a_recording_split_in_files_reads_as_the_drive_it_is(tmp_path: Path) -> None:
    """One drive cut in two files where a logger's size limit cut it: no note, no check, the
    whole drive's result."""
    messages = _drive(15.1, 1).messages
    half = len(messages) // 2
    parts = [_write(tmp_path / "p1.log", messages[:half]), _write(tmp_path / "p2.log", messages[half:])]
    whole = _write(tmp_path / "whole.log", messages)
    code, split, err = _analysed(tmp_path, parts)
    assert code == 0 and split is not None, err
    _, one, _ = _analysed(tmp_path, [whole])
    assert one is not None
    assert split["c2n"] == one["c2n"] and split["c2n_ci95"] == one["c2n_ci95"]
    assert not any("separate recordings" in w for w in split["warnings"])


def test_channels_merged_from_loggers_on_different_clocks_are_said(tmp_path: Path) -> None:
    """`--merge` of the optical sensor's log on the calendar's clock and the vehicle's counting
    from 0: the files do not overlap, which is said (the only warning blamed the mounting)."""
    messages = _drive(15.1, 1).messages
    optical = [m for m in messages if m.arbitration_id in (0x7E5, 0x7E4, 0x7E6)]
    vehicle = [m for m in messages if m.arbitration_id not in (0x7E5, 0x7E4, 0x7E6)]
    a = _write(tmp_path / "optical.log", optical, shift_s=1.76e9)
    b = _write(tmp_path / "vehicle.log", vehicle, shift_s=-vehicle[0].timestamp)
    out = tmp_path / "m.json"
    run_cli(["analyze", str(a), str(b), "--merge", "--json", str(out)])
    warnings = json.loads(out.read_text())["warnings"]
    [said] = [w for w in warnings if "not beside them" in w]
    assert said.startswith(f"{b}: its frames lie") and "before those of optical.log" in said


def shifted(messages: list[can.Message], shift_s: float) -> list[can.Message]:
    """The frames ``shift_s`` seconds later."""
    return [
        can.Message(
            timestamp=m.timestamp + shift_s,
            arbitration_id=m.arbitration_id,
            is_extended_id=m.is_extended_id,
            data=m.data,
            channel=m.channel,
        )
        for m in messages
    ]


def _one_file(path: Path, *parts: tuple[list[can.Message], float]) -> Path:
    """Drives written one after another into one log, each shifted by its seconds."""
    with can.Logger(path) as writer:
        for messages, shift_s in parts:
            for m in shifted(messages, shift_s):
                writer.on_message_received(m)
    return path


@pytest.mark.parametrize("suffix", [".log", ".blf"])  # frame by frame, and in blocks
def test_two_tyre_sets_in_one_file_across_a_pause_have_no_one_c2n(tmp_path: Path, suffix: str) -> None:
    """A logger left recording through a tyre change: 14.89 before a pause of ten minutes, 15.91
    after it, in one file. It read 15.442 [15.214, 15.671] — outside both — as one drive; the
    parts between the sensor's pauses are now analysed alone, as separate files are."""
    before, after = _drive(14.89, 5).messages, _drive(15.91, 6).messages
    shift = before[-1].timestamp + 600.0 - after[0].timestamp
    log = _one_file(tmp_path / f"day{suffix}", (before, 0.0), (after, shift))
    code, result, err = _analysed(tmp_path, [log])
    assert code == 1 and result is None
    assert f"the drives disagree, each alone: {log.name} 0–150 s 14.9" in err
    assert f"{log.name} 750–900 s 15.9" in err and f"split the log at its pauses (c2n split {log})" in err


def test_a_sensor_dropout_in_one_drive_leaves_its_c2n(tmp_path: Path) -> None:
    """Two seconds without the optical sensor in one drive: two parts that agree, run on as
    one — a C2n, its interval holding the truth, and no word of parts."""
    drive = _drive(14.89, 5)
    start = drive.messages[0].timestamp
    optical = set(sensor_messages(load_config()))  # the Correvit's frames, which the dropout takes out
    assert any(m.arbitration_id in optical for m in drive.messages)
    dropped = [m.arbitration_id in optical and 70.0 <= m.timestamp - start < 72.0 for m in drive.messages]
    kept = [m for m, gone in zip(drive.messages, dropped, strict=True) if not gone]
    log = _one_file(tmp_path / "dropout.log", (kept, 0.0))
    code, result, err = _analysed(tmp_path, [log])
    assert code == 0 and result is not None, err
    assert result["c2n_ci95"][0] <= 14.89 <= result["c2n_ci95"][1]
    assert "disagree" not in err and "pause" not in err
