"""`c2n split LOG`: a log holding two tyre sets across a pause of its optical sensor, cut into a
file per part (``app/cli/split.py``) — every frame once, in the input's format, each part its own
C2n in `c2n analyze` — and what it refuses, writing nothing."""

import gzip
import json
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import can
import numpy as np
import pytest

from app.config import load_config
from app.results.log_clock import sensor_messages
from app.sources.logs import LogReport, LogSource, read_log
from tests.test_reliability_inputs import run_cli
from tests.test_separate_recordings import _drive, _one_file

REPO = Path(__file__).resolve().parents[1]
TRUTH = (14.89, 15.91)  # the two tyre sets' C2n, before and after the pause
NAME = "day [tyre change] 1"  # brackets and spaces in the input's name


def _key(m: can.Message) -> tuple[object, ...]:
    return (
        m.timestamp,
        m.arbitration_id,
        m.is_extended_id,
        bytes(m.data),
        m.dlc,
        m.channel,
        m.is_remote_frame,
        m.is_error_frame,
        m.is_fd,
    )


def _frames(path: Path) -> list[tuple[object, ...]]:
    return [_key(m) for m in read_log(path, LogReport(path))]


@pytest.fixture(scope="module")
def day(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    """A logger left recording through a tyre change (14.89, ten minutes' pause, 15.91), as a
    candump .log and a .blf, each in a folder of its own; plain.log: one drive, no pause."""
    before, after = _drive(TRUTH[0], 5).messages, _drive(TRUTH[1], 6).messages
    shift = before[-1].timestamp + 600.0 - after[0].timestamp
    logs = {}
    for suffix in (".log", ".blf"):
        folder = tmp_path_factory.mktemp(suffix[1:])
        logs[suffix] = _one_file(folder / f"{NAME}{suffix}", (before, 0.0), (after, shift))
    logs["plain"] = _one_file(tmp_path_factory.mktemp("plain") / "plain.log", (_drive(15.1, 1).messages, 0.0))
    return logs


def _part_files(folder: Path) -> list[Path]:
    """The part files a split wrote, by name: all but its parts.json."""
    return sorted(p for p in folder.iterdir() if p.name != "parts.json")


def _split(log: Path, *more: str) -> tuple[int, str, str]:
    return run_cli(["split", str(log), *more])


@pytest.fixture(scope="module")
def said(day: dict[str, Path]) -> dict[str, str]:
    """Each two-drive log split into its default folder, beside it: what the command said."""
    words = {}
    for suffix in (".log", ".blf"):
        code, out, err = _split(day[suffix])
        assert code == 0, err
        words[suffix] = out
    return words


@pytest.fixture(scope="module")
def parts(day: dict[str, Path], said: dict[str, str]) -> dict[str, list[Path]]:
    """The part files of each split, in order."""
    return {suffix: _part_files(day[suffix].with_name(f"{NAME}-parts")) for suffix in said}


@pytest.mark.parametrize("suffix", [".log", ".blf"])
def test_every_frame_is_in_exactly_one_part_in_order_as_read(
    day: dict[str, Path], parts: dict[str, list[Path]], suffix: str
) -> None:
    """The parts, one after the other, hold the input's frames exactly (time, id, data, channel
    …), none lost or doubled; each in the input's format, named by its part and seconds."""
    names = [p.name for p in parts[suffix]]
    assert names == [f"{NAME} part 1 of 2 (0–150 s){suffix}", f"{NAME} part 2 of 2 (750–900 s){suffix}"]
    whole = _frames(day[suffix])
    split = [_frames(p) for p in parts[suffix]]
    assert sum(len(s) for s in split) == len(whole)
    assert [frame for s in split for frame in s] == whole


@pytest.mark.parametrize("suffix", [".log", ".blf"])
def test_each_part_holds_its_own_drive_s_frames_as_within_file_cuts_them(
    day: dict[str, Path], parts: dict[str, list[Path]], suffix: str
) -> None:
    """Each part holds the frames of its drive, every id, and no other's: the second drive's
    vehicle bus, which wakes 0.2 s before its sensor, is in part 2 (cut at the sensor's first
    frame after the pause, part 1 had ended with them). `within_file.part_of` — the parts
    `c2n analyze` checks alone — puts every frame where the file is."""
    from app.results.within_file import cuts, part_of

    before = len(_drive(TRUTH[0], 5).messages)
    whole = _frames(day[suffix])
    assert [len(_frames(p)) for p in parts[suffix]] == [before, len(whole) - before]
    config = load_config()
    source = LogSource(
        [day[suffix]], spaced=frozenset(sensor_messages(config)), pause_s=config.filter.gap_reset_s
    )
    times = np.array([m.timestamp for m in source])
    assert np.bincount(part_of(cuts(source.reports[0].spacing.pauses), times)).tolist() == [
        before,
        len(whole) - before,
    ]


@pytest.mark.parametrize("suffix", [".log", ".blf"])
def test_each_part_analysed_alone_gives_its_own_tyre_sets_c2n(
    parts: dict[str, list[Path]], suffix: str, tmp_path: Path
) -> None:
    """`c2n analyze` of each part: a C2n whose interval holds that part's truth (the whole file
    is refused: its parts disagree)."""
    for part, truth in zip(parts[suffix], TRUTH, strict=True):
        summary = tmp_path / f"{truth}.json"
        code, _, err = run_cli(["analyze", str(part), "--json", str(summary)])
        assert code == 0, err
        low, high = json.loads(summary.read_text())["c2n_ci95"]
        assert low <= truth <= high, (part.name, low, high)


@pytest.fixture(scope="module")
def short() -> list[can.Message]:
    """Half a minute of each drive, ten minutes apart: enough frames for every format's writer."""
    before, after = _drive(TRUTH[0], 5).messages, _drive(TRUTH[1], 6).messages
    head = [m for m in before if m.timestamp - before[0].timestamp < 30.0]
    shift = head[-1].timestamp + 600.0 - after[0].timestamp
    tail = [m for m in after if m.timestamp - after[0].timestamp < 30.0]
    return [*head, *(_shifted(m, shift) for m in tail)]


def _shifted(m: can.Message, shift_s: float) -> can.Message:
    return can.Message(
        timestamp=m.timestamp + shift_s,
        arbitration_id=m.arbitration_id,
        is_extended_id=m.is_extended_id,
        data=m.data,
        channel=m.channel,
    )


@pytest.mark.parametrize(
    ("suffix", "written"),
    [
        (".asc", ".asc"),
        (".csv", ".csv"),
        (".log.gz", ".log.gz"),
        (".mf4", ".mf4"),
        (".trc", ".blf"),
        (".blf.gz", ".blf"),
    ],
)
def test_other_formats_are_split_frame_for_frame(
    short: list[can.Message], tmp_path: Path, suffix: str, written: str
) -> None:
    """ASC (its header's date keeps milliseconds: each part counts from the input's start),
    CSV, MF4 and a gzipped candump log are written as read; TRC, which python-can's writer does
    not give back as read (channels one higher, no remote, error or FD frames), as BLF, and said;
    a gzipped BLF as plain BLF (its writer seeks back, which a gzip stream cannot), and said —
    it said `python-can cannot write .blf files`."""
    if suffix == ".blf.gz":  # python-can writes no gzipped BLF: gzip one
        plain = _one_file(tmp_path / "plain.blf", (short, 0.0))
        log = tmp_path / f"d{suffix}"
        log.write_bytes(gzip.compress(plain.read_bytes()))
        plain.unlink()
    else:
        log = _one_file(tmp_path / f"d{suffix}", (short, 0.0))
    code, _, err = _split(log)
    assert code == 0, err
    files = _part_files(tmp_path / "d-parts")
    assert [p.name for p in files] == [
        f"d part 1 of 2 (0–30 s){written}",
        f"d part 2 of 2 (630–660 s){written}",
    ]
    assert [frame for p in files for frame in _frames(p)] == _frames(log)
    assert ("the parts are written as" in err) == (suffix != written)
    assert "cannot write" not in err


def test_the_output_says_each_part_and_how_to_go_on(said: dict[str, str]) -> None:
    words = said[".log"]
    assert "2 parts between the optical sensor's pauses" in words
    assert f"{NAME} part 1 of 2 (0–150 s).log 0.0–" in words and "frames" in words
    assert f"{NAME} part 2 of 2 (750–900 s).log" in words
    assert "c2n analyze" in words and "--pool the parts of one set of tyres" in words


def test_a_second_split_goes_to_a_new_folder_never_into_the_first(
    day: dict[str, Path], parts: dict[str, list[Path]]
) -> None:
    """The default folder is taken: `-parts-2`, the first split left as it was."""
    first = {p: p.stat().st_mtime_ns for p in parts[".log"]}
    code, _, err = _split(day[".log"])
    assert code == 0, err
    again = day[".log"].with_name(f"{NAME}-parts-2")
    assert [p.name for p in _part_files(again)] == [p.name for p in parts[".log"]]
    assert {p: p.stat().st_mtime_ns for p in parts[".log"]} == first


def test_a_log_without_a_pause_is_not_split_and_nothing_is_written(day: dict[str, Path]) -> None:
    code, _, err = _split(day["plain"])
    assert code == 1
    assert err.count("\n") == 1 and "never pause longer than gap_reset_s" in err
    assert "nothing to split (nothing written)" in err
    assert sorted(p.name for p in day["plain"].parent.iterdir()) == ["plain.log"]


def test_out_naming_the_input_is_refused(day: dict[str, Path]) -> None:
    code, _, err = _split(day["plain"], "--out", str(day["plain"]))
    assert code == 2 and err.count("\n") == 1 and "that is an input of this command" in err


def test_an_out_folder_holding_someone_elses_file_is_left_untouched(
    day: dict[str, Path], tmp_path: Path
) -> None:
    """Refused before the log is read: the folder holds the user's file, as it was, and nothing
    else."""
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("my notes")
    code, _, err = _split(day[".log"], "--out", str(out))
    assert code == 1 and err.count("\n") == 1
    assert "holds files c2n did not write (notes.txt)" in err
    assert [p.name for p in out.iterdir()] == ["notes.txt"] and (out / "notes.txt").read_text() == "my notes"


def test_out_takes_a_new_folder_and_replaces_an_older_split_of_the_log(
    day: dict[str, Path], parts: dict[str, list[Path]], tmp_path: Path
) -> None:
    out = tmp_path / "split"
    for _ in range(2):
        code, _, err = _split(day[".log"], "--out", str(out))
        assert code == 0, err
        assert [p.name for p in _part_files(out)] == [p.name for p in parts[".log"]]
    assert [p.name for p in tmp_path.iterdir()] == ["split"]  # no temporary left


@pytest.mark.parametrize(
    "theirs",
    [
        f"{NAME} part 1 of 1 (my notes on the tyre change).txt",  # named like a part
        f"{NAME} part 7 of 9 (from the logger).log",
    ],
)
def test_files_merely_named_like_parts_are_the_users_and_left_untouched(
    day: dict[str, Path], tmp_path: Path, theirs: str
) -> None:
    """A part's name was enough to be replaced: a user's notes or logger file so named went,
    without a word. Only what parts.json lists is a split's."""
    out = tmp_path / "mine"
    out.mkdir()
    (out / theirs).write_text("mine")
    code, _, err = _split(day[".log"], "--out", str(out))
    assert code == 1 and "holds files c2n did not write" in err
    assert [p.name for p in out.iterdir()] == [theirs] and (out / theirs).read_text() == "mine"


def test_the_split_of_another_log_of_the_same_name_is_not_replaced(
    day: dict[str, Path], tmp_path: Path
) -> None:
    """Two cars' `day.log` split into one --out: the first car's parts went, replaced by the
    second's. The second is refused; the first split is as it was."""
    out = tmp_path / "split"
    other = tmp_path / "car 2" / day[".log"].name
    other.parent.mkdir()
    other.write_bytes(day[".log"].read_bytes())
    assert _split(day[".log"], "--out", str(out))[0] == 0
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    code, _, err = _split(other, "--out", str(out))
    assert code == 1 and "holds files c2n did not write" in err
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before


def test_parts_json_lists_the_log_and_each_part(day: dict[str, Path], parts: dict[str, list[Path]]) -> None:
    listed = json.loads((parts[".log"][0].parent / "parts.json").read_text())
    assert listed["log"] == str(day[".log"].resolve())
    assert [p["file"] for p in listed["parts"]] == [p.name for p in parts[".log"]]
    assert [p["frames"] for p in listed["parts"]] == [len(_frames(p)) for p in parts[".log"]]
    assert listed["parts"][1]["sensor_from_s"] == pytest.approx(750.0, abs=1.0)


def test_a_log_without_the_optical_sensor_is_refused(tmp_path: Path) -> None:
    sensor = set(sensor_messages(load_config()))
    kept = [m for m in _drive(15.1, 1).messages if m.arbitration_id not in sensor]
    log = _one_file(tmp_path / "vehicle only.log", (kept, 0.0))
    code, _, err = _split(log)
    assert code == 1 and err.count("\n") == 1
    assert "no frames of the optical sensor" in err and "--config" in err
    assert [p.name for p in tmp_path.iterdir()] == ["vehicle only.log"]


def test_a_log_timed_in_milliseconds_gives_its_clocks_reason(tmp_path: Path) -> None:
    """A pause at every frame: the clock's refusal, not a part per frame."""
    drive = _drive(15.1, 1).messages[:20_000]
    log = tmp_path / "ms.log"
    with can.Logger(log) as writer:
        for m in drive:
            writer.on_message_received(
                can.Message(
                    timestamp=m.timestamp * 1000.0,
                    arbitration_id=m.arbitration_id,
                    is_extended_id=m.is_extended_id,
                    data=m.data,
                    channel=m.channel,
                )
            )
    code, _, err = _split(log)
    assert code == 1 and err.count("\n") == 1
    assert "timestamps in milliseconds read as seconds" in err and "(nothing written)" in err
    assert [p.name for p in tmp_path.iterdir()] == ["ms.log"]


@pytest.mark.skipif(sys.platform != "linux", reason="RLIMIT_FSIZE caps a file's size, as a full disk does")
def test_a_full_disk_is_one_line_naming_the_file_and_leaves_nothing(
    day: dict[str, Path], tmp_path: Path
) -> None:
    """Files capped by the kernel at 1 MB (the parts are 3 MB): one line naming the part, exit
    1, no folder, no temporary."""
    log = tmp_path / day[".log"].name
    log.write_bytes(day[".log"].read_bytes())
    child = textwrap.dedent(
        f"""
        import resource, signal, sys
        sys.path.insert(0, {str(REPO)!r})
        from app.cli import main
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the cap fails, as on a full disk
        resource.setrlimit(resource.RLIMIT_FSIZE, (1_000_000, resource.RLIM_INFINITY))
        sys.exit(main(["split", {str(log)!r}]))
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", child], capture_output=True, text=True, timeout=300, cwd=REPO
    )
    assert done.returncode == 1, done.stderr
    [line] = done.stderr.splitlines()
    assert f"{NAME}-parts/{NAME} part 1 of 2 (0–150 s).log: cannot write the part (File too large)" in line
    assert line.endswith("— nothing written")
    assert [p.name for p in tmp_path.iterdir()] == [log.name]


def _flaky(log: Path, late: bool = False) -> list[can.Message]:
    """A sensor whose connector drops out every two seconds, 150 times, a vehicle frame going on
    through every pause, written to ``log`` in time order — ``late``: and the first part's first
    vehicle frame again at the end, as a log out of order across all its pauses would hold it (a
    sensor's frame there is the clock going back: a part of its own)."""
    sensor = min(sensor_messages(load_config()))
    frames = []
    for p in range(150):
        frames += [
            can.Message(timestamp=2.0 * p + 0.01 * i, arbitration_id=sensor, data=bytes(8)) for i in range(20)
        ]
        frames += [
            can.Message(timestamp=2.0 * p + 0.1 * i + 0.005, arbitration_id=0x7A0, data=bytes([p % 256]))
            for i in range(20)
        ]
    frames.sort(key=lambda m: m.timestamp)
    with can.CanutilsLogWriter(log) as writer:
        vehicle = next(m for m in frames if m.arbitration_id == 0x7A0)
        for m in [*frames, vehicle] if late else frames:
            writer.on_message_received(m)
    return frames


@pytest.mark.skipif(sys.platform == "win32", reason="RLIMIT_NOFILE is POSIX's")
def test_a_log_of_hundreds_of_pauses_is_split_within_the_open_file_limit(tmp_path: Path) -> None:
    """150 parts split in a process allowed 48 open files (all 150 were held open at once: `Too
    many open files`, nothing written). Every frame once, each part exactly its own."""
    log = tmp_path / "flaky.log"
    frames = _flaky(log)
    child = textwrap.dedent(
        f"""
        import resource, sys
        sys.path.insert(0, {str(REPO)!r})
        from app.cli import main
        resource.setrlimit(resource.RLIMIT_NOFILE, (48, resource.getrlimit(resource.RLIMIT_NOFILE)[1]))
        sys.exit(main(["split", {str(log)!r}]))
        """
    )
    done = subprocess.run(
        [sys.executable, "-c", child], capture_output=True, text=True, timeout=300, cwd=REPO
    )
    assert done.returncode == 0, done.stderr
    written = _part_files(tmp_path / "flaky-parts")  # numbered to sort in order: part 001 of 150
    assert len(written) == 150
    kept = [[m.timestamp for m in can.LogReader(part)] for part in written]
    assert sorted(t for part in kept for t in part) == [round(m.timestamp, 6) for m in frames]  # as candump
    for p, times in enumerate(kept):  # cut at the middle of each pause: 0.19 … 2.0 s
        assert 2.0 * p - 0.905 < min(times) and (max(times) < 2.0 * p + 1.095 or p == 149)
        assert sum(1 for t in times if 2.0 * p <= t < 2.0 * p + 0.2) == 20 + 2  # the sensor's, 2 others


def test_a_frame_out_of_order_across_every_open_part_is_refused_and_nothing_written(tmp_path: Path) -> None:
    """Its part's file is finished when the frame comes: refused in one line, nothing written."""
    log = tmp_path / "late.log"
    _flaky(log, late=True)
    code, _, err = _split(log)
    assert code == 1 and "Traceback" not in err
    assert (
        "the frame at 0.005 s (id 0x7A0) belongs to late part 001 of 150 (0–0 s).log, written already" in err
    )
    assert err.rstrip().endswith("split a copy sorted by time (nothing written)")
    assert [p.name for p in tmp_path.iterdir()] == [log.name]


def _split_until_it_writes(log: Path, sig: signal.Signals) -> subprocess.Popen[bytes]:
    """`c2n split` of ``log`` in a process sent ``sig`` once its hidden folder of parts is there."""
    child = subprocess.Popen(
        [sys.executable, "-m", "app", "split", str(log)],
        cwd=REPO,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
    )
    deadline = time.monotonic() + 120
    while not list(log.parent.glob(".*.partial-*")) and child.poll() is None:
        assert time.monotonic() < deadline
        time.sleep(0.01)
    assert child.poll() is None  # still writing
    child.send_signal(sig)
    child.wait(timeout=120)
    return child


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
def test_sigterm_while_writing_leaves_nothing_and_a_killed_splits_leftovers_go_at_the_next(
    day: dict[str, Path], tmp_path: Path
) -> None:
    """SIGTERM (a closed terminal too) left the hidden folder of part files and an empty
    `-parts` folder, which the next split passed over for `-parts-2`, keeping the leftover for
    good. It is now Ctrl-C's way out: nothing left. SIGKILL cannot be caught: what it leaves goes
    at the next split of the log, which then takes the name it had claimed."""
    log = tmp_path / day[".log"].name
    log.write_bytes(day[".log"].read_bytes())
    child = _split_until_it_writes(log, signal.SIGTERM)
    assert child.returncode != 0 and b"Traceback" not in (child.stderr.read() if child.stderr else b"")
    assert [p.name for p in tmp_path.iterdir()] == [log.name]
    child = _split_until_it_writes(log, signal.SIGKILL)
    assert len(list(tmp_path.iterdir())) == 3  # the log, the claimed folder, the hidden one
    code, _, err = _split(log)
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([log.name, f"{NAME}-parts"])


def test_a_clock_set_back_between_two_tyre_sets_is_cut_there_as_a_pause_is(tmp_path: Path) -> None:
    """The two tyre sets with the logger's clock set back between them (its battery out for the
    change, a time sync, `cat b.log a.log`): `analyze` read one C2n, 14.922 [14.644, 15.211] for
    14.0 and 16.0, with only `timestamps went backwards once`, and `split` found nothing to cut.
    (python-can's writers hold a time before the first frame's at it: the logs are concatenated.)"""
    before, after = _drive(TRUTH[0], 5).messages, _drive(TRUTH[1], 6).messages
    shift = before[0].timestamp - 600.0 - after[0].timestamp  # the second 600 s before the first began
    first = _one_file(tmp_path / "a.log", (before, 0.0))
    second = _one_file(tmp_path / "b.log", (after, shift))
    log = tmp_path / "back.log"
    log.write_bytes(first.read_bytes() + second.read_bytes())
    code, _, err = run_cli(["analyze", str(log)])
    assert code == 1 and "c2n: error: the drives disagree, each alone:" in err, err
    code, out, err = _split(log)
    assert code == 0, err
    assert "2 parts between the optical sensor's pauses and where its clock goes back" in out
    files = _part_files(tmp_path / "back-parts")
    assert [len(_frames(p)) for p in files] == [len(before), len(after)]  # every frame with its own drive
    for file, truth in zip(files, TRUTH, strict=True):
        code, out, err = run_cli(["analyze", str(file)])
        assert code == 0, err
        assert float(out.split("C2n = ")[1].split()[0]) == pytest.approx(truth, rel=0.01)


def test_one_drive_twice_in_one_file_is_refused_not_counted_twice(tmp_path: Path) -> None:
    """`cat a.log a.log`: the file's two parts, one drive twice, agree, so they ran as one and
    every sample counted twice, the interval √2 too narrow. Now `analyze` refuses them as it
    refuses two files of one drive, and `split` still cuts them apart."""
    one = _one_file(tmp_path / "a.log", (_drive(TRUTH[0], 5).messages, 0.0))
    log = tmp_path / "twice.log"
    log.write_bytes(one.read_bytes() * 2)
    code, out, err = run_cli(["analyze", str(log), "--json", str(tmp_path / "twice.json")])
    assert code == 1 and "C2n =" not in out, out
    assert "twice.log's part 1 (0–150 s) and part 2 (0–150 s) hold the same driving" in err
    assert "one drive recorded twice in one file" in err and "keep one copy of the drive" in err
    assert "--pool" not in err
    assert "Traceback" not in err
    code, out, err = run_cli(["analyze", str(one)])
    assert code == 0 and float(out.split("C2n = ")[1].split()[0]) == pytest.approx(TRUTH[0], rel=0.01), err
    messages = _drive(TRUTH[0], 5).messages  # a resent piece first, then the drive twice: all weighed
    piece = _one_file(tmp_path / "piece.log", (messages[len(messages) // 10 : len(messages) // 5], 0.0))
    log.write_bytes(piece.read_bytes() + one.read_bytes() * 2)
    code, out, err = run_cli(["analyze", str(log)])
    assert code == 1 and "one drive recorded twice in one file" in err, out


def test_a_log_named_near_the_file_system_s_limit_is_split_into_names_that_fit(
    day: dict[str, Path], tmp_path: Path
) -> None:
    """A 239-byte log name: `split` read the whole log, then failed on its folder's name (`File
    name too long`), or at a 225-byte name on the first part's. The names are now cut short, the
    log named whole in parts.json."""
    log = tmp_path / f"{'ä' * 117}x.log"  # 239 bytes: ä is two
    log.write_bytes(day[".log"].read_bytes())
    code, _, err = _split(log)
    assert code == 0, err
    [folder] = [p for p in tmp_path.iterdir() if p.is_dir()]
    names = sorted(p.name for p in folder.iterdir())
    assert len(names) == 3 and all(len(name.encode()) <= 255 for name in [folder.name, *names])
    assert all("… part " in name for name in names if name != "parts.json")
    assert json.loads((folder / "parts.json").read_text())["log"] == str(log.resolve())


def test_a_damaged_log_s_split_says_in_parts_json_where_its_read_stopped(
    day: dict[str, Path], tmp_path: Path
) -> None:
    """A log damaged four fifths in: its last part ended there, as a warning said once, but
    parts.json listed it as if the drive had ended. It now keeps why the read stopped."""
    lines = day[".log"].read_bytes().split(b"\n")
    cut = len(lines) * 4 // 5
    log = tmp_path / "damaged.log"
    log.write_bytes(b"\n".join([*lines[:cut], b"(12x.5) can0 zz#!!", *lines[cut:]]))
    code, _, err = _split(log)
    assert code == 0 and "damaged.log: stopped after frame " in err, err
    listed = json.loads((tmp_path / "damaged-parts" / "parts.json").read_text())
    assert listed["read_stopped"].startswith("stopped after frame ") and "12x.5" in listed["read_stopped"]
    whole = tmp_path / "whole.log"
    whole.write_bytes(day[".log"].read_bytes())
    code, _, err = _split(whole)
    assert code == 0, err
    assert json.loads((tmp_path / "whole-parts" / "parts.json").read_text())["read_stopped"] is None
