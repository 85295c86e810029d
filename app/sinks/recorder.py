"""The session folder: raw frames as they arrive, the config and DBCs used, events and summary.

The raw log is written with python-can's writer for its suffix (a writer is a Listener, so
recording is one more sink). The live loop calls ``flush`` at least every 50 ms and whenever the
bus is idle, so after a crash (even ``kill -9``) the log reads back up to the last flush; and the
raw log and the events table are synced to the disk every second (``SYNC_S``), so after a power
cut they read back to at most a second before it.
"""

import contextlib
import copy
import errno
import json
import os
import shutil
import tomllib
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import can
from can.util import channel2int

from app.config import Config
from app.errors import C2nError, OutputError
from app.output.durable import PeriodicSync, synced, synced_tree
from app.output.files import new_folder
from app.output.paths import SESSION_CONFIG, SESSION_SUMMARY
from app.records import Crossing, CrossingRejected, Event
from app.sinks.events_csv import EventsTable
from app.sinks.sink import Sink
from app.sinks.summary import Summary
from app.sinks.summary import write as write_summary
from app.sources.sessions import PARTS_FILE, RAW_FORMATS

# how often the raw log and the events table are synced to the disk: what a power cut can lose
# (a sync is about a millisecond on a laptop's SSD and is made off the bus's thread)
SYNC_S = 1.0


class _Spool:
    """A text file for python-can's text writers that holds what they write in memory until
    ``drain`` hands it to the file in one unbuffered write: the file on disk always ends at a
    frame boundary, even after ``kill -9``, and never with half a line. ``parts``: where the file
    reaches the largest its disk holds (``EFBIG``: FAT32's 4 GiB), the lines that did not fit are
    kept (``full``) for a next file (``restart``) — a format with no header (candump's)."""

    def __init__(self, path: Path, parts: bool = False) -> None:
        self._file = path.open("wb", buffering=0)
        self._pending: list[str] = []
        self.write = self._pending.append  # a frame's line: the hot path
        self.closed = False
        self.error: OSError | None = None  # the write that failed (a full disk): nothing more is kept
        self.parts = parts
        self.full: bytes | None = None  # the file is as large as its disk holds: what did not fit

    def flush(self) -> None:
        """Nothing: what is written reaches the file at ``drain``."""

    def drain(self) -> None:
        if not self._pending or self.error is not None:
            self._pending.clear()
            return
        text = "".join(self._pending).encode()
        self._pending.clear()
        if self.full is not None:  # waiting for its next file
            self.full += text
            return
        data = memoryview(text)
        try:
            while data:
                written = self._file.write(data)
                data = data[written or 0 :]
        except OSError as error:  # from now on each drain drops what came since the last one
            if error.errno == errno.EFBIG and self.parts:
                self.full = self._cut(text, len(text) - len(data))
            else:
                self.error = error

    def _cut(self, text: bytes, written: int) -> bytes:
        """The file back to its last whole line (the write that filled it ended mid-line); the
        lines of ``text`` it does not hold."""
        whole = text.rfind(b"\n", 0, written) + 1
        with contextlib.suppress(OSError):  # else the reader skips a cut last line
            os.ftruncate(self._file.fileno(), os.fstat(self._file.fileno()).st_size - (written - whole))
        return text[whole:]

    def restart(self, path: Path) -> None:
        """Go on in a new file, ``path``, first with the lines the last one did not hold."""
        file = path.open("wb", buffering=0)
        with contextlib.suppress(OSError):
            self._file.close()
        self._file, self.closed = file, False
        rest, self.full = self.full or b"", None
        self._pending.insert(0, rest.decode())
        self.drain()

    def close(self) -> None:  # the writer's stop(): keep what it wrote last
        if not self.closed:
            self.drain()
            self.closed = True
            with contextlib.suppress(OSError):
                self._file.close()


class _CandumpWriter(can.CanutilsLogWriter):
    """python-can's candump writer, with the common frame — a classic data frame — written from
    a head cached per (channel, id): the same bytes (tests/test_recording.py) at a fraction of
    the cost, which on a saturated bus is a tenth of the live loop's time (tools/bench.py).
    Error, remote and CAN FD frames go through python-can's own formatting."""

    _MAX_HEADS = 4096  # a bus of random ids must not grow the cache without bound

    def __init__(self, file: Any) -> None:
        super().__init__(file)
        self._heads: dict[tuple[Any, int, bool, bool], tuple[str, str]] = {}

    def on_message_received(self, msg: can.Message) -> None:
        if msg.is_error_frame or msg.is_remote_frame or msg.is_fd or not msg.timestamp:
            channel = _candump_channel(msg.channel, self.channel)
            if channel != msg.channel:  # a copy: the frame itself goes on to the pipeline as it came
                msg = copy.copy(msg)
                msg.channel = channel
            super().on_message_received(msg)
            return
        first = self.last_timestamp  # python-can's writer keeps the first frame's time here
        if first is None:
            first = self.last_timestamp = msg.timestamp
        key = (msg.channel, msg.arbitration_id, msg.is_extended_id, msg.is_rx)
        head = self._heads.get(key)
        if head is None:
            head = _candump_head(msg, self.channel)
            if len(self._heads) < self._MAX_HEADS:
                self._heads[key] = head
        t = msg.timestamp if msg.timestamp >= first else first
        self.file.write(f"({t:f}){head[0]}{msg.data.hex().upper()}{head[1]}")


def _candump_channel(channel: Any, default_channel: str) -> Any:
    """The channel as one word of a candump line, which its readers split at white space: an
    interface that names no channel on its frames gets its description instead (python-can's
    serial one: ``Serial interface: loop://``), and spaces in it made the whole log unreadable."""
    if isinstance(channel, str):
        return "_".join(channel.split()) or default_channel
    return default_channel if channel is None else channel


def _candump_head(msg: can.Message, default_channel: str) -> tuple[str, str]:
    """What python-can's candump writer puts between the time and the data, and after it."""
    channel = _candump_channel(msg.channel, default_channel)
    if isinstance(channel, int) or (isinstance(channel, str) and channel.isdigit()):
        channel = f"can{channel}"
    frame_id = f"{msg.arbitration_id:08X}" if msg.is_extended_id else f"{msg.arbitration_id:03X}"
    return f" {channel} {frame_id}#", " R\n" if msg.is_rx else " T\n"


class _BLFWriter(can.BLFWriter):
    """python-can's BLF writer for any channel name. BLF numbers channels in 16 bits; a name whose
    trailing digits do not fit (``vcan70000``, a generated test channel) is written as the writer's
    default channel instead of failing the recording."""

    def __init__(self, path: Path) -> None:
        super().__init__(path)
        self._fits: dict[Any, bool] = {}
        self.error: OSError | None = None  # the write that failed (a full disk): nothing more is kept

    def on_message_received(self, msg: can.Message) -> None:
        if self.error is not None:
            return
        fits = self._fits.get(msg.channel)
        if fits is None:
            number = channel2int(msg.channel)
            fits = self._fits[msg.channel] = number is None or 0 <= number < 0xFFFF
        if not fits:
            msg = copy.copy(msg)
            msg.channel = None
        try:
            super().on_message_received(msg)
        except OSError as error:  # a container did not fit on the disk
            self.error = error

    def _flush(self) -> None:
        if self.error is None:
            try:
                super()._flush()
            except OSError as error:
                self.error = error

    def stop(self) -> None:
        if self.error is not None:  # the header cannot be finished: keep the containers written
            with contextlib.suppress(OSError):
                self.file.close()
            return
        try:
            super().stop()
        except OSError as error:
            self.error = error


_TEXT_WRITERS: dict[str, Any] = {".log": _CandumpWriter, ".asc": can.ASCWriter}


def copy_config(config: Config, copies: Path) -> None:
    """The config and its DBCs side by side in ``copies`` (a new folder), the copy naming each
    DBC by its name beside it: ``--config SESSION/config/car.toml`` reads the session as it was
    recorded. Two DBCs of one name (from different folders) are both kept, the second as
    ``name-2.dbc``."""
    copies.mkdir()
    names: dict[Path, str] = {}
    for dbc in config.dbcs:
        name, k = dbc.path.name, 2
        while name in names.values():
            name, k = f"{dbc.path.stem}-{k}{dbc.path.suffix}", k + 1
        names[dbc.path] = name
        shutil.copy2(dbc.path, copies / name)
    text = config.path.read_text(encoding="utf-8")
    files = tomllib.loads(text).get("dbc", {}).get("files", [])
    for given in files:
        renamed = names.get((config.path.parent / given).resolve())
        if renamed is not None and renamed != given:  # the copy's config names the copy beside it
            # as the file spells it: a literal string, a basic one (backslashes escaped)
            for spelt in (f"'{given}'", f'"{given}"', json.dumps(given, ensure_ascii=False)):
                text = text.replace(spelt, json.dumps(renamed, ensure_ascii=False))
    (copies / config.path.name).write_text(text, encoding="utf-8")


class SessionRecorder(Sink):
    """The session folder as a sink: every raw frame as it arrives, every event as a row of
    events.csv; ``close`` finishes both (a BLF gets its header), ``write_summary`` adds the
    summary beside them. ``folder`` must be new — or ``claimed``: made empty by the caller for
    this session alone (``app.cli.live.session_folder``). The folder, its files' names and the
    config's copy are on the disk before the first frame; the two growing files every
    ``sync_every_s`` after (``PeriodicSync``). A candump log (``.log``) that reaches the largest
    file its disk holds (FAT32's 4 GiB: a busy bus's seven hours) goes on in a session folder of its
    own beside the first, ``<first>-part2``…: each a session folder as any, the config's copy,
    its frames, the events from then on, at the end the whole run's summary (``folders``)."""

    def __init__(
        self,
        folder: Path,
        config: Config,
        raw_format: str = ".log",
        claimed: bool = False,
        sync_every_s: float = SYNC_S,
    ) -> None:
        if raw_format not in RAW_FORMATS:
            raise C2nError(f"raw format '{raw_format}' — use one of {', '.join(RAW_FORMATS)}")
        self.folder = folder  # the one recording now
        self.folders = [folder]  # the session's, in order: the first, then each part
        self._config = config
        try:
            if not claimed:
                folder.mkdir(parents=True, exist_ok=False)
            copy_config(config, folder / SESSION_CONFIG)
            self.raw_path = folder / f"frames{raw_format}"
            self._spool = (
                _Spool(self.raw_path, parts=raw_format == ".log") if raw_format in _TEXT_WRITERS else None
            )
            self._writer: Any = (
                _TEXT_WRITERS[raw_format](self._spool) if self._spool else _BLFWriter(self.raw_path)
            )
            self._events = EventsTable(folder / "events.csv")
            synced_tree(folder)
            synced(folder.parent)  # the session folder's own name
            self._sync = PeriodicSync([self.raw_path, self._events.path], sync_every_s)
        except OSError as error:
            raise OutputError(
                f"{folder}: cannot record the session ({error.strerror}) — use --record DIR"
            ) from error
        self._closed = False
        self.problem: str | None = None  # why the recording stopped before the session did
        self.on_problem: Callable[[str], None] = lambda text: None
        self.notes: list[str] = []  # where the recording went on (a part folder)
        self.on_note: Callable[[str], None] = lambda text: None
        # each frame as it arrives, straight to the writer: it runs for every frame on the bus
        self.on_frame = self._writer.on_message_received  # type: ignore[method-assign]

    def on_frame(self, msg: can.Message) -> None:
        self._writer.on_message_received(msg)

    def on_events(self, events: Sequence[Event], t0: float) -> None:
        for event in events:
            if isinstance(event, Crossing | CrossingRejected):
                self._events.add(event, t0)

    def flush(self) -> None:
        """Hand everything received so far to the operating system."""
        if self._spool is not None:
            self._spool.drain()
            if self._spool.full is not None:
                self._next_part()
        else:
            # BLF buffers frames into compressed containers of 128 KiB; python-can has no public
            # call that writes a partial one, and its reader needs whole containers.
            self._writer._flush()  # nothing when nothing is new
            if self._writer.error is None:
                try:
                    self._writer.file.flush()
                except OSError as error:
                    self._writer.error = error
        self._check()

    def _check(self) -> None:
        """Say once, when the disk refused a write or a sync, what was kept: the session goes on."""
        if self.problem is not None:
            return
        error = (self._spool or self._writer).error
        if self._deleted():
            self.problem = (
                f"{self.raw_path}: deleted while the session recorded it (its folder removed by a user "
                "or a program) — the frames went with it and are not recorded from here on; the live "
                "numbers go on"
            )
        elif error is not None:
            kept = self.raw_path.stat().st_size if self.raw_path.exists() else 0
            mount = _mount_of(self.folder)
            why = f"{error.strerror or error} on the disk of {mount}"
            fix = "free space and start a new session"
            if error.errno == errno.EFBIG:  # the largest file the disk holds (an .asc or .blf: no parts)
                why = f"the file is as large as the disk of {mount} holds (FAT32: 4 GiB)"
                fix = "record as .log (it goes on in a new folder), or onto an exFAT, NTFS or ext4 disk"
            self.problem = (
                f"{self.raw_path}: the recording stopped — {why}; {kept / 1e6:.1f} MB of frames up to "
                f"then are kept, the live numbers go on — {fix}"
            )
        elif self._sync.error is not None:
            self.problem = (
                f"{self.raw_path}: the disk of {_mount_of(self.folder)} did not confirm the frames "
                f"written ({self._sync.error.strerror or self._sync.error}) — what is recorded may "
                "not survive a power cut; copy the session off and check the disk"
            )
        else:
            return
        self.on_problem(self.problem)

    def _next_part(self) -> None:
        """The raw log is as large as its disk holds: the session goes on in a folder of its own
        beside the first (made new, never entered), with the config's copy, the lines that did
        not fit, and the events from now on. A part that cannot be made stops the recording."""
        assert self._spool is not None
        full, folder, events = self.raw_path, None, None
        try:
            folder = _new_beside(self.folders[0], len(self.folders) + 1)
            _list_parts(self.folders[0], [*self.folders[1:], folder])
            copy_config(self._config, folder / SESSION_CONFIG)
            events = EventsTable(folder / "events.csv")
            raw = folder / full.name
            self._spool.restart(raw)
        except (OSError, C2nError) as error:  # the part is this run's alone: nothing in it to keep
            if events is not None:
                events.close()
            if folder is not None:
                shutil.rmtree(folder, ignore_errors=True)
            self._spool.error = error if isinstance(error, OSError) else OSError(errno.EIO, str(error))
            self._spool.full = None
            return
        with contextlib.suppress(OSError):  # its names on the disk; its frames at the next sync
            synced_tree(folder)
            synced(folder.parent)
        self._events.close()
        self._sync.close()  # the full part's last lines on the disk
        self._events, self.folder, self.raw_path = events, folder, raw
        self._sync = PeriodicSync([raw, events.path], self._sync.every_s)
        self.folders.append(folder)
        size = full.stat().st_size
        held = f"{size / 1e9:.2f} GB" if size >= 1e9 else f"{size / 1e6:.1f} MB"
        note = (
            f"{full}: {held}, the largest file the disk of {_mount_of(folder)} holds — the recording "
            f"goes on in {folder}"
        )
        self.notes.append(note)
        self.on_note(note)

    def _deleted(self) -> bool:
        """Is the raw log gone from its folder while still open here (``rm -rf`` of the sessions)?"""
        file = self._spool._file if self._spool is not None else getattr(self._writer, "file", None)
        try:
            return file is not None and os.fstat(file.fileno()).st_nlink == 0
        except (OSError, ValueError):  # closed
            return False

    def close(self) -> None:
        """Finish the raw log and the events table (once; again is nothing)."""
        if self._closed:
            return
        self._check()  # a deletion is seen while the file is open
        self._closed = True
        try:
            self._writer.stop()  # a candump log's last lines: a part to go on in, where they need one
            if self._spool is not None and self._spool.full is not None:
                self._next_part()
                self._spool.close()
        finally:
            self._events.close()
            self._sync.close()  # the files' last bytes (a BLF's header) on the disk
            with contextlib.suppress(OSError):  # nothing new in it since the start
                synced(self.folder)
        self._check()

    def write_summary(self, summary: Summary) -> None:
        """The whole run's summary in each of the session's folders that is still there (one
        deleted meanwhile is not made again to hold a summary of frames it no longer has)."""
        for folder in self.folders:
            if folder.is_dir():
                write_summary(folder / SESSION_SUMMARY, summary)


_MOST_PARTS = 10_000  # a folder c2n cannot make beside the first this many times: stop trying


def _new_beside(first: Path, number: int) -> Path:
    """A new folder beside ``first`` for its part ``number`` (``<first>-part2``…), claimed by
    making it: a folder or file already there is never entered."""
    folder = new_folder(first.with_name(f"{first.name}-part{n}") for n in range(number, number + _MOST_PARTS))
    if folder is None:
        raise OSError(errno.EEXIST, f"{_MOST_PARTS} folders named {first.name}-part… are taken")
    return folder


def _mount_of(path: Path) -> Path:
    """The mount point of the file system ``path`` is on."""
    path = path.resolve()
    while not os.path.ismount(path) and path != path.parent:
        path = path.parent
    return path


def _list_parts(first: Path, parts: list[Path]) -> None:
    """Name the session's parts in its first folder, as each is made (before its first frame):
    the first folder alone is the whole session (``read_session``), renamed or killed, and a
    user's folder that happens to be named ``<session>-part2`` is never taken for one."""
    text = json.dumps({"parts": [part.name for part in parts]}) + "\n"
    temporary = first / f".{PARTS_FILE}.{os.getpid()}"
    temporary.write_text(text, encoding="utf-8")
    synced(temporary)
    os.replace(temporary, first / PARTS_FILE)
    with contextlib.suppress(OSError):  # its name on the disk
        synced(first)
