"""Two recordings of one stretch of driving: a second logger on the same bus, or a copy cut short
or thinned — not one file twice (``identity.py`` reads that once), but the optical sensor's frames
alike over a stretch. Pooled, that stretch counts twice: C2n's interval √2 too narrow over it, a
campaign's group weighing it double.

The sensor's data bytes carry its noise, so a run of ``WINDOW`` consecutive frames of one id is
the drive's own: no other drive repeats it. A recording keeps the runs that end at an anchor — a
frame whose payload's mixed bits fall in one eighth — so that two copies keep the same runs
whatever each lost or wherever each began. A run of few distinct payloads (a car standing, a
sensor holding its last value) is not kept: every drive has those.

Two recordings hold one stretch of driving where the runs both hold span most of the shorter
one's runs, first to last: a second logger's copy spans all of it whatever frames it lost (a run
is lost with any of its frames, so a copy missing 10 % of them shares 19 % of the runs, but
spread over the whole), and a log cut from another lies wholly in it. Two simulations of one seed
share the noise wherever their tyres do not part them (straights, standing): told the same way.
"""

from collections import deque
from collections.abc import Iterable
from dataclasses import dataclass, field

import can
import numpy as np

from app.sources.blocks import FrameBlock

WINDOW = 16  # consecutive frames of one id: 0.16 s of a sensor at 100 Hz
DISTINCT = WINDOW // 2  # at least this many different payloads in a run kept
_ANCHOR_SHIFT = 61  # a run ends where the mixed payload's top 3 bits are 0: one frame in 8
_MIX = 0x9E3779B97F4A7C15  # Fibonacci hashing's multiplier: every bit of the payload moves the top ones
_POLY = 0x100000001B3  # the runs' polynomial hash (FNV's prime)
_MASK = (1 << 64) - 1
_POWERS = np.array([pow(_POLY, WINDOW - 1 - j, 1 << 64) for j in range(WINDOW)], dtype=np.uint64)


def payload(data: bytes | bytearray | np.ndarray) -> int:
    """A frame's first eight data bytes as one number (little-endian, zeros beyond its length)."""
    return int.from_bytes(bytes(data[:8]).ljust(8, b"\0"), "little")


def _anchored(value: int) -> bool:
    return ((value * _MIX) & _MASK) >> _ANCHOR_SHIFT == 0


def _run_hash(values: "deque[int] | list[int]") -> int:
    h = 0
    for v in values:
        h = (h * _POLY + v) & _MASK
    return h


@dataclass
class SensorPrints:
    """The runs of the frames of ``ids`` a recording holds (their hashes), frame by frame or in
    blocks alike."""

    ids: frozenset[int] = frozenset()
    runs: dict[int, float] = field(default_factory=dict, init=False)  # each run's hash: its last frame's time
    _recent: dict[int, "deque[int]"] = field(default_factory=dict, init=False)

    def add(self, item: can.Message | FrameBlock) -> None:
        """Note a frame's payload, or a block's frames' (the caller may skip frames of other ids)."""
        if isinstance(item, FrameBlock):
            for frame_id in self.ids:
                mine = item.frame_id == frame_id
                if mine.any():
                    width = min(item.data.shape[1], 8)
                    rows = np.zeros((int(mine.sum()), 8), dtype=np.uint8)
                    rows[:, :width] = item.data[mine, :width]
                    rows[np.arange(8) >= item.length[mine][:, None]] = 0  # as a Message's bytes end
                    self._add_values(frame_id, rows.view("<u8").ravel(), item.t[mine])
        elif item.arbitration_id in self.ids and not item.is_error_frame and not item.is_remote_frame:
            recent = self._recent.setdefault(item.arbitration_id, deque(maxlen=WINDOW))
            value = payload(item.data)
            recent.append(value)
            if len(recent) == WINDOW and _anchored(value) and len(set(recent)) >= DISTINCT:
                self.runs.setdefault(_run_hash(recent), item.timestamp)

    def _add_values(self, frame_id: int, values: np.ndarray, times: np.ndarray) -> None:
        """``add`` over an id's payloads in order, with the numbers of numpy: the same runs."""
        recent = self._recent.setdefault(frame_id, deque(maxlen=WINDOW))
        joined = np.concatenate([np.array(recent, dtype=np.uint64), values.astype(np.uint64)])
        recent.extend(int(v) for v in values[-WINDOW:])
        if len(joined) < WINDOW:
            return
        windows = np.lib.stride_tricks.sliding_window_view(joined, WINDOW)
        last = windows[:, -1]
        with np.errstate(over="ignore"):
            anchored = (last * np.uint64(_MIX)) >> np.uint64(_ANCHOR_SHIFT) == 0
            # only the windows that end in this block's frames: the carried ones were judged before
            anchored[: max(len(windows) - len(values), 0)] = False
            chosen = windows[anchored]
            if not len(chosen):
                return
            ordered = np.sort(chosen, axis=1)
            distinct = 1 + (np.diff(ordered, axis=1) != 0).sum(axis=1)
            kept = distinct >= DISTINCT
            hashes = (chosen[kept] * _POWERS).sum(axis=1, dtype=np.uint64)
        ends = times[np.flatnonzero(anchored) - (len(windows) - len(values))][kept]
        for h, t in zip(hashes.tolist(), ends.tolist(), strict=True):
            self.runs.setdefault(h, t)


SAMPLED = 16  # a campaign row carries one run in 16 (by its hash: every copy keeps the same ones)


def sample(prints: "Iterable[SensorPrints]") -> tuple[tuple[int, float], ...]:
    """The runs of a drive's recordings (a session's parts) a campaign row carries: one in
    ``SAMPLED``, chosen by hash, so that two copies' samples hold the same runs."""
    return tuple(sorted((h, t) for p in prints for h, t in p.runs.items() if h % SAMPLED == 0))


def of_runs(runs: "Iterable[tuple[int, float]]") -> SensorPrints:
    """A recording's prints from its runs (a campaign row's sample)."""
    prints = SensorPrints()
    prints.runs.update(runs)
    return prints


def spanned(a: SensorPrints, b: SensorPrints) -> float:
    """How much of the shorter recording (by its runs' times, first to last) the runs both hold
    span, first to last: 0 to 1, 0 where they share fewer than ``MIN_SHARED``."""
    shorter = a if _span(a.runs.values()) <= _span(b.runs.values()) else b
    both = [shorter.runs[h] for h in a.runs.keys() & b.runs.keys()]
    whole = _span(shorter.runs.values())
    if len(both) < MIN_SHARED or whole <= 0.0:
        return 0.0
    return _span(both) / whole


def _span(times: Iterable[float]) -> float:
    listed = list(times)
    return max(listed) - min(listed) if listed else 0.0


MIN_SHARED = 3  # runs alike that make a stretch: one run alike by chance is one in 2⁶⁴ or so
MOST = 0.5  # the runs both hold span more than half the shorter recording: it is mostly the other's


def overlapping(recordings: "list[tuple[str, SensorPrints]]") -> tuple[str, str, float] | None:
    """The first two recordings of which the shorter is mostly the other's (``spanned`` over
    ``MOST``), and how much of it; None where no two are (``alike_earlier``, each in turn)."""
    earlier: list[SensorPrints] = []
    holder: dict[int, int] = {}
    for second, prints in recordings:
        i = alike_earlier(prints, earlier, holder)
        if i is not None:
            return recordings[i][0], second, spanned(earlier[i], prints)
    return None


def alike_earlier(prints: SensorPrints, earlier: "list[SensorPrints]", holder: dict[int, int]) -> int | None:
    """The first of the ``earlier`` recordings whose stretch of driving ``prints`` holds too
    (``spanned`` over ``MOST``), by ``holder`` (each run's first holder among them, kept up to
    date here: ``prints`` is added as the next); None where none."""
    mine = len(earlier)
    alike = sorted({i for run in prints.runs if (i := holder.setdefault(run, mine)) != mine})
    found = next((i for i in alike if spanned(earlier[i], prints) > MOST), None)
    earlier.append(prints)
    return found
