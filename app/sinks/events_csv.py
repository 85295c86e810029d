"""The events table (events.csv): one row per sideslip sign change, used or not.

The live recorder appends rows as they happen; ``c2n export`` writes the whole table at the end.
"""

import csv
from collections.abc import Iterable
from pathlib import Path
from typing import IO

from app.errors import OutputError
from app.output.csv_dialects import CSV_DIALECTS
from app.output.files import write_atomically
from app.records import Crossing, CrossingRejected

FIELDS = (
    "t",
    "event",
    "direction",
    "sweep",
    "u0_mps",
    "u0_kmh",
    "ay_mps2",
    "c2n",
    "ci95_low",
    "ci95_high",
    "n_samples",
    "reason",
)
UNITS = ("s", "", "", "", "m/s", "km/h", "m/s²", "1/rad", "1/rad", "1/rad", "", "")
_NUMBERS = (0, 4, 5, 6, 7, 8, 9)  # the columns holding a decimal number


def row(event: Crossing | CrossingRejected, t0: float) -> list[str | int]:
    """A table row; times in seconds since ``t0`` (the session's first frame)."""
    if isinstance(event, Crossing):
        lo, hi = event.ci95
        return [
            f"{event.t - t0:.3f}",
            "crossing",
            event.direction,
            event.sweep,
            f"{event.u0_mps:.4f}",
            f"{event.u0_kmh:.3f}",
            f"{event.ay_mps2:.3f}",
            f"{event.c2n:.4f}",
            f"{lo:.4f}",
            f"{hi:.4f}",
            event.n_samples,
            "",
        ]
    return [
        f"{event.t - t0:.3f}",
        "rejected",
        event.direction or "",
        event.sweep,
        f"{event.u_mps:.4f}",
        f"{event.u_mps * 3.6:.3f}",
        "",
        "",
        "",
        "",
        "",
        event.reason,
    ]


class EventsTable:
    """events.csv, written a row at a time and flushed after each."""

    def __init__(self, path: Path, dialect: str = "excel") -> None:
        self.path = path
        delimiter, self._decimal = CSV_DIALECTS[dialect]
        try:
            self._file: IO[str] = path.open("w", newline="", encoding="utf-8")
        except OSError as error:
            raise OutputError(f"{path}: cannot write the events table ({error.strerror})") from error
        self._csv = csv.writer(self._file, delimiter=delimiter)
        self._csv.writerow(FIELDS)
        self._file.flush()

    def add(self, event: Crossing | CrossingRejected, t0: float) -> None:
        cells = row(event, t0)
        if self._decimal != ".":
            cells = [str(c).replace(".", self._decimal) if i in _NUMBERS else c for i, c in enumerate(cells)]
        self._csv.writerow(cells)
        self._file.flush()

    def close(self) -> None:
        self._file.close()


def write(
    path: Path, events: Iterable[Crossing | CrossingRejected], t0: float, dialect: str = "excel"
) -> None:
    """The whole table at once, atomically (``app.output.files``), in ``dialect`` (``CSV_DIALECTS``)."""

    def rows(tmp: Path) -> None:
        table = EventsTable(tmp, dialect)
        try:
            for event in sorted(events, key=lambda e: e.t):
                table.add(event, t0)
        finally:
            table.close()

    write_atomically(path, rows, "the events table")
