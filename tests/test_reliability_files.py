"""Issue 20, second round: what an adversarial user still broke with files — the same log twice,
exports that overwrite each other, a DBC that talks to the terminal."""

import json
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import can
import pytest

from tests.live_process import foreground
from tests.simulated import REPO, cached_drive, sent_on_virtual_bus
from tests.test_reliability_inputs import MONDEO, run_cli


def test_the_same_log_twice_is_warned_about_and_read_once(drive_log: Path, tmp_path: Path) -> None:
    copy = tmp_path / "copy.blf"
    shutil.copy(drive_log, copy)
    code, _, err = run_cli(["analyze", str(drive_log), "--json", str(tmp_path / "once.json")])
    assert code == 0
    code, _, err = run_cli(
        ["analyze", str(drive_log), str(drive_log), str(copy), "--json", str(tmp_path / "thrice.json")]
    )
    assert code == 0 and "Traceback" not in err
    once, thrice = (json.loads((tmp_path / f"{n}.json").read_text()) for n in ("once", "thrice"))
    assert thrice["crossings"] == once["crossings"] and thrice["c2n_ci95"] == once["c2n_ci95"]
    assert thrice["frames"]["total"] == once["frames"]["total"]
    assert f"{drive_log}: the same recording as {drive_log}: read once" in thrice["warnings"]
    assert f"{copy}: the same recording as {drive_log}: read once" in thrice["warnings"]
    assert f"c2n: warning: {copy}: the same recording as {drive_log}: read once" in err


def test_logs_with_dotted_names_export_to_folders_of_their_own(drive_log: Path, tmp_path: Path) -> None:
    runs = [tmp_path / "day1.run1.blf", tmp_path / "day1.run2.blf"]
    for run in runs:
        shutil.copy(drive_log, run)
        assert run_cli(["export", str(run), "--no-plots", "--format", "csv"])[0] == 0
    for run in runs:
        summary = json.loads((tmp_path / f"{run.stem}-export" / "summary.json").read_text())
        assert summary["inputs"] == [str(run)]


def test_text_from_a_dbc_never_reaches_the_terminal_raw(drive_log: Path, tmp_path: Path) -> None:
    """A unit holding an escape sequence (clear the screen) is shown escaped in the one error line."""
    text = (REPO / "dbc" / "kistler_smotion.dbc").read_text(encoding="latin-1")
    start = text.index('"', text.index("VelX_cor"))
    end = text.index('"', start + 1)
    evil = tmp_path / "evil.dbc"
    evil.write_text(text[: start + 1] + "m/s\x1b[2J\x07" + text[end:], encoding="latin-1")
    config = tmp_path / "car.toml"
    config.write_text(MONDEO.replace(f"{REPO}/dbc/kistler_smotion.dbc", str(evil)))
    code, out, err = run_cli(["analyze", str(drive_log), "--config", str(config)])
    assert code == 1 and "\x1b" not in err + out and "\x07" not in err
    assert "unit 'm/s\\x1b[2J\\x07'" in err


def test_a_candump_line_cut_inside_its_data_is_counted_damaged_not_decoded(tmp_path: Path) -> None:
    """python-can reads `7E5#3B03FFFF3B03FAF` (15 hex digits) as 8 bytes with a wrong last one
    and a dlc of 7: such a frame is not decoded, it is counted and warned about."""
    log = tmp_path / "drive.log"
    with can.Logger(log) as writer:
        for m in cached_drive("constant_radius", 41, 15.1).messages[:4000]:
            writer.on_message_received(m)
    lines = log.read_text().splitlines()
    optical = [k for k, line in enumerate(lines) if " 7E5#" in line]
    for k in optical[100:103]:
        lines[k] = lines[k].split()[0] + " " + lines[k].split()[1] + " " + lines[k].split()[2][:-1]
    log.write_text("\n".join(lines) + "\n")
    code, _, err = run_cli(["analyze", str(log), "--json", str(tmp_path / "s.json")])
    summary = json.loads((tmp_path / "s.json").read_text())
    assert summary["frames"]["bad_length"] == 3 and summary["frames"]["total"] == len(lines)
    assert "3 frames not decoded: their length is not their DBC message's (3 with a data field cut" in err
    assert "Traceback" not in err and code in (0, 1)


def test_nan_timestamps_in_a_csv_log_are_counted_and_warned_about(tmp_path: Path) -> None:
    log = tmp_path / "drive.csv"
    frames = cached_drive("constant_radius", 41, 15.1).messages
    with can.Logger(log) as writer:
        for m in frames:
            writer.on_message_received(m)
    lines = log.read_text().splitlines()
    start = frames[0].timestamp
    damaged = 0
    for k in range(1, len(lines)):
        if 40.0 <= frames[k - 1].timestamp - start < 48.0:  # 8 s of the drive
            lines[k] = "nan" + lines[k][lines[k].index(",") :]
            damaged += 1
    log.write_text("\n".join(lines) + "\n")
    code, _, err = run_cli(["analyze", str(log), "--json", str(tmp_path / "s.json")])
    assert code == 0 and "Traceback" not in err
    summary = json.loads((tmp_path / "s.json").read_text())
    frames_out = summary["frames"]
    assert frames_out["total"] == len(frames)
    assert 0 < frames_out["bad_time"] <= damaged  # the needed messages' frames among them
    assert frames_out["total"] == sum(
        n for kind, n in frames_out.items() if kind not in ("total", "fd_frames")
    )
    assert f"{frames_out['bad_time']} frames without a usable timestamp (NaN, infinite, or beyond" in err
    assert summary["c2n"] is not None


def test_demo_ended_by_sigterm_leaves_no_temporary_folder_and_a_killed_ones_is_removed_next_time(
    tmp_path: Path,
) -> None:
    import os
    import signal
    import subprocess
    import sys
    import time

    from app.cli.demo import TEMP_PREFIX, remove_stale

    env = {**os.environ, "TMPDIR": str(tmp_path)}
    child = subprocess.Popen(
        [sys.executable, "-m", "app", "demo", "--speedup", "1"],
        cwd=REPO,
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        deadline = time.monotonic() + 60
        while not list(tmp_path.glob(f"{TEMP_PREFIX}*/*.truth.json")) and time.monotonic() < deadline:
            time.sleep(0.05)
        assert list(tmp_path.glob(f"{TEMP_PREFIX}{child.pid}-*")), "the demo never made its folder"
        time.sleep(1.0)  # replaying
        child.send_signal(signal.SIGTERM)
        out, err = child.communicate(timeout=30)
    finally:
        child.kill()
    # ended as Ctrl-C ends it: the result of the frames replayed, said to be theirs (it said
    # nothing, exit 0, and set the simulated truth beside it as if the drive had been whole)
    assert child.returncode == 130 and "Traceback" not in err, err
    assert "c2n: interrupted — " in err and " frames replayed: the result above is theirs" in err
    assert "simulated truth" not in out
    assert not list(tmp_path.glob(f"{TEMP_PREFIX}*"))
    # SIGKILL cannot be caught: the folder stays until the next demo finds its process gone
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    stale, mine = tmp_path / f"{TEMP_PREFIX}{dead.pid}-x", tmp_path / f"{TEMP_PREFIX}{os.getpid()}-y"
    for folder in (stale, mine):
        folder.mkdir()
        (folder / "demo-drive.blf").write_bytes(b"x")
    assert remove_stale(tmp_path) == [stale] and not stale.exists() and mine.exists()


def test_two_dbcs_of_one_name_are_both_kept_in_a_session_and_it_exports(tmp_path: Path) -> None:
    from app.config import load_config
    from app.sinks.recorder import SessionRecorder

    for folder, source in (("sensor", "kistler_smotion.dbc"), ("vehicle", "vehicle_ford.dbc")):
        (tmp_path / folder).mkdir()
        shutil.copy(REPO / "dbc" / source, tmp_path / folder / "car.dbc")
    text = MONDEO.replace(f"{REPO}/dbc/kistler_smotion.dbc", "sensor/car.dbc")
    text = text.replace(f"{REPO}/dbc/vehicle_ford.dbc", "vehicle/car.dbc")
    (tmp_path / "car.toml").write_text(text)
    config = load_config(tmp_path / "car.toml")
    session = tmp_path / "session"
    recorder = SessionRecorder(session, config)
    frames = cached_drive("constant_radius", 41, 15.1).messages
    for m in frames:
        recorder.on_frame(m)
    recorder.close()
    assert sorted(p.name for p in (session / "config").iterdir()) == ["car-2.dbc", "car.dbc", "car.toml"]
    copy = load_config(session / "config" / "car.toml", dbc_dir=session / "config")
    assert [d.path.read_bytes() for d in copy.dbcs] == [d.path.read_bytes() for d in config.dbcs]
    alone = load_config(session / "config" / "car.toml")  # the copy names the DBCs beside it
    assert [d.path for d in alone.dbcs] == [session / "config" / "car.dbc", session / "config" / "car-2.dbc"]
    assert [d.path.read_bytes() for d in alone.dbcs] == [d.path.read_bytes() for d in config.dbcs]
    code, _, err = run_cli(["export", str(session), "--no-plots", "--format", "csv"])
    assert code == 0 and "Traceback" not in err
    summary = json.loads((session / "export" / "summary.json").read_text())
    assert summary["frames"]["total"] == len(frames) and summary["c2n"] == pytest.approx(15.1, rel=0.02)


def test_a_session_s_config_copy_reads_the_session_by_itself(tmp_path: Path) -> None:
    """The shipped config names its DBCs as ``../dbc/…``; its copy in a session names them beside
    it, so ``--config SESSION/config/mondeo.toml`` reads the session as recorded (was: DBC file
    not found — only ``c2n export SESSION`` could use it)."""
    from app.config import load_config
    from app.sinks.recorder import SessionRecorder

    session = tmp_path / "session"
    recorder = SessionRecorder(session, load_config(REPO / "config" / "mondeo.toml"))
    for m in cached_drive("constant_radius", 41, 15.1).messages:
        recorder.on_frame(m)
    recorder.close()
    argv = ["analyze", str(session / "frames.log"), "--config", str(session / "config" / "mondeo.toml")]
    code, _, err = run_cli([*argv, "--json", str(tmp_path / "s.json")])
    assert code == 0, err
    assert json.loads((tmp_path / "s.json").read_text())["c2n"] == pytest.approx(15.1, rel=0.02)


def _export(log: Path, out: Path, *options: str) -> tuple[int, str]:
    code, _, err = run_cli(["export", str(log), "--out", str(out), "--no-plots", *options])
    return code, err


def test_an_export_folder_is_one_run_whole(drive_log: Path, tmp_path: Path) -> None:
    """A re-export with fewer formats leaves no file of the run before; a folder holding files
    export did not write is refused and left as it was."""
    out = tmp_path / "out"
    assert _export(drive_log, out, "--format", "csv", "--format", "parquet")[0] == 0
    assert {p.name for p in out.iterdir()} == {
        "channels.csv",
        "channels.parquet",
        "events.csv",
        "summary.json",
    }
    assert _export(drive_log, out, "--format", "csv")[0] == 0
    assert {p.name for p in out.iterdir()} == {"channels.csv", "events.csv", "summary.json"}
    assert [p.name for p in tmp_path.iterdir()] == ["out"]  # no partial or old folder beside it
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine")
    code, err = _export(drive_log, mine, "--format", "csv")
    assert code == 1 and err.strip() == (
        f"c2n: error: --out {mine}: holds files c2n did not write (notes.txt) — choose a new or empty folder"
    )
    assert [p.name for p in mine.iterdir()] == ["notes.txt"]


def test_two_exports_into_one_folder_at_once_or_a_kill_leave_one_runs_folder(
    drive_log: Path, tmp_path: Path
) -> None:
    import os
    import signal
    import subprocess
    import sys
    import time

    short = tmp_path / "short.blf"
    with can.Logger(short) as writer:
        for m in cached_drive("constant_radius", 41, 15.1).messages[:20000]:
            writer.on_message_received(m)
    out = tmp_path / "out"

    def export(log: Path) -> subprocess.Popen[str]:
        argv = [sys.executable, "-m", "app", "export", str(log), "--out", str(out), "--format", "csv"]
        return subprocess.Popen(argv, cwd=REPO, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)

    alone = {}
    for log in (drive_log, short):
        assert (
            run_cli(["export", str(log), "--out", str(tmp_path / f"alone-{log.stem}"), "--format", "csv"])[0]
            == 0
        )
        alone[str(log)] = (tmp_path / f"alone-{log.stem}" / "channels.csv").read_bytes()
    runs = [export(drive_log), export(short)]
    for run in runs:
        _, err = run.communicate(timeout=120)
        assert run.returncode == 0 and "Traceback" not in err
    summary = json.loads((out / "summary.json").read_text())
    [log] = summary["inputs"]
    assert (out / "channels.csv").read_bytes() == alone[log]  # the channels and the summary of one run
    assert f"c2n — {Path(log).name}" in (out / "report.html").read_text()
    assert not list(tmp_path.glob(".out.*"))  # no partial or old folder beside it
    # kill -9 in the middle of a re-export: the folder is the run before, whole
    before = (out / "summary.json").read_bytes()
    run = export(drive_log)
    deadline = time.monotonic() + 60
    while not list(tmp_path.glob(".out.partial-*")) and time.monotonic() < deadline:
        time.sleep(0.02)
    os.kill(run.pid, signal.SIGKILL)
    run.wait()
    assert (out / "summary.json").read_bytes() == before
    assert _export(Path(log), out, "--format", "csv")[0] == 0  # the next run clears what the kill left
    assert not list(tmp_path.glob(".out.*"))


def test_the_plot_names_export_recognises_are_the_plots_it_writes() -> None:
    from app.cli.export import PLOT_NAMES
    from app.sinks.plots import PLOTS

    assert tuple(PLOTS) == PLOT_NAMES


class _FullDisk:
    """A raw file on a disk that fills up after ``room`` bytes."""

    def __init__(self, file: object, room: int) -> None:
        self.file, self.room = file, room

    def write(self, data: memoryview) -> int:
        import errno

        if len(data) > self.room:
            raise OSError(errno.ENOSPC, "No space left on device")
        self.room -= len(data)
        return self.file.write(data)  # type: ignore[attr-defined, no-any-return]

    def __getattr__(self, name: str) -> object:  # closed, tell, seek, flush: the file's own
        return getattr(self.file, name)


@pytest.mark.parametrize("raw_format", [".log", ".blf"])
def test_live_on_a_full_disk_says_what_was_kept_and_the_numbers_go_on(
    raw_format: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import uuid

    from app.sinks import recorder as rec

    room = 300_000
    if raw_format == ".log":
        opened = rec._Spool.__init__

        def spool(self: rec._Spool, path: Path, **options: bool) -> None:
            opened(self, path, **options)
            self._file = _FullDisk(self._file, room)  # type: ignore[assignment]

        monkeypatch.setattr(rec._Spool, "__init__", spool)
    else:
        made = rec._BLFWriter.__init__

        def blf(self: rec._BLFWriter, path: Path) -> None:
            made(self, path)  # writes the file's 144-byte header: the disk holds `room` in all
            self.file = _FullDisk(self.file, room - self.file.tell())

        monkeypatch.setattr(rec._BLFWriter, "__init__", blf)
    channel = f"full-{uuid.uuid4().hex}"
    frames = cached_drive("constant_radius", 41, 15.1).messages
    record = tmp_path / "sessions"
    argv = ["live", "-i", "virtual", "-c", channel, "--record", str(record), "--raw-format", raw_format]
    with sent_on_virtual_bus(channel, frames):
        code, out, err = run_cli([*argv, "--duration", "6"])
    assert code == 1 and "Traceback" not in err
    [session] = list(record.glob("20*"))
    raw = session / f"frames{raw_format}"
    assert f"c2n: {raw}: the recording stopped — No space left on device on the disk of" in out
    assert "MB of frames up to then are kept, the live numbers go on" in out
    assert "C2n = " in out  # measured from every frame received, recorded or not
    summary = json.loads((session / "summary.json").read_text())
    assert summary["frames"]["total"] == len(frames) and summary["c2n"] == pytest.approx(15.1, rel=0.02)
    assert summary["warnings"][0].startswith(f"{raw}: the recording stopped")
    kept = list(can.LogReader(raw)) if raw_format == ".log" else []
    if raw_format == ".log":  # whole lines up to the failure, every one a frame received
        assert 0 < len(kept) < len(frames)
        assert [bytes(m.data) for m in kept] == [bytes(m.data) for m in frames[: len(kept)]]
    assert 0 < raw.stat().st_size <= room


_PEAK = """
import resource, sys
from app.cli import main
code = main(sys.argv[1:])
print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss // 1024, code)
"""


def _peak_mb(*argv: str) -> tuple[int, int, str]:
    import subprocess
    import sys

    run = subprocess.run(
        [sys.executable, "-c", _PEAK, *argv], cwd=REPO, capture_output=True, text=True, timeout=300
    )
    peak, code = run.stdout.split()[-2:]
    return int(peak), int(code), run.stderr


def test_a_huge_sparse_text_log_is_refused_in_bounded_memory(drive_log: Path, tmp_path: Path) -> None:
    """256 MB of NUL bytes with a candump suffix (a sparse file: no disk used), then a frame."""
    sparse = tmp_path / "sparse.log"
    with sparse.open("wb") as file:
        file.truncate(256 << 20)
        file.seek(0, 2)
        file.write(b"\n(1.0) can0 7E5#0102030405060708\n")
    frames = tmp_path / "frames.log"
    with can.Logger(frames) as writer:
        for m in cached_drive("constant_radius", 41, 15.1).messages[:2000]:
            writer.on_message_received(m)
    baseline, code, _ = _peak_mb("analyze", str(frames))
    assert code == 0
    peak, code, err = _peak_mb("analyze", str(sparse))
    assert code == 1 and "Traceback" not in err
    assert (
        f"{sparse}: not a readable log, damaged from the start (a line longer than 65,536 characters" in err
    )
    assert peak < baseline + 64, (peak, baseline)
    # the same after good frames: every frame before it is used, and it says where it stopped
    with frames.open("ab") as file:
        file.write(b"\0" * (8 << 20) + b"\n")
    code, _, err = run_cli(["analyze", str(frames)])
    assert "stopped after frame 2,000" in err or "stopped after frame 2000" in err, err


def test_gap_check_on_a_pack_without_its_seal_is_refused_before_any_work(
    drive_log: Path, tmp_path: Path
) -> None:
    pack = tmp_path / "pack"
    (pack / "case_001").mkdir(parents=True)
    shutil.copy(drive_log, pack / "case_001" / "drive.blf")
    code, out, err = run_cli(["gap-check", str(pack), "--json", str(tmp_path / "scores.json")])
    assert code == 1 and "Traceback" not in err and "case_001" not in out
    [line] = err.strip().splitlines()
    assert line.startswith("c2n: error: ") and "no sealed" in line and "c2n simulate --pack" in line
    assert not (tmp_path / "scores.json").exists()


def _a_pack(tmp_path: Path) -> Path:
    """A pack of one case whose drive does not read (diagnosed at once: an error), sealed."""
    pack = tmp_path / "pack"
    (pack / "case_001").mkdir(parents=True)
    (pack / "case_001" / "drive.blf").write_bytes(b"not a log")
    (pack / "sealed").mkdir()
    seal = {"cases": {"case_001": {"effect": {"name": "none", "size": 0.0}}}}
    (pack / "sealed" / "truth.json").write_text(json.dumps(seal))
    return pack


@pytest.mark.parametrize(
    "seal",
    [
        "[]",
        '{"cases": 5}',
        '"x"',
        '{"cases": {"case_001": 3}}',
        '{"cases": {"case_001": {"effect": null}}}',
        '{"cases": {"case_001": {"effect": {"name": "none", "size": 0}, "model": 5}}}',  # helper-33
        '{"cases": {"case_001": {"effect": {"name": "none", "size": "big"}}}}',
    ],
)
def test_gap_check_on_a_damaged_seal_is_one_line_before_any_work(tmp_path: Path, seal: str) -> None:
    """A seal of another form ended, after every case was diagnosed, in a KeyError, an
    AttributeError or a TypeError (helper-32)."""
    pack = _a_pack(tmp_path)
    (pack / "sealed" / "truth.json").write_text(seal)
    code, out, err = run_cli(["gap-check", str(pack)])
    assert code == 1 and "Traceback" not in err and "case_001" not in out, err
    [line] = err.strip().splitlines()
    assert "truth.json: not a pack's seal (its cases, each with its effect's name and size)" in line
    assert not (pack / "gap").exists()


def test_gap_check_replaces_only_its_own_answers_and_leaves_no_earlier_one(tmp_path: Path) -> None:
    """gap-check wrote `PACK/gap/` without a look (helper-32): a user's scores.json and a
    read-only case_001.json were replaced, a file named gap failed after all the work, and a case
    that failed this time kept the last run's diagnosis beside this run's scores."""
    pack = _a_pack(tmp_path)
    answers = pack / "gap"
    answers.mkdir()
    (answers / "scores.json").write_text("my notes")
    code, out, err = run_cli(["gap-check", str(pack)])
    assert code == 1 and "[1/1]" not in out, err
    assert "gap/scores.json: exists and is not a file c2n wrote of this kind" in err
    assert (answers / "scores.json").read_text() == "my notes"
    (answers / "scores.json").unlink()
    earlier = {"diagnosis": "road_cross_slope", "verdict": "…", "calibration": {}}
    (answers / "case_001.json").write_text(json.dumps(earlier))
    (answers / "case_001.json").chmod(0o444)
    code, _, err = run_cli(["gap-check", str(pack)])
    assert code == 1 and "case_001.json: is read-only" in err, err
    (answers / "case_001.json").chmod(0o644)
    (pack / "case_002").mkdir()  # a copy, not in the seal: said, not diagnosed
    (pack / "case_002" / "drive.blf").write_bytes(b"not a log")
    code, out, err = run_cli(["gap-check", str(pack)])
    assert code == 0, err
    assert "case_002: not a case of the pack's seal — not diagnosed" in err and "[1/1] case_001: error" in out
    assert not (answers / "case_001.json").exists()  # the earlier answer, not beside this run's error
    assert json.loads((answers / "scores.json").read_text())["cases"][0]["diagnosis"] == "error"
    (answers / "scores.json").write_text(json.dumps({"accuracy": 1.0, "generators": {}, "cases": []}))
    code, _, err = run_cli(["gap-check", str(pack), "--json", str(tmp_path / "elsewhere.json")])
    assert code == 0, err  # helper-34: the pack's own scores were left as they were beside new answers
    assert json.loads((answers / "scores.json").read_text()) == json.loads(
        (tmp_path / "elsewhere.json").read_text()
    )
    shutil.rmtree(answers)
    answers.write_text("a file")
    code, _, err = run_cli(["gap-check", str(pack)])
    assert code == 1 and "gap: is a file, where gap-check writes its answers (a folder) — move it" in err, err


@pytest.mark.skipif(not hasattr(signal, "SIGHUP"), reason="POSIX signals")
@pytest.mark.parametrize("sig", ["SIGTERM", "SIGHUP"])
def test_sigterm_while_export_writes_leaves_no_hidden_folder(
    drive_log: Path, tmp_path: Path, sig: str
) -> None:
    """SIGTERM or a closed terminal while `c2n export` writes ended the process where it stood:
    its hidden folder of half-written files stayed (24 MB for a 150-s drive). Every command now
    ends on them as on Ctrl-C, unwinding: nothing is left, exit 130."""
    out = tmp_path / "export"
    child = subprocess.Popen(
        [sys.executable, "-m", "app", "export", str(drive_log), "--out", str(out), "--no-plots"],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        preexec_fn=foreground,
    )
    deadline = time.monotonic() + 120
    while not list(tmp_path.glob(".export.partial-*")) and child.poll() is None:
        assert time.monotonic() < deadline
        time.sleep(0.005)
    assert child.poll() is None  # writing
    child.send_signal(getattr(signal, sig))
    _, err = child.communicate(timeout=120)
    assert child.returncode == 130, err.decode()  # was -2 (SIGINT) 1 run in 4: see test_cli.py
    assert b"c2n: interrupted" in err and b"Traceback" not in err
    assert list(tmp_path.iterdir()) == []


def test_analyze_or_export_ended_by_a_signal_says_so_and_keeps_the_older_output(
    drive_log: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Ctrl-C, SIGTERM or a closed terminal during `analyze --json J` ended it with exit 0, the C2n of
    the part read printed as the drive's and J replaced by it (14.935 from the first 170 s of a
    563-s drive whose whole read 14.866), without a word; `export` swapped the part's export in
    for the whole drive's (98 s of 563)."""
    from app.sources.logs import LogSource

    result = tmp_path / "result.json"
    assert run_cli(["analyze", str(drive_log), "--json", str(result)])[0] == 0
    whole = result.read_bytes()
    items = LogSource.items

    def cut_short(self: LogSource, *args: Any, **kwargs: Any) -> Iterator[Any]:
        for n, item in enumerate(items(self, *args, **kwargs)):
            if n == 2:
                raise KeyboardInterrupt  # as SIGTERM and SIGHUP are raised (app.cli.common.interrupt)
            yield item

    exported = tmp_path / "exported"  # export: exit 0, the older export swapped for the part's
    assert (
        run_cli(["export", str(drive_log), "--out", str(exported), "--no-plots", "--format", "csv"])[0] == 0
    )
    export = {entry.name: entry.read_bytes() for entry in exported.iterdir()}
    monkeypatch.setattr(LogSource, "items", cut_short)
    code, _, err = run_cli(["analyze", str(drive_log), "--json", str(result)])
    assert code == 130, err
    said = err.split("c2n: interrupted — the result above is of the first ")[1]
    frames = int(said.split("s read (")[1].split(" frames)")[0].replace(",", ""))
    assert 0 < frames < json.loads(whole)["frames"]["total"]
    assert said.rstrip().endswith(f"not the whole of {drive_log}; {result} not written"), err
    assert result.read_bytes() == whole
    code, _, err = run_cli(
        ["export", str(drive_log), "--out", str(exported), "--no-plots", "--format", "csv"]
    )
    assert code == 130, err
    assert f"c2n: interrupted — {drive_log} not read to its end: nothing written to {exported}" in err
    assert {entry.name: entry.read_bytes() for entry in exported.iterdir()} == export


def test_export_replaces_only_an_older_export_of_the_same_log(drive_log: Path, tmp_path: Path) -> None:
    """`export --out DIR` replaced a folder of files named and begun as an export's, whatever they
    were: a `gap` report alone, an `analyze` summary alone, another drive's whole export — each
    deleted, exit 0, no word."""
    fast = ["--no-plots", "--format", "csv"]
    notes = tmp_path / "notes"
    notes.mkdir()
    (notes / "report.html").write_text('<html><head><meta name="generator" content="c2n"></head></html>')
    results = tmp_path / "results"
    assert run_cli(["analyze", str(drive_log), "--json", str(results / "summary.json")])[0] == 0
    for folder in (notes, results):
        before = {entry.name: entry.read_bytes() for entry in folder.iterdir()}
        code, _, err = run_cli(["export", str(drive_log), "--out", str(folder), *fast])
        assert code == 1 and f"c2n: error: {folder}: holds c2n's files but no export (" in err, err
        assert {entry.name: entry.read_bytes() for entry in folder.iterdir()} == before
    other = tmp_path / "other.blf"
    shutil.copy(drive_log, other)
    exported = tmp_path / "exported"
    assert run_cli(["export", str(drive_log), "--out", str(exported), *fast])[0] == 0
    before = {entry.name: entry.read_bytes() for entry in exported.iterdir()}
    code, _, err = run_cli(["export", str(other), "--out", str(exported), *fast])
    assert (
        code == 1 and f"{exported}: holds the export of {drive_log}, not of {other} — choose another" in err
    )
    assert {entry.name: entry.read_bytes() for entry in exported.iterdir()} == before
    assert run_cli(["export", str(drive_log), "--out", str(exported), *fast])[0] == 0  # its own: replaced
    for _ in range(2):  # the default folder beside the log is the log's own
        assert run_cli(["export", str(other), *fast])[0] == 0
    # another log of the same stem (a logger's BLF and its candump copy): its default folder is the
    # first's export, which was replaced, exit 0, no word
    same_stem = tmp_path / "other.log"
    default = tmp_path / "other-export"
    before = {entry.name: entry.read_bytes() for entry in default.iterdir()}
    same_stem.write_bytes(b"")  # the name is enough: the folder is refused before the log is read
    code, _, err = run_cli(["export", str(same_stem), *fast])
    assert code == 1 and f"{default}: holds the export of {other}, not of {same_stem}" in err, err
    assert {entry.name: entry.read_bytes() for entry in default.iterdir()} == before


def test_a_format_asked_twice_is_written_and_listed_once(drive_log: Path, tmp_path: Path) -> None:
    """`--format csv --format csv` wrote channels.csv twice over and listed it twice."""
    out = tmp_path / "exported"
    code, text, err = run_cli(
        ["export", str(drive_log), "--out", str(out), "--format", "csv", "--format", "csv"]
    )
    assert code == 0, err
    assert text.count("channels.csv") == 1
