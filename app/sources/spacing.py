"""How far apart the frames of a periodic message lie in a log's own time, and where they pause.

The log's clock unit shows in it: a sensor sending every 10 ms whose log keeps its times in
milliseconds (a CSV or candump file written by another tool) reads as frames 10 "s" apart. The
reader keeps each watched id's spacings (``LogReport.spacing``); ``results/log_clock.py`` says
what they mean. A pause — no frame of any watched id for longer than ``pause_s`` (the config's
``gap_reset_s``, beyond which the filter starts afresh) — is kept over the whole file: the
recording stopped there, or the sensor did, and what comes after may be another drive
(``c2n analyze`` checks the parts between pauses alone).
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
    """The spacings of consecutive frames of each id in ``ids`` (none: nothing is kept), and the
    pauses longer than ``pause_s`` between the frames of any of them."""

    ids: frozenset[int] = frozenset()
    pause_s: float = math.inf
    watching: set[int] = field(init=False)  # the ids still short of SPACINGS_KEPT
    pauses: list[tuple[float, float]] = field(default_factory=list, init=False)  # (last before, first after)
    # where the watched frames' clock went back by more than pause_s: (the latest before, the
    # frame's), in file order — a second recording appended, a logger's clock set back
    rewinds: list[tuple[float, float]] = field(default_factory=list, init=False)
    pause_rewinds: list[int] = field(default_factory=list, init=False)  # how many came before each pause
    _last: dict[int, float] = field(default_factory=dict, init=False)
    _gaps: dict[int, list[float]] = field(default_factory=dict, init=False)
    _latest: float = field(default=-math.inf, init=False)  # the latest watched frame's time

    def __post_init__(self) -> None:
        self.watching = set(self.ids)

    def add(self, item: can.Message | FrameBlock) -> None:
        """Note a frame's time, or a block's frames' (the caller may skip frames of other ids)."""
        if isinstance(item, FrameBlock):
            watched = np.isin(item.frame_id, list(self.ids)) & np.isfinite(item.t)
            times, ids = item.t[watched], item.frame_id[watched]
            if not len(times):
                return
            for frame_id in list(self.watching):
                own = times[ids == frame_id]
                if len(own):
                    self._note(frame_id, own.tolist())
            while len(times):  # each stretch up to where the clock goes back
                back = rewound_at(times, self._latest, self.pause_s)
                latest = np.maximum.accumulate(np.concatenate(([self._latest], times[:back])))
                for k in np.flatnonzero((np.diff(latest) > self.pause_s) & np.isfinite(latest[:-1])):
                    self._pause(float(latest[k]), float(latest[k + 1]))
                self._latest = float(latest[-1])
                if back >= len(times):
                    break
                self._rewind(float(times[back]))
                times = times[back + 1 :]
        elif item.arbitration_id in self.ids and math.isfinite(item.timestamp):
            if item.arbitration_id in self.watching:
                self._note(item.arbitration_id, [item.timestamp])
            if item.timestamp < self._latest - self.pause_s:
                self._rewind(item.timestamp)
            elif item.timestamp - self._latest > self.pause_s and self._latest > -math.inf:
                self._pause(self._latest, item.timestamp)
            self._latest = max(self._latest, item.timestamp)

    def _pause(self, before: float, after: float) -> None:
        self.pauses.append((before, after))
        self.pause_rewinds.append(len(self.rewinds))

    def _rewind(self, t: float) -> None:
        """The clock went back to ``t``: what follows is measured from there (its pauses too)."""
        self.rewinds.append((self._latest, t))
        self._latest = t

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


def rewound_at(times: np.ndarray, latest: float, pause_s: float) -> int:
    """The index of the first of ``times`` (finite, in file order) more than ``pause_s`` before the
    latest time seen (``latest`` before the first): where the clock went back; ``len(times)``
    where it never did."""
    before = np.maximum.accumulate(np.concatenate(([latest], times[:-1])))
    back = np.flatnonzero(times < before - pause_s)
    return int(back[0]) if len(back) else len(times)
