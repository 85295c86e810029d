"""What a power cut leaves: c2n's files are on the disk before they are put in place.

A kill leaves the system running, which writes its cache out; a power cut (the ignition, a flat
laptop battery) loses the cache. So these tests watch what reaches the disk: every ``fsync``
(the inode and its size then) and every rename, in order. A file renamed into place before its
content was synced can come back empty after a cut, the older one gone; a name not synced in its
folder can come back missing."""

import errno
import os
import stat
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

import can
import pytest

from app.config import load_config
from app.errors import OutputError
from app.output import durable, files
from app.output.files import files_together, write_atomically
from app.sinks.recorder import SessionRecorder
from tests.simulated import cached_drive
from tests.test_reliability_inputs import run_cli
from tests.test_reliability_outputs import day  # noqa: F401  (a fixture)


@dataclass
class Disk:
    """What reached the disk, in order: ("sync", inode, size, is_folder) and ("rename", dst)."""

    events: list[tuple[object, ...]] = field(default_factory=list)

    def synced_before(self, path: Path, at: int) -> bool:
        """``path`` as it is now (its inode and size) was synced before event ``at``."""
        now = os.stat(path)
        return ("sync", now.st_ino, now.st_size, stat.S_ISDIR(now.st_mode)) in self.events[:at]

    def folder_synced_after(self, folder: Path, at: int) -> bool:
        ino = os.stat(folder).st_ino
        return any(e[0] == "sync" and e[1] == ino and e[3] for e in self.events[at:])

    def put_in_place(self, path: Path) -> int:
        """The index of the last rename that gave ``path`` its name."""
        found = [i for i, e in enumerate(self.events) if e[0] == "rename" and e[1] == os.path.realpath(path)]
        assert found, f"{path} was never renamed into place"
        return found[-1]


@pytest.fixture
def disk(monkeypatch: pytest.MonkeyPatch) -> Iterator[Disk]:
    seen = Disk()
    fsync, replace, rename, exchange = os.fsync, os.replace, os.rename, files.exchange

    def watched_fsync(fd: int) -> None:
        fsync(fd)
        now = os.fstat(fd)
        seen.events.append(("sync", now.st_ino, now.st_size, stat.S_ISDIR(now.st_mode)))

    def renamed(move: Callable[..., None]) -> Callable[..., None]:
        def call(src: Path | str, dst: Path | str, *args: object, **kwargs: object) -> None:
            move(src, dst, *args, **kwargs)
            seen.events.append(("rename", os.path.realpath(dst)))

        return call

    def watched_exchange(a: Path, b: Path) -> bool:
        done = exchange(a, b)
        if done:
            seen.events.append(("rename", os.path.realpath(b)))
        return done

    monkeypatch.setattr(os, "fsync", watched_fsync)
    monkeypatch.setattr(os, "replace", renamed(replace))
    monkeypatch.setattr(os, "rename", renamed(rename))
    monkeypatch.setattr(files, "exchange", watched_exchange)
    yield seen


def test_a_result_file_is_on_the_disk_before_it_takes_the_older_one_s_place(
    tmp_path: Path, disk: Disk
) -> None:
    """Renamed over the older summary before its content was synced, a power cut could leave
    summary.json empty, the older one gone."""
    out = tmp_path / "summary.json"
    out.write_text('{"c2n": 14.0}\n')
    write_atomically(out, lambda tmp: tmp.write_text('{"c2n": 15.1}\n'), "the summary")
    at = disk.put_in_place(out)
    assert disk.synced_before(out, at), "the content was not on the disk before the rename"
    assert disk.folder_synced_after(tmp_path, at), "the new name was not on the disk"


def test_an_export_folder_is_on_the_disk_before_it_takes_the_older_one_s_place(
    day: Path,  # noqa: F811
    disk: Disk,
) -> None:
    drive, out = day / "d.blf", day / "exp"
    argv = ["export", str(drive), "--config", str(day / "car.toml"), "--out", str(out), "--no-plots"]
    assert run_cli(argv)[0] == 0  # an older export: the next one takes its place
    disk.events.clear()
    code, _, err = run_cli(argv)
    assert code == 0, err
    at = disk.put_in_place(out)
    written = [p for p in sorted(out.rglob("*")) if p.is_file()]
    assert {p.name for p in written} >= {"channels.csv", "events.csv", "summary.json"}
    for path in [*written, out]:
        assert disk.synced_before(path, at), f"{path.name} was not on the disk before the swap"
    assert disk.folder_synced_after(day, at), "the swap was not on the disk"


def test_a_campaign_s_results_are_on_the_disk_before_they_are_put_in_place(
    tmp_path: Path, disk: Disk
) -> None:
    names = ("results.csv", "comparison.json", "report.html")
    for name in names:
        (tmp_path / name).write_text("old")
    with files_together(tmp_path, names) as staging:
        for name in names:
            (staging / name).write_text(f"new {name}")
    for name in names:
        at = disk.put_in_place(tmp_path / name)
        assert (tmp_path / name).read_text() == f"new {name}"
        assert disk.synced_before(tmp_path / name, at), name
        assert disk.folder_synced_after(tmp_path, at), name


def test_a_disk_that_refuses_to_sync_leaves_the_older_file_and_says_so(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An I/O error on the sync (a failing card, NFS's late ENOSPC): the data may not be there,
    so it is not put in place — the older file stays, no temporary is left, the file is named."""
    out = tmp_path / "summary.json"
    out.write_text("older")

    def failing(fd: int) -> None:
        raise OSError(errno.EIO, "Input/output error")

    monkeypatch.setattr(os, "fsync", failing)
    with pytest.raises(OutputError, match=r"summary\.json: cannot write the summary \(Input/output error\)"):
        write_atomically(out, lambda tmp: tmp.write_text("newer"), "the summary")
    assert out.read_text() == "older"
    assert [p.name for p in tmp_path.iterdir()] == ["summary.json"]


def test_a_file_system_without_sync_is_written_as_before(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """EINVAL: the file system has no sync (some network and FUSE mounts): nothing more can be done."""

    def unsupported(fd: int) -> None:
        raise OSError(errno.EINVAL, "Invalid argument")

    monkeypatch.setattr(os, "fsync", unsupported)
    write_atomically(tmp_path / "summary.json", lambda tmp: tmp.write_text("new"), "the summary")
    assert (tmp_path / "summary.json").read_text() == "new"


FULL_SYNC = 51  # macOS's F_FULLFSYNC, set where these tests run on Linux


def test_on_macos_a_file_is_synced_through_the_drive_s_cache_before_the_rename(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """macOS's fsync leaves the data in the drive's own cache, which a cut loses: there the sync
    is fcntl's F_FULLFSYNC, asked for on the temporary before it takes the older file's place."""
    import fcntl

    events: list[tuple[str, object]] = []
    fsync, replace = os.fsync, os.replace

    def full_sync(fd: int, command: int, *args: object) -> int:
        assert command == FULL_SYNC
        fsync(fd)
        events.append(("full", os.fstat(fd).st_size))
        return 0

    monkeypatch.setattr(durable, "_FULL_SYNC", FULL_SYNC)
    monkeypatch.setattr(fcntl, "fcntl", full_sync)
    monkeypatch.setattr(os, "fsync", lambda fd: events.append(("fsync", fd)))
    monkeypatch.setattr(os, "replace", lambda a, b: (replace(a, b), events.append(("rename", b)))[0])
    out = tmp_path / "summary.json"
    out.write_text('{"c2n": 14.0}\n')
    write_atomically(out, lambda tmp: tmp.write_text('{"c2n": 15.1}\n'), "the summary")
    assert out.read_text() == '{"c2n": 15.1}\n'
    kinds = [kind for kind, _ in events]
    assert "fsync" not in kinds, (
        "fsync alone was asked for where the full sync is the one that reaches the disk"
    )
    assert events[kinds.index("rename") - 1] == ("full", out.stat().st_size)  # the new content, then in place
    assert kinds[kinds.index("rename") + 1 :] == ["full"]  # and the folder's new name


def test_on_macos_a_file_system_without_the_full_sync_gets_fsync(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """SMB shares and some FAT drivers refuse F_FULLFSYNC: those are synced as elsewhere."""
    import fcntl

    synced: list[int] = []
    fsync = os.fsync

    def refused(fd: int, command: int, *args: object) -> int:
        raise OSError(errno.ENOTSUP, "Operation not supported")

    def watched(fd: int) -> None:
        fsync(fd)
        synced.append(os.fstat(fd).st_size)

    monkeypatch.setattr(durable, "_FULL_SYNC", FULL_SYNC)
    monkeypatch.setattr(fcntl, "fcntl", refused)
    monkeypatch.setattr(os, "fsync", watched)
    out = tmp_path / "summary.json"
    write_atomically(out, lambda tmp: tmp.write_text('{"c2n": 15.1}\n'), "the summary")
    assert out.read_text() == '{"c2n": 15.1}\n'
    assert out.stat().st_size in synced


def test_a_folder_c2n_may_write_in_but_not_list_takes_the_result(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A drop folder (mode 0300: write, no read) cannot be opened to sync its entries: the file
    put in place there is a success, not an error after the fact."""
    opened = os.open

    def no_listing(path: object, flags: int, *args: int) -> int:
        if os.path.isdir(str(path)):
            raise PermissionError(errno.EACCES, "Permission denied")
        return opened(path, flags, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(os, "open", no_listing)
    write_atomically(tmp_path / "summary.json", lambda tmp: tmp.write_text("new"), "the summary")
    assert (tmp_path / "summary.json").read_text() == "new"


def _frames(n: int) -> list[can.Message]:
    return cached_drive("constant_radius", 41, 15.1).messages[:n]


def test_a_live_recording_is_on_the_disk_every_second_not_only_at_its_end(tmp_path: Path, disk: Disk) -> None:
    """The raw log is flushed to the system every 50 ms, which a kill survives; a power cut loses
    what the system has not written out (up to half a minute on Linux's defaults). Synced every
    ``sync_every_s`` while the session runs, the cut loses at most that much."""
    session = tmp_path / "session"
    recorder = SessionRecorder(session, load_config(), ".log", sync_every_s=0.05)
    assert disk.folder_synced_after(tmp_path, 0), "the session folder's name was not on the disk"
    frames = _frames(3000)
    for chunk in (frames[:1000], frames[1000:2000], frames[2000:]):
        for message in chunk:
            recorder.on_frame(message)
        recorder.flush()
        size, deadline = recorder.raw_path.stat().st_size, time.monotonic() + 5.0
        ino = recorder.raw_path.stat().st_ino
        while ("sync", ino, size, False) not in disk.events and time.monotonic() < deadline:
            time.sleep(0.01)
        assert ("sync", ino, size, False) in disk.events, "what was recorded was not synced while recording"
    recorder.close()
    for path in (recorder.raw_path, session / "events.csv"):
        assert disk.synced_before(path, len(disk.events)), f"{path.name} was not on the disk at the end"
    assert disk.folder_synced_after(session, 0)


def test_a_slow_disk_does_not_hold_up_the_recording(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A USB stick's sync can take a second: made on a thread of its own, it never keeps the live
    loop from handing the next frames to the system."""
    recorder = SessionRecorder(tmp_path / "session", load_config(), ".log", sync_every_s=0.01)
    held, release = threading.Event(), threading.Event()
    fsync = os.fsync

    def slow(fd: int) -> None:
        held.set()
        release.wait(10.0)
        fsync(fd)

    monkeypatch.setattr(os, "fsync", slow)
    assert held.wait(5.0), "no sync was made"
    frames = _frames(2000)
    for i in range(0, 2000, 100):
        for message in frames[i : i + 100]:
            recorder.on_frame(message)
        recorder.flush()
    flushed_while_held = not release.is_set()
    release.set()
    recorder.close()
    assert flushed_while_held
    assert len(list(can.LogReader(recorder.raw_path))) == 2000


def test_a_disk_that_refuses_a_recording_s_sync_is_said_once_and_the_session_goes_on(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    recorder = SessionRecorder(tmp_path / "session", load_config(), ".log", sync_every_s=0.01)
    said: list[str] = []
    recorder.on_problem = said.append
    raw = recorder.raw_path.stat().st_ino
    fsync = os.fsync

    def failing(fd: int) -> None:
        if os.fstat(fd).st_ino == raw:
            raise OSError(errno.EIO, "Input/output error")
        fsync(fd)

    monkeypatch.setattr(os, "fsync", failing)
    frames = _frames(1000)
    deadline = time.monotonic() + 5.0
    for i in range(0, 1000, 100):
        for message in frames[i : i + 100]:
            recorder.on_frame(message)
        while not said and i == 0 and time.monotonic() < deadline:
            time.sleep(0.01)
            recorder.flush()
        recorder.flush()
    recorder.close()
    assert len(said) == 1 and "did not confirm the frames written (Input/output error)" in said[0]
    assert len(list(can.LogReader(recorder.raw_path))) == 1000


def test_when_a_process_started_is_read_from_the_system(tmp_path: Path) -> None:
    before = time.time()
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        after = time.time()
        started = files._started_s(child.pid)
        assert started is not None and before - 1.5 <= started <= after + 0.5
    finally:
        child.kill()
        child.wait()


def test_leftovers_named_after_a_number_another_process_has_after_a_reboot_are_cleared(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A power cut between a run's two renames (where the folders cannot trade places in one
    step) leaves ``.exp.old-PID-…`` and no ``exp``; after the reboot that number is some other
    process's, started after. Taken for a run still writing, the older folder was never put back
    and a staging folder never removed. The leftover's own process, still running, keeps them."""
    child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
    try:
        out = tmp_path / "exp"
        older = tmp_path / f".exp.old-{child.pid}-0123abcd"
        older.mkdir()
        (older / "summary.json").write_text("the previous export")
        staging = tmp_path / f".exp.partial-{child.pid}-4567cdef"
        staging.mkdir()
        # the process running now started before its leftovers: they are kept
        files.recover_swapped_away(out, lambda path: True)
        assert files.remove_stale(tmp_path, ".exp.partial-") == [] and older.is_dir()
        assert not out.exists()
        # after a reboot: the same number, a process started after its leftovers last changed
        monkeypatch.setattr(files, "_started_s", lambda pid: time.time() + 60.0)
        files.recover_swapped_away(out, lambda path: True)
        assert (out / "summary.json").read_text() == "the previous export" and not older.exists()
        assert files.remove_stale(tmp_path, ".exp.partial-") == [staging] and not staging.exists()
    finally:
        child.kill()
        child.wait()
