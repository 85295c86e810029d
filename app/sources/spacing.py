"""How far apart the frames of a periodic message lie in a log's own time.

The log's clock unit shows in it: a sensor sending every 10 ms whose log keeps its times in
milliseconds (a CSV or candump file written by another tool) reads as frames 10 "s" apart. The
reader keeps each watched id's spacings (``LogReport.spacing``); ``results/log_clock.py`` says
what they mean.
"""

import math
import statistics
from dataclasses import dataclass, field

import can
import numpy as np

from app.sources.blocks import FrameBlock

# Spacings kept of each id (80 kB): a clock's unit shows in any stretch of a periodic message's
# frames, so the first ten thousand (100 s of a sensor at 100 Hz) say what the whole log would.
SPACINGS_KEPT = 10_000


@dataclass(frozen=True)
class Spacing:
    """The median time between consecutive frames of one id, in the log's own unit."""

    frame_id: int
    median: float
    spacings: int  # how many it is the median of


@dataclass
class FrameSpacing:
    """The spacings of consecutive frames of each id in ``ids`` (none: nothing is kept)."""

    ids: frozenset[int] = frozenset()
    watching: set[int] = field(init=False)  # the ids still short of SPACINGS_KEPT
    _last: dict[int, float] = field(default_factory=dict, init=False)
    _gaps: dict[int, list[float]] = field(default_factory=dict, init=False)

    def __post_init__(self) -> None:
        self.watching = set(self.ids)

    def add(self, item: can.Message | FrameBlock) -> None:
        """Note a frame's time, or a block's frames' (the caller may skip frames of other ids)."""
        if isinstance(item, FrameBlock):
            for frame_id in list(self.watching):
                times = item.t[item.frame_id == frame_id]
                times = times[np.isfinite(times)]
                if len(times):
                    self._note(frame_id, times.tolist())
        elif item.arbitration_id in self.watching and math.isfinite(item.timestamp):
            self._note(item.arbitration_id, [item.timestamp])

    def _note(self, frame_id: int, times: list[float]) -> None:
        last = self._last.get(frame_id)
        gaps = self._gaps.setdefault(frame_id, [])
        for t in times:
            if last is not None:
                gaps.append(t - last)
            last = t
        self._last[frame_id] = times[-1]
        if len(gaps) >= SPACINGS_KEPT:
            del gaps[SPACINGS_KEPT:]
            self.watching.discard(frame_id)

    def busiest(self) -> Spacing | None:
        """The spacing of the id with the most frames (None before any id had two)."""
        kept = [(len(gaps), frame_id, gaps) for frame_id, gaps in self._gaps.items() if gaps]
        if not kept:
            return None
        count, frame_id, gaps = max(kept, key=lambda entry: entry[0])
        return Spacing(frame_id, statistics.median(gaps), count)
