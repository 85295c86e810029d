"""Frames from log files: any format python-can reads, BLF and MF4 also in bulk.

A source is an iterable of ``can.Message``. Library errors become one-line LogFileErrors here,
at the edge; a log that breaks part-way gives every frame before the damage and says where it
stopped.
"""

import errno
import gc
import heapq
import io
import locale
import logging
import math
import os
import re
import stat
import sys
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Any, Literal, cast, overload

import can

from app.errors import LogFileError, need, one_line
from app.sources.blf_bulk import TriagedBLFReader
from app.sources.blocks import FrameBlock
from app.sources.identity import DriveIdentity, identity_of
from app.sources.overlap import SensorPrints
from app.sources.spacing import FrameSpacing
from app.sources.triage import NotInBulk, Triage

log = logging.getLogger(__name__)

READABLE_SUFFIXES = (".asc", ".blf", ".csv", ".db", ".log", ".mf4", ".trc")
# Reader options per format: ASC gives absolute times (like BLF and candump), not file-relative ones.
_READER_OPTIONS: dict[str, dict[str, Any]] = {".asc": {"relative_timestamp": False}}


@dataclass
class LogReport:
    """How reading one file went."""

    path: Path
    frames: int = 0
    stopped: str | None = None  # why reading stopped before the end, if it did
    done: bool = False
    reader: object = None  # the python-can reader while the file is open
    span_s: tuple[float, float] | None = None  # the times of the first frame read and the last
    spacing: FrameSpacing = field(default_factory=FrameSpacing)  # of the frames of the ids it watches
    prints: SensorPrints | None = None  # the runs of those frames' payloads, where asked (``overlap``)

    def bytes_read(self) -> int | None:
        """How far into the file the reader is (None where the reader does not say)."""
        if self.done:
            return _size(self.path)
        file = getattr(self.reader, "file", None)
        try:
            return os.lseek(file.fileno(), 0, os.SEEK_CUR) if file is not None else None
        except (OSError, ValueError, AttributeError):
            return None


def _size(path: Path) -> int:
    try:
        return path.stat().st_size
    except OSError:
        return 0


def status(path: Path) -> os.stat_result:
    """The input's status (through a link, where it points), or the LogFileError that says why
    there is none: a path the system cannot even look up (a name too long for it) is the user's
    to fix, not a traceback."""
    try:
        return path.stat()
    except OSError as error:
        if error.errno in (errno.ENOENT, errno.ENOTDIR):
            raise LogFileError(f"{path}: no such file") from error
        if error.errno == errno.ENAMETOOLONG:
            raise LogFileError(_too_long(path)) from error
        raise LogFileError(
            f"{path}: cannot be read ({error.strerror or error}) — check the path and its permissions"
        ) from error


_SHOWN = 40  # characters of an over-long name shown in its error: the rest would fill the screen


def _too_long(path: Path) -> str:
    """Which part of ``path`` no file system here can hold: a name over its NAME_MAX bytes (255
    on ext4), else the whole path over PATH_MAX — no file can be there, so the name is the
    mistake (a pasted name run on, a name made by a script)."""
    limit = _name_max(path)
    for part in path.parts:
        size = len(os.fsencode(part))
        if size > limit:
            shown = str(path).replace(part, f"{part[:_SHOWN]}…", 1)
            return (
                f"{shown}: the file name is too long ({size} bytes; this file system takes at most "
                f"{limit}) — no file can have it: check the name"
            )
    return (
        f"{str(path)[:_SHOWN]}…: the path is too long ({len(os.fsencode(path))} bytes) — "
        "give it relative to a folder nearer to the file"
    )


def _name_max(path: Path) -> int:
    """The longest file name, in bytes, of the file system of the nearest folder of ``path``
    that can be looked up."""
    for folder in path.absolute().parents:
        try:
            return int(os.pathconf(folder, "PC_NAME_MAX"))
        except (OSError, ValueError):
            continue
    return 255


def _format(path: Path) -> str:
    """The log's suffix (the one before .gz), after the checks every log passes (and the
    library its format needs: asammdf for MF4, an optional extra). A pipe or a device is
    refused before it is opened: reading one would wait for a writer, and its size of 0 is no
    file's."""
    found = status(path)
    if stat.S_ISDIR(found.st_mode):
        raise LogFileError(f"{path}: is a folder, not a log file")
    if not stat.S_ISREG(found.st_mode):
        raise LogFileError(f"{path}: is a pipe or a device, not a log file — give the recorded file")
    suffixes = [s.lower() for s in path.suffixes]
    real = (
        suffixes[-2]
        if suffixes and suffixes[-1] == ".gz" and len(suffixes) > 1
        else (suffixes[-1] if suffixes else "")
    )
    if found.st_size == 0:
        raise LogFileError(f"{path}: the file is empty")
    if real == ".mf4":
        need("asammdf", "reading .mf4 logs", "mf4")
    return real


def open_log(path: Path) -> Iterable[can.Message]:
    """Open a log with python-can's reader for its suffix, translating its errors."""
    real = _format(path)
    if real not in READABLE_SUFFIXES:
        sniffed = _sniff(path)
        if sniffed is None:
            raise LogFileError(
                f"{path}: unknown log format '{real or path.name}' — "
                f"use one of {', '.join(READABLE_SUFFIXES)}"
            )
        try:
            return _TEXT_READERS[sniffed](_bounded(path))  # type: ignore[arg-type]
        except Exception as error:
            raise LogFileError(f"{path}: not a readable {sniffed} log ({one_line(error)})") from error
    try:
        options = _READER_OPTIONS.get(real, {})
        text = _TEXT_CLASSES.get(real) if path.suffix.lower() == real else None  # not .gz
        reader: Iterable[can.Message] = (
            text(_bounded(path), **options) if text is not None else can.LogReader(path, **options)
        )
        return reader
    except ImportError as error:
        raise LogFileError(f"{path}: cannot read {real} files ({error}) — pip install asammdf") from error
    except Exception as error:
        reason = one_line(error)
        _drop_quietly(error)
        raise LogFileError(f"{path}: not a readable {real} log ({reason})") from error


# Text logs are read through a file whose lines are bounded: a "line" of a gigabyte (a sparse or
# binary file given a text suffix) is an error after LINE_LIMIT characters, not a gigabyte in memory.
LINE_LIMIT = 1 << 16
_TEXT_CLASSES: dict[str, Callable[..., Iterable[can.Message]]] = {
    ".log": can.CanutilsLogReader,
    ".asc": can.ASCReader,
    ".csv": can.CSVReader,
    ".trc": can.TRCReader,
}


class _BoundedLines(io.TextIOWrapper):
    """A text file whose lines (iterated or read) are at most LINE_LIMIT characters."""

    def __next__(self) -> str:  # type: ignore[override]  # typeshed: IOBase yields bytes
        line = self.readline()
        if not line:
            raise StopIteration
        return line

    def readline(self, size: int | None = -1, /) -> str:  # type: ignore[override]
        limit = LINE_LIMIT if size is None or size < 0 else min(size, LINE_LIMIT)
        line = super().readline(limit)
        if len(line) >= LINE_LIMIT and not line.endswith("\n"):
            raise ValueError(f"a line longer than {LINE_LIMIT:,} characters: not a text log")
        return line


def _bounded(path: Path) -> _BoundedLines:
    return _BoundedLines(path.open("rb"), encoding=locale.getpreferredencoding(False))


def _drop_quietly(error: BaseException) -> None:
    """Free a failed reader now: asammdf's half-built MDF object raises again from ``__del__``,
    which Python would print as a traceback long after the one-line error."""
    hook = sys.unraisablehook
    sys.unraisablehook = lambda unraisable: log.debug("while closing a failed reader: %s", unraisable)
    try:
        error.__traceback__ = None
        gc.collect()  # the reader may sit in a reference cycle
    finally:
        sys.unraisablehook = hook


_CANDUMP_LINE = re.compile(r"^\(\d+(\.\d+)?\)\s+\S+\s+[0-9A-Fa-f]{1,8}#")
_TEXT_READERS: dict[str, Callable[[Path], Iterable[can.Message]]] = {
    "candump": can.CanutilsLogReader,
    "asc": lambda path: can.ASCReader(path, relative_timestamp=False),
}


def _sniff(path: Path) -> str | None:
    """Recognise a text log with a suffix python-can does not know (e.g. candump saved as .can)."""
    try:
        with path.open("r", encoding="ascii", errors="replace") as file:
            head = [line.strip() for _, line in zip(range(20), file, strict=False)]
    except OSError:
        return None
    lines = [line for line in head if line]
    if lines and _CANDUMP_LINE.match(lines[0]):
        return "candump"
    if (
        lines
        and lines[0].lower().startswith("date ")
        and any(line.lower().startswith("base ") for line in lines[:3])
    ):
        return "asc"
    return None


@overload
def read_log(
    path: Path, report: LogReport, triage: Triage | None = None, blocks: Literal[False] = False
) -> Iterator[can.Message]: ...
@overload
def read_log(
    path: Path, report: LogReport, triage: Triage | None, blocks: bool
) -> Iterator[can.Message | FrameBlock]: ...
def read_log(
    path: Path, report: LogReport, triage: Triage | None = None, blocks: bool = False
) -> Iterator[can.Message | FrameBlock]:
    """Frames of one log file, in file order; damage ends the file, noted in ``report`` (the
    caller says so: the summary's warnings, or a line of its own).

    With ``triage`` (the decoder), BLF and MF4 files are read in bulk: only the frames the
    pipeline decodes are yielded, the rest are counted by the decoder directly. With ``blocks``
    too, a BLF or an MF4 yields them as FrameBlocks (``Pipeline.process_block``), and the frames
    a block does not hold (a BLF's remote and error frames, CAN FD …) as Messages among them.
    The times of the frames of the ids ``report.spacing`` watches are noted there."""
    reader = _bulk_reader(path, report, triage, blocks) if triage is not None else None
    if reader is None:
        reader = open_log(path)
    report.reader = reader
    iterator = iter(reader)
    spaced = report.spacing.ids  # the sensor's: its spacing and its pauses
    first: can.Message | FrameBlock | None = None
    last: can.Message | FrameBlock | None = None
    try:
        while True:
            try:
                message = next(iterator)
            except StopIteration:
                ended = _ENDS_EARLY.get(path.suffix.lower())
                why = ended(path, reader) if ended is not None else None
                if why is not None:
                    report.stopped = f"stopped after frame {report.frames}: {why}"
                return
            except Exception as error:
                report.stopped = f"stopped after frame {report.frames}: {one_line(error)}"
                return
            if first is None:
                first = message
            last = message
            if isinstance(message, FrameBlock):
                report.frames += len(message)
                if spaced:
                    report.spacing.add(message)
                    if report.prints is not None:
                        report.prints.add(message)
            else:
                report.frames += 1
                if spaced and message.arbitration_id in spaced:
                    report.spacing.add(message)
                    if report.prints is not None:
                        report.prints.add(message)
            yield message
    finally:
        report.done, report.reader = True, None
        if first is not None and last is not None:
            report.span_s = (_time(first, 0), _time(last, -1))
        stop = getattr(reader, "stop", None)
        if callable(stop):
            stop()


def _time(item: "can.Message | FrameBlock", index: int) -> float:
    return float(item.t[index]) if isinstance(item, FrameBlock) else float(item.timestamp)


_BulkReader = Callable[[Path, Triage, Callable[[int], None]], Iterable[can.Message | FrameBlock]]


def _triaged_mf4(
    path: Path, triage: Triage, skipped: Callable[[int], None], blocks: bool = False
) -> Iterable[can.Message | FrameBlock]:
    _format(path)  # asammdf, or the line that says how to install it
    from app.sources.mf4_bulk import TriagedMF4Reader

    return TriagedMF4Reader(path, triage, skipped, blocks=blocks)


_BULK_READERS: dict[str, _BulkReader] = {".blf": TriagedBLFReader, ".mf4": _triaged_mf4}
_BLOCK_READERS: dict[str, _BulkReader] = {
    ".blf": partial(TriagedBLFReader, blocks=True),
    ".mf4": partial(_triaged_mf4, blocks=True),
}


def _bulk_reader(
    path: Path, report: LogReport, triage: Triage, blocks: bool
) -> Iterable[can.Message | FrameBlock] | None:
    """A bulk reader for the file, or None where none applies (another format, a file the bulk
    reader leaves to python-can's, or one that does not open: python-can's reader says why)."""
    suffix = path.suffix.lower()
    reader = _BLOCK_READERS.get(suffix) if blocks else None
    if reader is None:
        reader = _BULK_READERS.get(suffix)
    if reader is None:
        return None

    def skipped(frames: int) -> None:
        report.frames += frames

    try:
        return reader(path, triage, skipped)
    except NotInBulk as reason:
        log.debug("%s: read frame by frame: %s", path, reason)
    except Exception as error:
        _drop_quietly(error)
    return None


def _blf_ends_early(path: Path, reader: object) -> str | None:
    """A BLF whose writer finished says its size in the header; a copy cut short is smaller. (A
    recording killed mid-run never got its header finished and reads up to its last container.)"""
    declared = int(getattr(reader, "file_size", 0) or 0)
    size = _size(path)
    if size < declared:
        return f"the file ends at byte {size} of the {declared} its header declares (truncated)"
    return None


def _asc_ends_early(path: Path, reader: object) -> str | None:
    """An ASC file ends with 'End TriggerBlock'; python-can's reader skips a last line cut in half."""
    try:
        with path.open("rb") as file:
            file.seek(max(_size(path) - 512, 0))
            tail = file.read()
    except OSError:
        return None
    if b"end triggerblock" in tail.lower():
        return None
    return "the file ends without 'End TriggerBlock' (truncated?)"


# Readers that end quietly on a cut-off file: how to tell that the file stopped early.
_ENDS_EARLY: dict[str, Callable[[Path, object], str | None]] = {
    ".blf": _blf_ends_early,
    ".asc": _asc_ends_early,
}


def check_readable(path: Path) -> None:
    """Open a log and read its first frame: a file that is damaged from the start, or holds no
    frame at all, is an error, not an empty drive."""
    if _format(path) == ".mf4":
        _check_mf4(path)
        return
    reader = open_log(path)
    try:
        if next(iter(reader), None) is None:
            raise LogFileError(f"{path}: no CAN frames in the file")
    except LogFileError:
        raise
    except Exception as error:
        reason = one_line(error)
        _drop_quietly(error)
        if _format(path) == ".db" and "no such table" in reason:  # another program's database
            raise LogFileError(
                f"{path}: not a python-can SQLite log ({reason}: python-can keeps its frames in the table "
                "messages) — rename its table to messages, or export the frames as BLF, ASC or candump"
            ) from error
        raise LogFileError(f"{path}: not a readable log, damaged from the start ({reason})") from error
    finally:
        stop = getattr(reader, "stop", None)
        if callable(stop):
            stop()


def _check_mf4(path: Path) -> None:
    """check_readable for MF4, without python-can's reader (``holds_frames`` says why)."""
    from app.sources.mf4_bulk import holds_frames

    try:
        found = holds_frames(path)
    except Exception as error:
        reason = one_line(error)
        _drop_quietly(error)
        raise LogFileError(f"{path}: not a readable .mf4 log ({reason})") from error
    if not found:
        raise LogFileError(f"{path}: no CAN frames in the file")


def drive_identity(path: Path) -> DriveIdentity:
    """The identity of the drive ``path`` holds (the frames read up to any damage)."""
    return identity_of(read_log(path, LogReport(path)))


def first_of_each(paths: list[Path]) -> tuple[list[Path], list[tuple[Path, Path]]]:
    """The paths with each drive once, in order, and (repeat, first) for every other copy."""
    kept: list[tuple[Path, DriveIdentity]] = []
    repeats: list[tuple[Path, Path]] = []
    for path in paths:
        identity = drive_identity(path)
        first = next((p for p, known in kept if known.same_drive(identity)), None)
        if first is None:
            kept.append((path, identity))
        else:
            repeats.append((path, first))
    return [p for p, _ in kept], repeats


def distinct(paths: Sequence[Path]) -> tuple[list[Path], list[LogReport]]:
    """The logs with each drive once (the same path, a link, a copy, or the same frames in
    another format: ``app.sources.identity``), and a report for each one given again."""
    if len(paths) < 2:
        return list(paths), []
    kept, repeats = first_of_each(list(paths))
    repeated = [
        LogReport(path, stopped=f"the same recording as {first}: read once", done=True)
        for path, first in repeats
    ]
    return kept, repeated


def starting_at(
    items: Iterator[can.Message | FrameBlock | None], start: float
) -> Iterator[can.Message | FrameBlock | None]:
    """The frames moved in time so that the first is at ``start``: drives pooled one after
    another (``c2n analyze --pool``) laid end to end, each recorded on its own clock."""
    offset: float | None = None
    for item in items:
        if isinstance(item, FrameBlock):
            if offset is None and len(item.t):
                offset = start - float(item.t[0])
            yield replace(item, t=item.t + (offset or 0.0))
            continue
        if item is not None:
            if offset is None:
                offset = start - item.timestamp
            item.timestamp += offset
        yield item


class LogSource:
    """Frames of several log files: one after another, or merged by timestamp (``merge``), for
    per-channel recordings of one drive (e.g. two candump files). Given the decoder as
    ``triage``, BLF and MF4 files are read in bulk (``read_log``). Each file's report keeps the
    spacing of the frames of the ids in ``spaced`` (the optical sensor's: the log's clock shows
    in it, ``results/log_clock.py``) and where they paused beyond ``pause_s``; with ``prints``,
    the runs of their payloads too (``overlap.py``: two recordings of one stretch of driving)."""

    def __init__(
        self,
        paths: Sequence[Path],
        merge: bool = False,
        triage: Triage | None = None,
        spaced: frozenset[int] = frozenset(),
        pause_s: float = math.inf,
        prints: bool = False,
    ) -> None:
        for path in paths:  # fail before any work on a missing, unknown or unreadable file
            check_readable(path)
        self.paths, self.repeated = distinct(paths)
        self.merge = merge
        self.triage = triage
        self.reports = [
            LogReport(
                p, spacing=FrameSpacing(spaced, pause_s), prints=SensorPrints(spaced) if prints else None
            )
            for p in self.paths
        ]

    @property
    def notes(self) -> list[LogReport]:
        """Every file's report, the ones given twice (and read once) among them."""
        return [*self.reports, *self.repeated]

    @property
    def total_bytes(self) -> int:
        return sum(_size(p) for p in self.paths)

    def bytes_read(self) -> int | None:
        """Bytes read so far over all files; None while a file is open whose reader does not say
        (MF4 is read by asammdf as a whole)."""
        done = 0
        for report in self.reports:
            if report.reader is None and not report.done:
                continue  # not opened yet
            position = report.bytes_read()
            if position is None:
                return None
            done += position
        return done

    def __iter__(self) -> Iterator[can.Message]:
        return cast(Iterator[can.Message], self.items(blocks=False))  # no blocks: Messages only

    def items(self, blocks: bool) -> Iterator[can.Message | FrameBlock]:
        """The frames; with ``blocks``, those of a BLF or an MF4 read in bulk as FrameBlocks
        (``c2n analyze``, ``c2n gap``: ``Pipeline.process_block``), unless the logs are merged."""
        blocks = blocks and not self.merge
        streams = [read_log(p, r, self.triage, blocks) for p, r in zip(self.paths, self.reports, strict=True)]
        if self.merge:
            yield from heapq.merge(*streams, key=lambda m: m.timestamp)  # type: ignore[union-attr]
        else:
            for stream in streams:
                yield from stream
