"""A recording that reaches the largest file its disk holds (FAT32's 4 GiB, a USB stick's usual
format: a busy bus's seven hours) goes on in a session folder of its own beside the first — not
a frame lost, none twice, each part a session folder any command reads."""

import errno
import itertools
import json
import os
import re
import subprocess
import sys
import textwrap
from pathlib import Path
from typing import Any

import can
import pytest

from app.campaign.analysis import Job, logs_hash, where
from app.config import Config
from app.errors import C2nError
from app.pipeline import Pipeline
from app.sinks.recorder import SessionRecorder
from app.sinks.summary import build
from app.sources.sessions import read_session
from tests.simulated import cached_drive
from tests.test_reliability_inputs import run_cli

REPO = Path(__file__).resolve().parents[1]


class Capped:
    """A file that holds at most ``cap`` bytes, as FAT32 holds 4 GiB: a write that crosses the
    cap writes up to it, the next one fails with EFBIG."""

    def __init__(self, file: Any, cap: int) -> None:
        self.file, self.cap = file, cap

    def write(self, data: memoryview) -> int:
        room = self.cap - os.fstat(self.file.fileno()).st_size
        if room <= 0:
            raise OSError(errno.EFBIG, "File too large")
        return int(self.file.write(data[:room]))

    def fileno(self) -> int:
        return int(self.file.fileno())

    def close(self) -> None:
        self.file.close()


def _frames(count: int) -> list[can.Message]:
    return cached_drive("constant_radius", 41, 15.1).messages[:count]


def _same(got: list[can.Message], sent: list[can.Message], times: bool = True) -> None:
    """The same frames in the same order; ``times``: with the times sent (a live bus gives its
    own: then in order of arrival)."""
    assert len(got) == len(sent)
    for a, b in zip(got, sent, strict=True):
        assert (a.arbitration_id, bytes(a.data)) == (b.arbitration_id, bytes(b.data))
        if times:
            assert a.timestamp == pytest.approx(b.timestamp, abs=1e-6)
    if not times:
        assert all(a.timestamp <= b.timestamp for a, b in itertools.pairwise(got))


def _recorded_in_parts(folder: Path, config: Config) -> tuple[SessionRecorder, list[can.Message]]:
    """500 frames recorded into ``folder`` on a disk that holds files of 5 kB: a session in parts."""
    recorder = SessionRecorder(folder, config)
    assert recorder._spool is not None
    recorder._spool._file = Capped(recorder._spool._file, 5_000)  # type: ignore[assignment]
    sent = _frames(500)
    for msg in sent:
        recorder.on_frame(msg)
        recorder.flush()
    recorder.close()
    return recorder, sent


def test_a_log_as_large_as_its_disk_holds_goes_on_in_a_folder_beside_it(
    tmp_path: Path, config: Config
) -> None:
    sent = _frames(3000)
    recorder = SessionRecorder(tmp_path / "s", config)
    noted: list[str] = []
    recorder.on_note = noted.append
    assert recorder._spool is not None
    cap = 40_001  # not a line's end: the write that fills it ends mid-line
    recorder._spool._file = Capped(recorder._spool._file, cap)  # type: ignore[assignment]
    for i, msg in enumerate(sent):
        recorder.on_frame(msg)
        if i % 100 == 99:
            recorder.flush()
    recorder.close()
    recorder.write_summary(build(Pipeline(config).snapshot(), config, ["virtual"]).warned(recorder.notes))
    first, part = tmp_path / "s", tmp_path / "s-part2"
    assert recorder.folders == [first, part] and recorder.problem is None
    full = (first / "frames.log").read_bytes()
    assert len(full) <= cap and full.endswith(b"\n")  # back to its last whole line
    got = [*can.LogReader(first / "frames.log"), *can.LogReader(part / "frames.log")]
    _same(got, sent)
    for folder in (first, part):  # each a session folder
        assert sorted(p.name for p in (folder / "config").iterdir()) == sorted(
            p.name for p in (first / "config").iterdir()
        )
        assert (folder / "events.csv").read_text().startswith("t,event,")
        warnings = json.loads((folder / "summary.json").read_text())["warnings"]
        assert any(f"the recording goes on in {part}" in w for w in warnings)
    assert noted == [
        f"{first / 'frames.log'}: {len(full) / 1e6:.1f} MB, the largest file the disk of "
        f"{noted[0].split('the disk of ')[1].split(' holds')[0]} holds — the recording goes on in {part}"
    ]


def test_the_parts_read_as_the_one_drive_they_are(tmp_path: Path, config: Config) -> None:
    """``c2n analyze A/frames.log A-part2/frames.log --config A/config/…`` gives what the whole
    recording gives."""
    whole = SessionRecorder(tmp_path / "whole", config)
    split = SessionRecorder(tmp_path / "split", config)
    assert split._spool is not None
    split._spool._file = Capped(split._spool._file, 2_000_000)  # type: ignore[assignment]
    for i, msg in enumerate(cached_drive("constant_radius", 41, 15.1).messages):
        whole.on_frame(msg)
        split.on_frame(msg)
        if i % 500 == 499:
            whole.flush()
            split.flush()
    whole.close()
    split.close()
    assert len(split.folders) >= 2
    copy = str(tmp_path / "split" / "config" / config.path.name)
    results = []
    for logs in ([tmp_path / "whole" / "frames.log"], [f / "frames.log" for f in split.folders]):
        out = tmp_path / f"{len(logs)}.json"
        code, _, err = run_cli(["analyze", *map(str, logs), "--config", copy, "--json", str(out)])
        assert code == 0, err
        results.append(json.loads(out.read_text()))
    assert results[1]["c2n"] == results[0]["c2n"] and results[1]["c2n_ci95"] == results[0]["c2n_ci95"]
    assert results[1]["frames"]["total"] == results[0]["frames"]["total"]
    # the session folder alone is the whole session: `c2n export` and a campaign read every part
    # (they read the first alone: 43,115 of 119,522 frames, another C2n, without a word)
    code, _, err = run_cli(["export", str(tmp_path / "split"), "--no-plots", "--format", "csv"])
    assert code == 0, err
    exported = json.loads((tmp_path / "split" / "export" / "summary.json").read_text())
    assert (
        exported["c2n"] == results[0]["c2n"] and exported["frames"]["total"] == results[0]["frames"]["total"]
    )
    raws, _, _ = where(Job(tmp_path / "split", None))
    assert raws == [f / "frames.log" for f in split.folders]


def test_a_campaign_of_a_session_in_parts_runs_again_from_its_cache(tmp_path: Path, config: Config) -> None:
    """A session in parts is one drive in a campaign, its row keyed by every part's hash. Its key
    was the parts' hashes joined, a name the cache's check did not know: the second run refused
    its own folder ("holds files c2n did not write"); and eight parts' hashes made a name longer
    than a file's can be (255 bytes)."""
    recorder, _ = _recorded_in_parts(tmp_path / "s", config)
    recorder.write_summary(build(Pipeline(config).snapshot(), config, ["virtual"]).warned(recorder.notes))
    assert len(recorder.folders) == 2
    manifest = tmp_path / "manifest.csv"
    manifest.write_text("log,tyre_set\ns,A\n")
    for _ in range(2):
        code, _, err = run_cli(["campaign", str(manifest), "--workers", "1"])
        assert code in (0, 1) and "did not write" not in err and "too long" not in err, err
    rows = list((tmp_path / "manifest-campaign" / "cache").glob("*-*.json"))
    assert len(rows) == 1 and len(rows[0].name) == 70
    assert re.fullmatch("[0-9a-f]{32}", logs_hash(tmp_path / "log", [Path(f"{i}") for i in range(60)], str))


def test_a_part_folder_never_enters_one_already_there(tmp_path: Path, config: Config) -> None:
    (tmp_path / "s-part2").mkdir()
    (tmp_path / "s-part2" / "notes.txt").write_text("mine")
    recorder, sent = _recorded_in_parts(tmp_path / "s", config)
    assert recorder.folders == [tmp_path / "s", tmp_path / "s-part3"]
    assert [p.name for p in (tmp_path / "s-part2").iterdir()] == ["notes.txt"]
    parts = [tmp_path / "s" / "frames.log", tmp_path / "s-part3" / "frames.log"]
    _same([msg for part in parts for msg in can.LogReader(part)], sent)
    # a session of the user's own named so, frames and all, is not taken for a part of it
    (tmp_path / "s-part2" / "frames.log").write_text("(1.000000) can0 123#00 R\n")
    assert read_session(tmp_path / "s")[0] == parts


def test_an_asc_as_large_as_its_disk_holds_stops_and_says_why(tmp_path: Path, config: Config) -> None:
    """An ASC file has a header a part would need again: it stops, and says what to do."""
    recorder = SessionRecorder(tmp_path / "s", config, ".asc")
    problems: list[str] = []
    recorder.on_problem = problems.append
    assert recorder._spool is not None
    recorder._spool._file = Capped(recorder._spool._file, 20_000)  # type: ignore[assignment]
    for msg in _frames(2000):
        recorder.on_frame(msg)
        recorder.flush()
    recorder.close()
    assert recorder.folders == [tmp_path / "s"]
    assert len(problems) == 1
    assert "the recording stopped — the file is as large as the disk of" in problems[0]
    assert problems[0].endswith(
        "the live numbers go on — record as .log (it goes on in a new folder), or onto an exFAT, "
        "NTFS or ext4 disk"
    )


@pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_FSIZE caps a file's size as FAT32 does")
def test_live_on_a_disk_that_holds_small_files_records_every_frame_in_parts(tmp_path: Path) -> None:
    """``c2n live`` itself, its files capped by the kernel (RLIMIT_FSIZE, as FAT32's 4 GiB) at
    150 kB: every frame sent is in the parts, in order, and the run says where it went on."""
    record, count = tmp_path / "sessions", 12_000
    child = textwrap.dedent(
        f"""
        import os, resource, signal, sys, threading, time
        sys.path.insert(0, {str(REPO)!r})
        import can
        from app.cli import main
        from tests.simulated import cached_drive

        RECORD = {str(record)!r}

        def send():
            while not (os.path.isdir(RECORD) and os.listdir(RECORD)):
                time.sleep(0.01)
            with can.Bus(interface="virtual", channel="parts") as bus:
                for i, msg in enumerate(cached_drive("constant_radius", 41, 15.1).messages[:{count}]):
                    bus.send(msg)
                    if i % 8 == 7:
                        time.sleep(0.002)
            time.sleep(0.5)
            os.kill(os.getpid(), signal.SIGINT)

        resource.setrlimit(resource.RLIMIT_FSIZE, (150_000, resource.RLIM_INFINITY))
        threading.Thread(target=send, daemon=True).start()
        sys.exit(main(["live", "-i", "virtual", "-c", "parts", "--record", RECORD]))
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", child], capture_output=True, text=True, timeout=300, cwd=REPO
    )
    assert done.returncode == 0, done.stderr
    folders = sorted(record.iterdir(), key=lambda p: (len(p.name), p.name))
    assert len(folders) >= 4  # 12,000 frames of about 45 bytes in parts of 150 kB
    assert [f.name for f in folders[1:]] == [f"{folders[0].name}-part{n}" for n in range(2, len(folders) + 1)]
    got = [msg for folder in folders for msg in can.LogReader(folder / "frames.log")]
    _same(got, _frames(count), times=False)
    for folder in folders:
        assert (folder / "frames.log").stat().st_size <= 150_000
        assert (folder / "summary.json").exists() and list((folder / "config").glob("*.toml"))
    said = " ".join(done.stdout.split())
    assert f"the recording goes on in {folders[1]}" in said
    assert "session saved in " + ", ".join(str(f) for f in folders) in said


def test_a_session_renamed_is_read_whole_and_one_without_its_part_is_refused(
    tmp_path: Path, config: Config
) -> None:
    """The first folder names its parts (`parts.json`): renamed, it is still read whole; with a
    part moved away, `c2n export` of it says which part is missing instead of exporting the first
    alone as if it were the session."""
    recorder, sent = _recorded_in_parts(tmp_path / "s", config)
    assert len(recorder.folders) >= 2
    (tmp_path / "s").rename(tmp_path / "day1")
    logs, _ = read_session(tmp_path / "day1")
    assert logs == [tmp_path / "day1" / "frames.log", *(f / "frames.log" for f in recorder.folders[1:])]
    _same([msg for log in logs for msg in can.LogReader(log)], sent)
    from app.sources.sessions import parts_left_out

    # a part given alone still names its session, now day1 (it named none: its name gives `s`)
    ((_, said),) = parts_left_out([recorder.folders[1] / "frames.log"])
    assert said.startswith(f"part 2 of {len(logs)} of the session {tmp_path / 'day1'}"), said
    (tmp_path / "elsewhere").mkdir()
    recorder.folders[1].rename(tmp_path / "elsewhere" / recorder.folders[1].name)
    code, _, err = run_cli(["export", str(tmp_path / "day1"), "--no-plots", "--format", "csv"])
    assert code == 1 and "Traceback" not in err
    assert f"its session went on in {recorder.folders[1].name}, which is not beside it" in err
    assert not (tmp_path / "day1" / "export").exists()


def test_one_part_of_a_session_in_parts_is_said_to_be_one_part(tmp_path: Path, config: Config) -> None:
    """`c2n analyze A/frames.log` — the command docs give for a session's log — read the first of
    four parts as the drive (3,613 of 13,623 samples, another C2n), and `export A-part2` the second,
    without a word of the others. Each now says which part it is and how to read them all; every
    part given, or the session folder, says nothing."""
    from app.sources.sessions import parts_left_out

    recorder, _ = _recorded_in_parts(tmp_path / "s", config)
    first, second = recorder.folders[:2]
    n = len(recorder.folders)
    logs = [folder / "frames.log" for folder in recorder.folders]
    ((path, said),) = parts_left_out([logs[0]])
    assert path == logs[0] and said.startswith(
        f"part 1 of {n} of the session {first}, which went on in parts"
    )
    assert f"give the session folder {first} to c2n export" in said and str(logs[-1]) in said
    ((_, said),) = parts_left_out([second])
    assert said.startswith(f"part 2 of {n} of the session {first}")
    assert parts_left_out(logs) == [] and parts_left_out([first]) == []
    plain = tmp_path / "plain.log"
    plain.write_bytes((first / "frames.log").read_bytes())
    assert parts_left_out([plain]) == []
    copy = str(first / "config" / config.path.name)
    _, _, err = run_cli(["analyze", str(logs[0]), "--config", copy])
    assert f"c2n: warning: {logs[0]}: part 1 of {n} of the session {first}" in err, err
    _, _, err = run_cli(["export", str(second), "--no-plots", "--format", "csv"])
    assert f"c2n: warning: {second}: part 2 of {n} of the session {first}" in err, err
    here = Path.cwd()
    try:  # standing in the part's folder, or through a link to its log (no warning, helper-31)
        os.chdir(second)
        ((_, said),) = parts_left_out([Path("frames.log")])
        assert said.startswith(f"part 2 of {n} of the session {first}")
    finally:
        os.chdir(here)
    (tmp_path / "p2.log").symlink_to(logs[1])
    ((_, said),) = parts_left_out([tmp_path / "p2.log"])
    assert said.startswith(f"part 2 of {n}")
    _, _, err = run_cli(["analyze", *map(str, logs), "--config", copy])
    assert "which went on in parts" not in err
    # gap too (helper-32: a diagnosis of three parts of six, without a word)
    _, _, err = run_cli(["gap", str(logs[0]), "--config", copy])
    assert f"c2n: warning: {logs[0]}: part 1 of {n} of the session {first}" in err, err
    assert "or every part's log to c2n gap (" in " ".join(err.split())
    # the session through a link (helper-32: its parts were looked for beside the link)
    (tmp_path / "links").mkdir()
    (tmp_path / "links" / "latest").symlink_to(first)
    assert read_session(tmp_path / "links" / "latest")[0] == [
        tmp_path / "links" / "latest" / "frames.log",
        *(Path(os.path.realpath(log)) for log in logs[1:]),
    ]


def test_a_parts_json_naming_a_folder_too_long_for_a_disk_is_one_line(tmp_path: Path, config: Config) -> None:
    """A damaged parts.json listing a 300-character name: `analyze A/frames.log` and `export A`
    ended in a traceback (File name too long)."""
    from app.sources.sessions import parts_left_out

    recorder, _ = _recorded_in_parts(tmp_path / "s", config)
    first = recorder.folders[0]
    (first / "parts.json").write_text(json.dumps({"parts": ["x" * 300]}))
    assert parts_left_out([first / "frames.log"]) == []
    code, _, err = run_cli(["export", str(first), "--no-plots", "--format", "csv"])
    assert code == 1 and "parts.json: not a list of part folders" in err and "Traceback" not in err, err


def test_a_parts_json_listing_a_part_twice_is_refused_not_counted_twice(
    tmp_path: Path, config: Config
) -> None:
    """A damaged parts.json naming one part twice (helper-31): the session was read with that
    part's samples twice — the interval √2 too narrow where they are most of the drive."""
    recorder, _ = _recorded_in_parts(tmp_path / "s", config)
    first = recorder.folders[0]
    names = [f.name for f in recorder.folders[1:]]
    for listed, twice in (([*names, names[0]], names[0]), ([first.name, *names], first.name)):
        (first / "parts.json").write_text(json.dumps({"parts": listed}))
        code, _, err = run_cli(["export", str(first), "--no-plots", "--format", "csv"])
        assert code == 1 and "Traceback" not in err, err
        assert f"parts.json: lists {twice} twice" in err, err
        assert not (first / "export").exists()


def test_a_part_whose_log_is_gone_is_named_not_left_out(tmp_path: Path, config: Config) -> None:
    """A part of a session that ended, its frames.log moved away (helper-33): the export read the
    others as the drive (9,059 of 13,628 samples, another C2n), only `the optical data stopped
    once` said. A part without a log is the run killed as its last part was made, and only that."""
    import shutil

    recorder, _ = _recorded_in_parts(tmp_path / "s", config)
    first, second = recorder.folders[:2]
    assert recorder.folders == [first, second] and not (first / "summary.json").exists()
    (second / "frames.log").rename(tmp_path / "p2.bak")  # killed as its last part was made
    assert read_session(first)[0] == [first / "frames.log"]
    (first / "summary.json").write_text("{}")  # but the session ended: its last part had frames
    with pytest.raises(C2nError, match=f"went on in {second.name}, whose log .* is not there"):
        read_session(first)
    (first / "summary.json").unlink()
    third = shutil.copytree(second, tmp_path / "s-part3")  # a part after it: it had frames
    (third / "frames.log").write_bytes((tmp_path / "p2.bak").read_bytes())
    (first / "parts.json").write_text(json.dumps({"parts": [second.name, third.name]}))
    with pytest.raises(C2nError, match=f"went on in {second.name}, whose log"):
        read_session(first)
    code, _, err = run_cli(["export", str(first), "--no-plots", "--format", "csv"])
    assert code == 1 and "whose log (frames.log/.asc/.blf) is not there" in err and "Traceback" not in err
