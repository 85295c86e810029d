"""The session folder: raw frames as they arrive, the config and DBCs used, events and summary.

The raw log is written with python-can's writer for its suffix (a writer is a Listener, so
recording is one more sink) and flushed by the live loop at least every 100 ms.
"""

import csv
import shutil
from pathlib import Path
from typing import IO, Any

import can

from app.config import Config
from app.errors import C2nError
from app.records import Crossing
from app.summary import write as write_summary

RAW_FORMATS = (".log", ".asc", ".blf")
EVENT_FIELDS = (
    "t",
    "direction",
    "sweep",
    "u0_mps",
    "u0_kmh",
    "ay_mps2",
    "c2n",
    "ci95_low",
    "ci95_high",
    "n_samples",
)


class SessionRecorder:
    def __init__(self, folder: Path, config: Config, raw_format: str = ".log") -> None:
        if raw_format not in RAW_FORMATS:
            raise C2nError(f"raw format '{raw_format}' — use one of {', '.join(RAW_FORMATS)}")
        self.folder = folder
        try:
            folder.mkdir(parents=True, exist_ok=False)
            copies = folder / "config"
            copies.mkdir()
            shutil.copy2(config.path, copies / config.path.name)
            for dbc in config.dbcs:
                shutil.copy2(dbc.path, copies / dbc.path.name)
            self.raw_path = folder / f"frames{raw_format}"
            self._writer: Any = can.Logger(self.raw_path)
            self._events: IO[str] = (folder / "events.csv").open("w", newline="")
        except OSError as error:
            raise C2nError(
                f"{folder}: cannot record the session ({error.strerror}) — use --record DIR"
            ) from None
        self._csv = csv.writer(self._events)
        self._csv.writerow(EVENT_FIELDS)
        self.frames = 0

    def on_message(self, msg: can.Message) -> None:
        self._writer.on_message_received(msg)
        self.frames += 1

    def on_crossing(self, c: Crossing, t0: float) -> None:
        lo, hi = c.ci95
        self._csv.writerow(
            [
                f"{c.t - t0:.3f}",
                c.direction,
                c.sweep,
                f"{c.u0_mps:.4f}",
                f"{c.u0_kmh:.3f}",
                f"{c.ay_mps2:.3f}",
                f"{c.c2n:.4f}",
                f"{lo:.4f}",
                f"{hi:.4f}",
                c.n_samples,
            ]
        )
        self._events.flush()

    def flush(self) -> None:
        file = getattr(self._writer, "file", None)
        if file is not None and not file.closed:
            file.flush()

    def close(self, summary: dict[str, Any]) -> None:
        self._writer.stop()
        self._events.close()
        write_summary(self.folder / "summary.json", summary)
