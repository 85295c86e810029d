"""Where frames come from: log files (any format python-can reads) and live buses.

A source is an iterable of ``can.Message``. Library errors become one-line LogFileError /
BusError here, at the edge; a log that breaks part-way gives every frame before the damage and
says where it stopped.
"""

import gc
import heapq
import logging
import os
import queue
import re
import sys
import threading
import time
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any, Literal, cast, overload

import can

from app.errors import BusError, C2nError, LogFileError
from app.sources.blf_bulk import TriagedBLFReader
from app.sources.blocks import FrameBlock
from app.sources.bus_health import BusHealth
from app.sources.mf4_bulk import TriagedMF4Reader, holds_frames
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


def _format(path: Path) -> str:
    """The log's suffix (the one before .gz), after the checks every log passes."""
    if not path.exists():
        raise LogFileError(f"{path}: no such file")
    if path.is_dir():
        raise LogFileError(f"{path}: is a folder, not a log file")
    suffixes = [s.lower() for s in path.suffixes]
    real = (
        suffixes[-2]
        if suffixes and suffixes[-1] == ".gz" and len(suffixes) > 1
        else (suffixes[-1] if suffixes else "")
    )
    if path.stat().st_size == 0:
        raise LogFileError(f"{path}: the file is empty")
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
            return _TEXT_READERS[sniffed](path)
        except Exception as error:
            raise LogFileError(f"{path}: not a readable {sniffed} log ({_one_line(error)})") from None
    try:
        reader: Iterable[can.Message] = can.LogReader(path, **_READER_OPTIONS.get(real, {}))
        return reader
    except ImportError as error:
        raise LogFileError(f"{path}: cannot read {real} files ({error}) — pip install asammdf") from None
    except Exception as error:
        reason = _one_line(error)
        _drop_quietly(error)
        raise LogFileError(f"{path}: not a readable {real} log ({reason})") from None


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
    too, an MF4 yields them as FrameBlocks (``Pipeline.process_block``)."""
    reader = _bulk_reader(path, report, triage, blocks) if triage is not None else None
    if reader is None:
        reader = open_log(path)
    report.reader = reader
    iterator = iter(reader)
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
                report.stopped = f"stopped after frame {report.frames}: {_one_line(error)}"
                return
            report.frames += len(message) if type(message) is FrameBlock else 1
            yield message
    finally:
        report.done, report.reader = True, None
        stop = getattr(reader, "stop", None)
        if callable(stop):
            stop()


_BulkReader = Callable[[Path, Triage, Callable[[int], None]], Iterable[can.Message | FrameBlock]]
_BULK_READERS: dict[str, _BulkReader] = {".blf": TriagedBLFReader, ".mf4": TriagedMF4Reader}
_BLOCK_READERS: dict[str, _BulkReader] = {".mf4": partial(TriagedMF4Reader, blocks=True)}


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
        reason = _one_line(error)
        _drop_quietly(error)
        raise LogFileError(f"{path}: not a readable log, damaged from the start ({reason})") from None
    finally:
        stop = getattr(reader, "stop", None)
        if callable(stop):
            stop()


def _check_mf4(path: Path) -> None:
    """check_readable for MF4, without python-can's reader (``holds_frames`` says why)."""
    try:
        found = holds_frames(path)
    except Exception as error:
        reason = _one_line(error)
        _drop_quietly(error)
        raise LogFileError(f"{path}: not a readable .mf4 log ({reason})") from None
    if not found:
        raise LogFileError(f"{path}: no CAN frames in the file")


class LogSource:
    """Frames of several log files: one after another, or merged by timestamp (``merge``), for
    per-channel recordings of one drive (e.g. two candump files). Given the decoder as
    ``triage``, BLF and MF4 files are read in bulk (``read_log``)."""

    def __init__(self, paths: Sequence[Path], merge: bool = False, triage: Triage | None = None) -> None:
        self.paths = list(paths)
        self.merge = merge
        self.triage = triage
        self.reports = [LogReport(p) for p in self.paths]
        for path in self.paths:  # fail before any work on a missing, unknown or unreadable file
            check_readable(path)

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
        """The frames; with ``blocks``, those of an MF4 read in bulk as FrameBlocks (``c2n
        analyze``: ``Pipeline.process_block``), unless the logs are merged."""
        blocks = blocks and not self.merge
        streams = [read_log(p, r, self.triage, blocks) for p, r in zip(self.paths, self.reports, strict=True)]
        if self.merge:
            yield from heapq.merge(*streams, key=lambda m: m.timestamp)  # type: ignore[union-attr]
        else:
            for stream in streams:
                yield from stream


def _one_line(error: BaseException) -> str:
    text = " ".join(str(error).split()) or type(error).__name__
    return text if len(text) <= 160 else text[:157] + "..."


# -- live buses ---------------------------------------------------------------------------------


def open_buses(
    interface: str | None, channels: Sequence[str | int | None], bitrate: int | None, **kwargs: Any
) -> list[can.BusABC]:
    """Open one python-can bus per channel. None values fall back to python-can's config file and
    CAN_INTERFACE / CAN_CHANNEL / CAN_BITRATE."""
    buses: list[can.BusABC] = []
    options = dict(kwargs)
    if bitrate is not None:
        options["bitrate"] = bitrate
    for channel in channels or [None]:
        try:
            buses.append(can.Bus(interface=interface, channel=channel, **options))
        except Exception as error:
            for bus in buses:
                bus.shutdown()
            named = channel if channel is not None else "(default channel)"
            where = f"{interface or 'default interface'} {named}"
            raise BusError(f"{where}: cannot open ({_one_line(error)}) — {_bus_hint(interface)}") from None
    return buses


def _bus_hint(interface: str | None) -> str:
    if interface is None:
        return "give -i/-c, or set CAN_INTERFACE and CAN_CHANNEL, or write ~/can.conf"
    if interface == "socketcan":
        return "is it up? (sudo ip link set can0 up type can bitrate 1000000)"
    return "check the interface name, channel and driver"


@dataclass(frozen=True)
class _Failure:
    """A bus's receive thread failed (cable pulled, interface gone, driver error)."""

    bus: can.BusABC
    error: BaseException


class _Forward(can.Listener):
    """Puts a bus's frames on the shared queue, naming the channel if the interface did not."""

    def __init__(self, out: "queue.SimpleQueue[can.Message | _Failure]", bus: can.BusABC) -> None:
        self.out = out
        self.bus = bus
        self.channel = bus.channel_info

    def on_message_received(self, msg: can.Message) -> None:
        if msg.channel is None:
            msg.channel = self.channel
        self.out.put(msg)

    def on_error(self, exc: Exception) -> None:
        self.out.put(_Failure(self.bus, exc))


@dataclass(frozen=True)
class Backoff:
    """Waits between attempts to reopen a lost bus: ``first_s``, doubling up to ``max_s``."""

    first_s: float = 0.5
    max_s: float = 5.0

    def delay_s(self, failed_attempts: int) -> float:
        return float(min(self.first_s * 2.0**failed_attempts, self.max_s))


@dataclass
class _Lost:
    since: float
    retry_at: float
    failed_attempts: int = 0


class BusSource:
    """Frames from one or more live buses in arrival order.

    Iterating yields a message, or None after ``idle_s`` without one (so the caller can redraw
    and flush the recording). It ends at once when ``stop`` is set, or once the buses fall quiet
    after ``finished`` is set (a player that has sent everything).

    A bus that fails ends it with BusError, unless ``reopen`` is given (index → a new bus for
    that channel): then the lost bus is closed, None is yielded at once, and reopening is tried
    after ``backoff`` delays on ``clock`` until it works; the other buses go on meanwhile.
    ``on_change`` hears each loss, failed attempt and return as one line.
    """

    def __init__(
        self,
        buses: Sequence[can.BusABC],
        stop: threading.Event,
        finished: threading.Event | None = None,
        idle_s: float = 0.05,
        reopen: Callable[[int], can.BusABC] | None = None,
        backoff: Backoff = Backoff(),
        clock: Callable[[], float] = time.monotonic,
        on_change: Callable[[str], None] | None = None,
    ) -> None:
        self.buses = list(buses)
        self.stop = stop
        self.finished = finished
        self.idle_s = idle_s
        self.reopen = reopen
        self.backoff = backoff
        self.clock = clock
        self.on_change = on_change or (lambda text: None)
        self.names = [str(bus.channel_info) for bus in self.buses]
        self.lost: dict[int, _Lost] = {}
        self.losses: list[str] = []  # one line per time a bus went away or bus-off, for the summary
        self.health = BusHealth()
        self._queue: queue.SimpleQueue[can.Message | _Failure] = queue.SimpleQueue()
        self._notifiers: dict[int, can.Notifier] = {}

    @property
    def problem(self) -> str | None:
        """Which buses are lost, bus-off or error-passive, for the dashboard (None while all are well)."""
        if not self.lost and not self.health.troubled:
            return None
        now = self.clock()
        lost = [
            f"{self.names[i]} lost for {now - lost.since:.0f} s, "
            f"next try in {max(lost.retry_at - now, 0.0):.1f} s"
            for i, lost in sorted(self.lost.items())
        ]
        return "; ".join(lost + self.health.problems(now))

    def _check_health(self, msg: can.Message) -> None:
        line = self.health.see(msg, self.clock())
        if line is not None:
            if str(msg.channel) in self.health.troubled:  # a new trouble, not a return
                self.losses.append(line.partition(" — ")[0])
            self.on_change(line)

    def __iter__(self) -> Iterator[can.Message | None]:
        """One bus is read in the caller's thread: no hand-off between threads per frame, which
        would cost more than decoding it (tools/bench.py). Several buses get a receive thread
        each, feeding one queue."""
        return self._read_one() if len(self.buses) == 1 else self._read_queued()

    def _read_queued(self) -> Iterator[can.Message | None]:
        try:
            for index in range(len(self.buses)):
                self._listen(index)
            stop, health = self.stop, self.health
            while not stop.is_set():
                if self.lost:
                    self._retry(self.clock())
                item = self._receive_queued()
                if item is None:
                    if self.finished is not None and self.finished.is_set():
                        return
                    yield None
                    continue
                if isinstance(item, _Failure):
                    if self._lose(item):
                        yield None  # the caller flushes the recording now
                    continue
                if item.is_error_frame or health.troubled:
                    self._check_health(item)
                yield item
        finally:
            self.close()

    def _receive_queued(self) -> "can.Message | _Failure | None":
        try:
            return self._queue.get(timeout=self.idle_s)
        except queue.Empty:
            return None

    def _read_one(self) -> Iterator[can.Message | None]:
        """``__iter__`` for one bus, read in this thread. While frames keep coming, each costs
        its ``recv`` and a few checks (tools/bench.py, live throughput)."""
        stop, health, idle_s = self.stop, self.health, self.idle_s
        try:
            while not stop.is_set():
                if self.lost:
                    self._retry(self.clock(), listen=False)
                if self.lost:  # the only bus is away: wait for the next attempt
                    time.sleep(max(0.0, min(idle_s, self.lost[0].retry_at - self.clock())))
                    if self.finished is not None and self.finished.is_set():
                        return
                    yield None
                    continue
                bus = self.buses[0]
                recv, channel = bus.recv, bus.channel_info
                while True:
                    try:
                        msg = recv(idle_s)
                    except Exception as error:  # what a receive thread would report to its listener
                        if self._lose(_Failure(bus, error)):
                            yield None  # the caller flushes the recording now
                        break
                    if msg is None:
                        if self.finished is not None and self.finished.is_set():
                            return
                        yield None
                        break
                    if msg.channel is None:
                        msg.channel = channel
                    if msg.is_error_frame or health.troubled:
                        self._check_health(msg)
                    yield msg
                    if stop.is_set():
                        return
        finally:
            self.close()

    def _listen(self, index: int) -> None:
        bus = self.buses[index]
        self._notifiers[index] = can.Notifier(bus, [_Forward(self._queue, bus)], timeout=self.idle_s)

    def _lose(self, failure: _Failure) -> bool:
        """Close a failed bus and schedule its reopening; False for a stale report."""
        index = next((i for i, bus in enumerate(self.buses) if bus is failure.bus), None)
        if index is None or index in self.lost:
            return False  # the receive thread reported again before it was stopped
        name, reason = self.names[index], _one_line(failure.error)
        if self.reopen is None:
            raise BusError(f"{name}: the bus failed ({reason})")
        notifier = self._notifiers.pop(index, None)
        if notifier is not None:
            notifier.stop(timeout=1.0)
        _shutdown(failure.bus)
        now = self.clock()
        delay = self.backoff.delay_s(0)
        self.lost[index] = _Lost(since=now, retry_at=now + delay)
        self.losses.append(f"{name}: the bus went away ({reason})")
        self.on_change(f"{self.losses[-1]} — recording kept, retrying in {delay:g} s")
        return True

    def _retry(self, now: float, listen: bool = True) -> None:
        if self.reopen is None:
            return
        for index, lost in list(self.lost.items()):
            if now < lost.retry_at:
                continue
            name = self.names[index]
            try:
                bus = self.reopen(index)
            except (C2nError, can.CanError, OSError) as error:
                lost.failed_attempts += 1
                delay = self.backoff.delay_s(lost.failed_attempts)
                lost.retry_at = now + delay
                self.on_change(f"{name}: still gone ({_one_line(error)}) — retrying in {delay:g} s")
                continue
            self.buses[index] = bus
            del self.lost[index]
            if listen:
                self._listen(index)
            self.on_change(f"{name}: the bus is back after {now - lost.since:.1f} s — measuring again")

    def close(self) -> None:
        for notifier in self._notifiers.values():
            notifier.stop(timeout=1.0)
        self._notifiers.clear()


def _shutdown(bus: can.BusABC) -> None:
    try:
        bus.shutdown()
    except (can.CanError, OSError) as error:  # it is already gone
        log.debug("closing a failed bus: %s", error)
