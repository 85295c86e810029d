"""What a log input can be besides a log: a name no file system holds, a pipe or a device, a
recording of another car's ids, a log timed in milliseconds, a session still being recorded. Each
through the command line: the exit code, the one line, what is on disk."""

import contextlib
import json
import os
import subprocess
import sys
from pathlib import Path

import can
import pytest

from tests.simulated import REPO, cached_drive
from tests.test_reliability_inputs import run_cli

SPEED_ID = 0x415  # BrakeSysFeatures: the Mondeo config's 'speed', on the vehicle bus
MONDEO_TOML = REPO / "config" / "mondeo.toml"


def _speed_frames() -> list[can.Message]:
    """The simulated drive's vehicle speed alone: a vehicle bus without the optical sensor."""
    return [m for m in cached_drive("constant_radius", 41, 15.1).messages if m.arbitration_id == SPEED_ID]


def _one_error_line(err: str) -> str:
    line = err.strip()
    assert line.startswith("c2n: error: ") and "\n" not in line and "Traceback" not in err, err
    return line


def _write_log(path: Path, frames: list[can.Message]) -> Path:
    with can.Logger(path) as writer:
        for m in frames:
            writer.on_message_received(m)
    return path


@pytest.mark.parametrize("command", ["analyze", "export"])
def test_a_log_name_too_long_for_the_file_system_is_one_line(command: str, tmp_path: Path) -> None:
    """A name over the file system's 255 bytes cannot be looked up (``ENAMETOOLONG``), in the file
    name or in a folder of the path (was: a traceback from ``path.exists()``)."""
    name = "a" * 260 + ".log"
    for log in (tmp_path / name, tmp_path / name / "d.log"):
        code, _, err = run_cli([command, str(log)])
        line = _one_error_line(err)
        assert code == 1
        assert f"{tmp_path / ('a' * 40)}…" in line and "the file name is too long (264 bytes" in line
        assert name not in line  # cut: the whole name would fill the screen
    assert sorted(os.listdir(tmp_path)) == []


@pytest.mark.parametrize("command", ["analyze", "export"])
def test_a_pipe_or_a_device_given_as_a_log_is_named_never_read(command: str, tmp_path: Path) -> None:
    """A FIFO (its size 0) was `the file is empty`; it is refused before it is opened, which
    would wait for a writer forever (hence a process with a timeout)."""
    fifo = tmp_path / "x.log"
    os.mkfifo(fifo)
    for log in (fifo, Path(os.devnull)):
        argv = [sys.executable, "-m", "app", command, str(log), "--config", str(MONDEO_TOML)]
        if command == "export":
            argv += ["--out", str(tmp_path / "exp"), "--no-plots"]
        run = subprocess.run(argv, cwd=REPO, capture_output=True, text=True, timeout=120)
        assert run.returncode == 1
        line = _one_error_line(run.stderr)
        assert line == f"c2n: error: {log}: is a pipe or a device, not a log file — give the recorded file"
    assert not (tmp_path / "exp").exists()


def test_an_export_where_no_role_decodes_says_so_exits_1_and_writes_nothing(tmp_path: Path) -> None:
    """A log of ids none of the config's DBCs hold (another car's, or the wrong config) was a
    0-row export, `C2n: no result (no cornering …)` and exit 0, where analyze exits 1: export says
    no role had a frame and leaves --out as it was — an empty export would replace an older one."""
    other = [
        can.Message(timestamp=0.01 * i, arbitration_id=0x123, data=bytes(8), is_extended_id=False)
        for i in range(200)
    ]
    log = _write_log(tmp_path / "other.log", other)
    out = tmp_path / "exp"
    result = tmp_path / "result.json"  # its reason is the refusal's (it had none; without the sensor,
    code, _, err = run_cli(["analyze", str(log), "--json", str(result)])  # one that blamed the driving)
    assert code == 1 and f"c2n: error: {log}: no frames for any role of " in err
    assert json.loads(result.read_text())["no_result"] == err.strip().splitlines()[-1].removeprefix(
        "c2n: error: "
    )
    vehicle = _write_log(tmp_path / "vehicle.log", _speed_frames())
    code, _, err = run_cli(["analyze", str(vehicle), "--json", str(result)])
    reason = json.loads(result.read_text())["no_result"]
    assert code == 1 and reason == err.strip().splitlines()[-1].removeprefix("c2n: error: ")
    assert "cornering" not in reason
    code, _, err = run_cli(["export", str(log), "--out", str(out), "--no-plots"])
    assert code == 1 and "Traceback" not in err
    error = err.strip().splitlines()[-1]
    assert error.startswith(f"c2n: error: {log}: no frames for any role of ")
    assert "wrong DBC or config" in error and f"nothing written to {out}" in error
    assert "c2n: warning: no frames for role 'vx'" in err
    assert not out.exists()
    vehicle = _write_log(tmp_path / "vehicle.log", _speed_frames())
    assert run_cli(["export", str(vehicle), "--out", str(out), "--no-plots", "--format", "csv"])[0] == 0
    before = {path.name: path.read_bytes() for path in out.iterdir()}
    assert run_cli(["export", str(log), "--out", str(out), "--no-plots", "--format", "csv"])[0] == 1
    assert {path.name: path.read_bytes() for path in out.iterdir()} == before  # the older export kept


def test_a_config_whose_channels_are_not_the_log_s_says_so(drive_log: Path, tmp_path: Path) -> None:
    """`[channels]` naming can0/can1 on a log whose channels are numbered otherwise (helper-33:
    c2n's own .trc, 1 and 2): `no frames for any role … wrong DBC or config for this log?`, where
    the ids were all there on other channels."""
    text = (REPO / "config" / "mondeo.toml").read_text().replace('"../dbc/', f'"{REPO}/dbc/')
    dbcs = f'"{REPO}/dbc/kistler_smotion.dbc" = "can7"\n"{REPO}/dbc/vehicle_ford.dbc" = "can8"'
    text = text.replace("# [channels]", f"[channels]\n{dbcs}\n#", 1)
    config = tmp_path / "car.toml"
    config.write_text(text)
    code, _, err = run_cli(["analyze", str(drive_log), "--config", str(config)])
    error = err.strip().splitlines()[-1]
    assert (
        code == 1
        and f"no frames for any role of {config} on the channels it names for them (can7, can8)" in error
    )
    assert "frames of their ids came on others — set [channels] to the channels this log carries" in error


@pytest.mark.parametrize("command", ["analyze", "export"])
def test_a_log_of_another_car_is_refused_for_what_it_lacks_without_a_result_line(
    command: str, tmp_path: Path
) -> None:
    """Not one frame of a role of the config (another car's log, the wrong config): the refusal
    says so — `no frames for any role of <config> — wrong DBC or config` — and no result line
    comes first (was: `C2n: no result (no cornering in the drive …)`, blaming the drive). A
    vehicle bus without the sensor is refused for the sensor, again without that line."""
    other = [
        can.Message(timestamp=0.01 * i, arbitration_id=0x123, data=bytes(8), is_extended_id=False)
        for i in range(200)
    ]
    log = _write_log(tmp_path / "other.log", other)
    argv = [command, str(log)] + (
        ["--out", str(tmp_path / "exp"), "--no-plots"] if command == "export" else []
    )
    code, out, err = run_cli(argv)
    assert code == 1 and "C2n:" not in out and "cornering" not in out + err, out + err
    error = err.strip().splitlines()[-1]
    assert error.startswith(f"c2n: error: {log}: no frames for any role of {MONDEO_TOML}")
    assert "wrong DBC or config for this log? give the car's with --config" in error
    if command == "analyze":
        vehicle = _write_log(tmp_path / "vehicle.log", _speed_frames())
        code, out, err = run_cli(["analyze", str(vehicle)])
        assert code == 1 and "C2n:" not in out and "no cornering" not in out + err, out + err
        assert err.strip().splitlines()[-1].startswith(f"c2n: error: {vehicle}: no frames for role 'vx'")


def _timed_in(unit: float, frames: list[can.Message]) -> list[can.Message]:
    """The frames with their timestamps in 1/``unit`` of a second, as a logger counting in
    milliseconds (``unit`` 1000) or microseconds writes them."""
    return [
        can.Message(
            timestamp=m.timestamp * unit,
            arbitration_id=m.arbitration_id,
            is_extended_id=m.is_extended_id,
            channel=m.channel,
            dlc=m.dlc,
            data=m.data,
        )
        for m in frames
    ]


@pytest.mark.parametrize(
    ("suffix", "unit", "name", "factor"),
    [(".csv", 1e3, "milliseconds", "1000"), (".log", 1e6, "microseconds", "1,000,000")],
    ids=["csv-ms", "candump-us"],
)
def test_a_log_timed_in_milliseconds_or_microseconds_is_one_line_saying_so(
    suffix: str, unit: float, name: str, factor: str, tmp_path: Path
) -> None:
    """A CSV or candump log whose timestamp column counts milliseconds (or microseconds) reads
    as a drive 1000× (10⁶×) too long: the filter restarted at every optical frame and analyze
    said `C2n: no result (no sideslip sign change and too little quasi-steady cornering …)` with
    exit 0 (in microseconds since 1970 no frame decoded: `no frames for role 'vx'`). The sensor's
    frames lie 20 "s" apart (median), past gap_reset_s: one line naming the log, the spacing and
    the fix, exit 1, and export writes nothing. The same frames in seconds say nothing of it."""
    frames = cached_drive("constant_radius", 41, 15.1).messages  # the sensor at 50 Hz
    log = _write_log(tmp_path / f"drive{suffix}", _timed_in(unit, frames))
    code, out, err = run_cli(["analyze", str(log), "--json", str(tmp_path / "s.json")])
    assert code == 1 and out == "", out
    why = (
        f"the optical sensor's frames (id 0x7E5) are {0.02 * unit:,.0f} s apart (median), where a sensor "
        f"sends one every 20 ms (its DBC's cycle): timestamps in {name} read as seconds, {factor}× too "
        "slow — past gap_reset_s (1 s) the filter restarts at every frame; convert the timestamp column "
        f"to seconds (÷ {factor})"
    )
    assert _one_error_line(err) == f"c2n: error: {log}: {why}"
    assert json.loads((tmp_path / "s.json").read_text())["warnings"][0] == f"{log}: {why}"
    folder = tmp_path / "exp"
    code, _, err = run_cli(["export", str(log), "--out", str(folder), "--no-plots", "--format", "csv"])
    assert code == 1 and _one_error_line(err) == f"c2n: error: {log}: {why} (nothing written to {folder})"
    assert not folder.exists()
    in_seconds = _write_log(tmp_path / f"seconds{suffix}", frames)
    code, out, err = run_cli(["analyze", str(in_seconds)])
    assert code == 0 and "C2n = " in out and "apart (median)" not in err, out + err


def test_a_campaign_row_of_a_log_timed_in_milliseconds_says_so(tmp_path: Path) -> None:
    """A campaign's row of the CSV timed in milliseconds: the clock's own reason, as analyze
    gives it (the row read `no C2n — no sideslip sign change and too little quasi-steady
    cornering …`, blaming the drive); the same frames in seconds keep their C2n."""
    import csv

    frames = cached_drive("constant_radius", 41, 15.1).messages
    ms = _write_log(tmp_path / "drive ms [a].csv", _timed_in(1e3, frames))
    seconds = _write_log(tmp_path / "drive.csv", frames)
    manifest = tmp_path / "manifest.csv"
    manifest.write_text(f"log,tyre_set\n{ms},A\n{seconds},A\n", encoding="utf-8")
    out = tmp_path / "campaign"
    argv = ["campaign", str(manifest), "--workers", "1", "--by", "tyre_set", "--out", str(out)]
    code, _, err = run_cli(argv)
    assert code == 0, err
    with (out / "results.csv").open(encoding="utf-8-sig", newline="") as file:
        slow, plain = csv.DictReader(file)
    assert slow["c2n"] == ""
    assert slow["error"].startswith(f"{ms}: the optical sensor's frames (id 0x7E5) are 20 s")
    assert "timestamps in milliseconds read as seconds" in slow["error"] and "cornering" not in slow["error"]
    assert plain["error"] == "" and 14.6 < float(plain["c2n"]) < 15.6
    assert "1 of 2 sessions failed" in err


def test_an_export_of_a_vehicle_bus_without_the_sensor_still_converts_what_there_is(tmp_path: Path) -> None:
    """Only where no role at all decodes is export refused: the vehicle's speed alone is exported."""
    frames = _speed_frames()
    log = _write_log(tmp_path / "vehicle.log", frames)
    out = tmp_path / "exp"
    code, _, err = run_cli(["export", str(log), "--out", str(out), "--no-plots", "--format", "csv"])
    assert code == 0 and "no frames for role 'vx'" in err
    with (out / "channels.csv").open(encoding="utf-8-sig") as file:
        assert len(file.readlines()) - 1 == len(frames)


def test_an_export_of_a_session_without_its_summary_warns_it_covers_the_frames_so_far(tmp_path: Path) -> None:
    """c2n live writes summary.json when it ends: without it the session is still being recorded
    or its run was killed (was: exported as if final, no word); the warning is on stderr and in
    the exported summary, first. A session with its summary exports without it, and a campaign's
    row of it, cached while it had none, is analysed again (it kept the warning)."""
    from app.config import load_config
    from app.sinks.recorder import SessionRecorder

    session = tmp_path / "session"
    recorder = SessionRecorder(session, load_config())
    for m in cached_drive("constant_radius", 41, 15.1).messages:
        recorder.on_frame(m)
    recorder.close()  # as a killed run left it: no summary
    warning = (
        f"{session}: no summary.json: the session is still being recorded, or its c2n live was "
        "killed — this export covers the frames on disk so far"
    )
    code, _, err = run_cli(["export", str(session), "--no-plots", "--format", "csv"])
    assert code == 0 and f"c2n: warning: {warning}\n" in err
    exported = json.loads((session / "export" / "summary.json").read_text())
    assert exported["warnings"][0] == warning and exported["c2n"] == pytest.approx(15.1, rel=0.02)
    manifest = tmp_path / "manifest.csv"  # a campaign's row of it: said too (it was not)
    manifest.write_text("log,tyre_set\nsession,A\n")
    code, _, err = run_cli(["campaign", str(manifest), "--workers", "1"])
    row = warning.replace("this export covers", "this row covers")
    assert code == 0 and f"c2n: warning: {row}\n" in err
    (session / "summary.json").write_text(json.dumps(exported))  # the end of the run
    code, _, err = run_cli(["export", str(session), "--no-plots", "--format", "csv"])
    assert code == 0 and "no summary.json" not in err
    code, _, err = run_cli(["campaign", str(manifest), "--workers", "1"])  # its cached row: said it still
    assert code == 0 and "no summary.json" not in err, err


def test_a_database_of_another_layout_is_named_so_not_damaged(tmp_path: Path) -> None:
    """A SQLite file whose frames are in a table of another name was `not a readable log,
    damaged from the start (no such table: messages)`: it is not damaged."""
    import sqlite3

    path = tmp_path / "bus.db"
    with contextlib.closing(sqlite3.connect(path)) as db:
        db.execute("CREATE TABLE frames (ts REAL, arbitration_id INTEGER, data BLOB)")
        db.commit()
    code, _, err = run_cli(["analyze", str(path)])
    assert code == 1 and f"{path}: not a python-can SQLite log (no such table: messages" in err, err
    assert "rename its table to messages" in err and "damaged" not in err
