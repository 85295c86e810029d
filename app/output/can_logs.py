"""Log files of CAN frames written as python-can writes them, in the format of the log they came
from where python-can gives back, read, what it was given (``c2n split``: a log cut into parts).
Each file is written under a temporary name (``files.partial_path``) and renamed into place once
whole and synced, so a kill or a full disk leaves no file that looks complete."""

import contextlib
import gzip
import math
import os
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Any

import can
from can.io.generic import MessageWriter

from app.output.durable import synced
from app.output.files import partial_path


class _ASCPartWriter(can.ASCWriter):
    """python-can's ASC writer whose times count from the input's own start: its header's date
    keeps milliseconds only, so a part counted from its first frame would read up to 1 ms
    early. Counted from the millisecond the input's reader parsed (``start``), each frame reads
    back at the time it had in the input."""

    def __init__(self, file: Any, start: float | None) -> None:
        super().__init__(file)
        self._start = start

    def log_event(self, message: str, timestamp: float | None = None) -> None:
        if not self.header_written and self._start is not None:
            self.header_written = True
            self.started = self.last_timestamp = self._start
            began = self._format_header_datetime(datetime.fromtimestamp(self._start))
            self.file.write(f"Begin Triggerblock {began}\n")
            super().log_event("Start of measurement")
        super().log_event(message, timestamp)


# python-can's writers that give back, read, the frames they were given: (file, the input's
# reader's start) -> writer; a text format's file may be a gzip stream
_Writer = Callable[[Any, float | None], MessageWriter]
_WRITERS: dict[str, _Writer] = {
    ".log": lambda file, start: can.CanutilsLogWriter(file),
    ".asc": _ASCPartWriter,
    ".blf": lambda file, start: can.BLFWriter(file),
    ".csv": lambda file, start: can.CSVWriter(file),
    ".mf4": lambda file, start: can.MF4Writer(file),
}
_TEXT = frozenset({".log", ".asc", ".csv"})  # what a .gz input is written as, gzipped
# Formats read but not written as read: why (the parts are written as BLF)
_NOT_AS_READ = {
    ".trc": "python-can's TRC writer leaves out remote, error and CAN FD frames and numbers the "
    "channels one higher",
    ".db": "python-can's SQLite writer loses the frames it has not stored when it stops",
}
_FALLBACK = ".blf"


@dataclass(frozen=True)
class Format:
    """How the parts of a log are written: ``kind`` the writer's suffix, ``suffix`` the files'
    (``.log.gz``), ``note`` why it is not the input's format (None: it is)."""

    kind: str
    suffix: str
    gz: bool = False
    note: str | None = None


def format_of(log: Path) -> tuple[str, Format]:
    """The log's name without its format's suffix, and how its parts are written."""
    suffixes = [s.lower() for s in log.suffixes]
    gz = len(suffixes) > 1 and suffixes[-1] == ".gz"
    real = suffixes[-2] if gz else (suffixes[-1] if suffixes else "")
    spelt = "".join(log.suffixes[-2:] if gz else log.suffixes[-1:])
    stem = log.name[: len(log.name) - len(spelt)] if spelt else log.name
    if real in _WRITERS and (not gz or real in _TEXT):
        return stem, Format(real, spelt, gz)
    if real in _WRITERS:  # a gzip of a binary format
        kind = real[1:].upper()
        why = f"python-can's {kind} writer goes back to its start at the end, which a gzip stream cannot"
        return stem, Format(real, real, note=f"{why}: the parts are written as plain {kind}")
    why = _NOT_AS_READ.get(real, f"python-can cannot write {real or 'its'} files")
    return stem, Format(_FALLBACK, _FALLBACK, note=f"{why}: the parts are written as BLF")


@dataclass
class PartFile:
    """One log file (a part of a log) being written: under a temporary name until ``finish``
    renames it into place, so a kill or a full disk leaves no file that looks whole."""

    path: Path
    writer: MessageWriter
    tmp: Path
    frames: int = 0
    first_s: float = math.inf  # the earliest frame's time
    last_s: float = -math.inf
    _closed: bool = field(default=False, repr=False)

    def add(self, msg: can.Message) -> None:
        self.writer.on_message_received(msg)
        self.frames += 1
        self.first_s = min(self.first_s, msg.timestamp)
        self.last_s = max(self.last_s, msg.timestamp)

    def finish(self) -> None:
        """Every frame on the disk, then the file under its name."""
        self._closed = True
        self.writer.stop()
        synced(self.tmp)
        os.replace(self.tmp, self.path)

    def abandon(self) -> None:
        """Stop and remove the temporary (a write that failed or was interrupted)."""
        if not self._closed:
            self._closed = True
            with contextlib.suppress(Exception):
                self.writer.stop()
        with contextlib.suppress(OSError):
            self.tmp.unlink(missing_ok=True)


def open_part(path: Path, fmt: Format, start: float | None) -> PartFile:
    """A part's writer, on its temporary (``partial_path``)."""
    tmp = partial_path(path)
    # the writer closes it when it stops
    file: Any = gzip.open(tmp, "wt", encoding="utf-8", newline="") if fmt.gz else tmp  # noqa: SIM115
    try:
        return PartFile(path, _WRITERS[fmt.kind](file, start), tmp)
    except BaseException:
        if fmt.gz:
            file.close()
        tmp.unlink(missing_ok=True)
        raise
