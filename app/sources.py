"""Where frames come from: log files (any format python-can reads) and live buses.

A source is an iterable of ``can.Message``. Library errors become one-line LogFileError /
BusError here, at the edge; a log that breaks part-way gives every frame before the damage and
says where it stopped.
"""

import heapq
import logging
import os
import queue
import re
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can

from app.errors import BusError, LogFileError

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


def open_log(path: Path) -> Iterable[can.Message]:
    """Open a log with python-can's reader for its suffix, translating its errors."""
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
        raise LogFileError(f"{path}: not a readable {real} log ({_one_line(error)})") from None


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


def read_log(path: Path, report: LogReport) -> Iterator[can.Message]:
    """Frames of one log file, in file order; damage ends the file, noted in ``report``."""
    reader = open_log(path)
    report.reader = reader
    iterator = iter(reader)
    try:
        while True:
            try:
                message = next(iterator)
            except StopIteration:
                return
            except Exception as error:
                report.stopped = f"stopped after frame {report.frames}: {_one_line(error)}"
                log.warning("%s: %s", path, report.stopped)
                return
            report.frames += 1
            yield message
    finally:
        report.done, report.reader = True, None
        stop = getattr(reader, "stop", None)
        if callable(stop):
            stop()


class LogSource:
    """Frames of several log files: one after another, or merged by timestamp (``merge``), for
    per-channel recordings of one drive (e.g. two candump files)."""

    def __init__(self, paths: Sequence[Path], merge: bool = False) -> None:
        self.paths = list(paths)
        self.merge = merge
        self.reports = [LogReport(p) for p in self.paths]
        for path in self.paths:  # fail before any work on a missing or unknown file
            reader = open_log(path)
            stop = getattr(reader, "stop", None)
            if callable(stop):
                stop()

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
        streams = [read_log(p, r) for p, r in zip(self.paths, self.reports, strict=True)]
        if self.merge:
            yield from heapq.merge(*streams, key=lambda m: m.timestamp)
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


class _Forward(can.Listener):
    """Puts a bus's frames on the shared queue, naming the channel if the interface did not."""

    def __init__(self, out: "queue.SimpleQueue[can.Message | BaseException]", channel: str) -> None:
        self.out = out
        self.channel = channel

    def on_message_received(self, msg: can.Message) -> None:
        if msg.channel is None:
            msg.channel = self.channel
        self.out.put(msg)

    def on_error(self, exc: Exception) -> None:
        self.out.put(exc)


class BusSource:
    """Frames from one or more live buses in arrival order.

    Iterating yields a message, or None after ``idle_s`` without one (so the caller can redraw).
    It ends at once when ``stop`` is set, or once the buses fall quiet after ``finished`` is set
    (a player that has sent everything). A bus that fails ends it with BusError.
    """

    def __init__(
        self,
        buses: Sequence[can.BusABC],
        stop: threading.Event,
        finished: threading.Event | None = None,
        idle_s: float = 0.05,
    ) -> None:
        self.buses = list(buses)
        self.stop = stop
        self.finished = finished
        self.idle_s = idle_s
        self._queue: queue.SimpleQueue[can.Message | BaseException] = queue.SimpleQueue()
        self._notifiers: list[can.Notifier] = []

    def __iter__(self) -> Iterator[can.Message | None]:
        if len(self.buses) == 1:
            yield from self._one(self.buses[0])
            return
        for bus in self.buses:
            self._notifiers.append(
                can.Notifier(bus, [_Forward(self._queue, bus.channel_info)], timeout=self.idle_s)
            )
        stop = self.stop
        try:
            while not stop.is_set():
                try:
                    item = self._queue.get(timeout=self.idle_s)
                except queue.Empty:
                    if self.finished is not None and self.finished.is_set():
                        return
                    yield None
                    continue
                if isinstance(item, BaseException):
                    raise BusError(f"the bus failed: {_one_line(item)}")
                yield item
        finally:
            self.close()

    def _one(self, bus: can.BusABC) -> Iterator[can.Message | None]:
        """One bus is read in this thread: no notifier thread, no queue, no GIL hand-over per
        frame (three times the frame rate of the threaded path, tools/bench.py)."""
        stop, finished, idle_s, name = self.stop, self.finished, self.idle_s, bus.channel_info
        while not stop.is_set():
            try:
                msg = bus.recv(idle_s)
            except Exception as error:
                raise BusError(f"the bus failed: {_one_line(error)}") from None
            if msg is None:
                if finished is not None and finished.is_set():
                    return
                yield None
                continue
            if msg.channel is None:
                msg.channel = name
            yield msg

    def close(self) -> None:
        for notifier in self._notifiers:
            notifier.stop(timeout=1.0)
        self._notifiers.clear()
