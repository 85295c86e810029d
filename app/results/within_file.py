"""Do the parts of one log file between its optical sensor's pauses measure one C2n?

A file in which the sensor's frames pause beyond ``gap_reset_s`` (``LogReport.spacing``: the
logger or the sensor stopped) holds parts the filter does not bridge, as separate files do: each
part is analysed alone, and parts that disagree (``agreement.disagreement``, Holm) have no one
C2n — a logger left recording through a tyre change read one C2n between the two sets, outside
both. Parts that agree run on as one, as before, without a word: a sensor's dropout of seconds
in a sweep splits a drive into parts too short to give a C2n of their own, or into parts that
agree. It costs one more read of the file, only where it paused.

``c2n analyze``, ``c2n export`` and each drive of a campaign ask ``parts_disagree``; each says
the fix its own way. The pipeline a part runs through is given (``Part``: ``app.pipeline``'s,
a floor above this one).
"""

import itertools
import math
from collections.abc import Callable, Sequence
from typing import Protocol

import can
import numpy as np

from app.config import Config
from app.results.agreement import DriveResult, disagreement
from app.results.headline import Headline
from app.results.log_clock import clock_notes, sensor_messages
from app.sources.blocks import FrameBlock, rows
from app.sources.logs import LogReport, LogSource
from app.sources.overlap import MOST, SensorPrints, spanned
from app.sources.spacing import FrameSpacing, rewound_at
from app.sources.triage import Triage

# A stretch of driving counted twice narrows the 95 % interval by √(N/(N + n)): beyond a quarter
# of the rest (n/N > 0.25) it holds the truth less than 92 % of the time, below the coverage
# c2n is held to (issue 38: 92–98 %). A logger's resent second is less; a log joined twice, 100 %.
REPEAT_SHARE = 0.25


REPEATED = "one drive recorded twice in one file"  # the repeat's reason: its fix is one copy, not a pool


def fix_for(why: str, fix: str, log: str) -> str:
    """What to do about the parts of ``log`` that ``why`` refused: ``fix`` (each part alone), or
    for a repeat, one copy."""
    if REPEATED in why:
        return (
            f"split it (c2n split {log}: at its pauses and where its clock goes back) and keep one "
            "copy of the drive"
        )
    return fix.format(log=log)


def repeated(prints: "list[SensorPrints]", spans: list[tuple[float, float]], name: str) -> str | None:
    """Why the file counts driving twice: its parts that mostly hold an earlier part's driving
    (``overlap.spanned`` over ``MOST``), each its largest such repeat, their seconds summed,
    beyond ``REPEAT_SHARE`` of the rest; the line names the pair that repeats most. None where
    the repeats weigh less, or there are none."""
    seconds = [end - begin for begin, end in spans]
    total, most = 0.0, (0.0, 0, 0, 0.0)
    for k, part in enumerate(prints):  # each part's largest repeat of an earlier one
        alike = [(spanned(prints[j], part), j) for j in range(k)]
        repeats = [(share * min(seconds[j], seconds[k]), j, k, share) for share, j in alike if share > MOST]
        if repeats:
            again = max(repeats)
            total += again[0]
            most = max(most, again)
    if not total > REPEAT_SHARE * (sum(seconds) - total):
        return None
    _, j, k, share = most
    called = [f"part {i + 1} ({begin:.0f}–{end:.0f} s)" for i, (begin, end) in enumerate(spans)]
    return (
        f"{name}'s {called[j]} and {called[k]} hold the same driving (the optical sensor's frames alike, "
        f"run for run, over {100 * share:.0f} % of the shorter), {total:.0f} s of it repeated: {REPEATED} "
        "— two logs joined, one of them twice? — which would count twice"
    )


class PartResult(Protocol):
    @property
    def headline(self) -> Headline | None: ...


class Part(Protocol):
    """What a part's frames run through: ``app.pipeline.Pipeline``."""

    @property
    def decoder(self) -> Triage: ...

    def process(self, msg: can.Message) -> object: ...

    def process_block(self, block: FrameBlock) -> object: ...

    def finish(self) -> object: ...

    def snapshot(self) -> PartResult: ...


def cuts(pauses: Sequence[tuple[float, float]]) -> np.ndarray:
    """Where a file is cut into parts: the middle of each of its sensor's pauses (``pauses``:
    the last frame before and the first after). A frame of another id in a pause goes to the
    drive it is nearer: the bus of the next drive waking before its sensor does is that drive's."""
    return np.array([(before + after) / 2.0 for before, after in pauses])


def part_of(cut: np.ndarray, t: np.ndarray | Sequence[float]) -> np.ndarray:
    """The part each time in ``t`` falls in (0 the first), the file cut at ``cut`` (``cuts``)."""
    return np.searchsorted(cut, t, side="right")


class Parting:
    """Which part of a file each of its frames is in, read in file order: cut at the middle of
    each pause of its sensor's frames (``cuts``), and wherever the sensor's clock went back
    beyond ``gap_reset_s`` (``FrameSpacing.rewinds``: a second recording appended, a logger's
    clock set back) — there by order in the file, the pauses by time within each stretch of
    the clock. A frame of another id goes to the stretch of the sensor's frames before it."""

    def __init__(self, spacing: FrameSpacing) -> None:
        self.ids = np.array(sorted(spacing.ids))
        self.pause_s = spacing.pause_s
        stretches: list[list[tuple[float, float]]] = [[] for _ in range(len(spacing.rewinds) + 1)]
        for pause, before in zip(spacing.pauses, spacing.pause_rewinds, strict=True):
            stretches[before].append(pause)
        self.pauses = stretches
        self.cuts = [cuts(pauses) for pauses in stretches]
        self.first = np.cumsum([0, *(len(c) + 1 for c in self.cuts)])[:-1]  # each stretch's first part
        self.count = int(self.first[-1]) + len(self.cuts[-1]) + 1
        self.rewinds = spacing.rewinds
        self._stretch, self._latest = 0, -math.inf

    @property
    def between(self) -> str:
        """What the parts lie between, as the commands say it."""
        return "pauses" if not self.rewinds else "pauses and where its clock goes back"

    def spans(self, span_s: tuple[float, float] | None) -> list[tuple[float, float]]:
        """Each part's first and last time of the sensor (the file's first and last frame at its
        ends: ``LogReport.span_s``), in the log's own seconds."""
        first, last = span_s if span_s is not None else (0.0, math.nan)
        starts = [first, *(after for _, after in self.rewinds)]
        ends = [*(before for before, _ in self.rewinds), last]
        bounds = []
        for pauses, start, end in zip(self.pauses, starts, ends, strict=True):
            edges = [start, *(t for pause in pauses for t in pause), end]
            bounds += [(edges[2 * k], edges[2 * k + 1]) for k in range(len(pauses) + 1)]
        return bounds

    def __call__(self, frame_id: np.ndarray | Sequence[int], t: np.ndarray | Sequence[float]) -> np.ndarray:
        """The part of each frame (ids ``frame_id``, times ``t``), the file's next frames in order."""
        t = np.asarray(t, dtype=float)
        if not self.rewinds:
            return part_of(self.cuts[0], t)
        stretch = np.empty(len(t), dtype=np.int64)
        rows = np.flatnonzero(np.isin(np.asarray(frame_id), self.ids) & np.isfinite(t))
        times = t[rows]
        start = done = 0  # the first row of this stretch; the sensor's frames seen
        while True:
            back = done + rewound_at(times[done:], self._latest, self.pause_s)
            if back > done:
                self._latest = max(self._latest, float(times[done:back].max()))
            end = int(rows[back]) if back < len(times) else len(t)
            # frames of other ids after the sensor's last, already behind its clock: the next
            # recording's bus woken before its sensor
            tail = int(rows[back - 1]) + 1 if back > done else start
            behind = ~(t[tail:end] < self._latest - self.pause_s)
            ahead = tail + (int(np.flatnonzero(behind)[-1]) + 1 if behind.any() else 0)
            following = min(self._stretch + 1, len(self.cuts) - 1)
            stretch[start:ahead], stretch[ahead:end] = self._stretch, following
            if back == len(times):
                break
            self._stretch, self._latest, start, done = following, float(times[back]), end, back + 1
        out = np.empty(len(t), dtype=np.int64)
        for k in np.unique(stretch).tolist():
            own = stretch == k
            out[own] = self.first[k] + part_of(self.cuts[k], t[own])
        return out


def parts_disagree(report: LogReport, config: Config, part: Callable[[Config], Part]) -> str | None:
    """One line naming each part's result and the pair that differs most, where the parts of
    ``report``'s file between its pauses (``report.spacing.pauses``) disagree, each alone (each
    run through its own ``part(config)``), or where two parts hold one stretch of driving (two
    logs joined, one of them twice: ``app.sources.overlap``), which would count twice; None where
    they agree, where the file did not pause (it is not read again), and where its clock is not
    in seconds (every frame is a pause then, and ``log_clock`` says why)."""
    spacing = report.spacing
    if not (spacing.pauses or spacing.rewinds) or clock_notes([report], config):
        return None
    parting = Parting(spacing)
    parts = [part(config) for _ in range(parting.count)]
    prints = [SensorPrints(frozenset(sensor_messages(config))) for _ in parts]
    for item in LogSource([report.path], triage=parts[0].decoder).items(blocks=True):
        if isinstance(item, FrameBlock):
            index = parting(item.frame_id, item.t)
            edges = [0, *(np.flatnonzero(np.diff(index)) + 1), len(index)]
            for begin, end in itertools.pairwise(edges):
                some = rows(item, begin, end)
                parts[int(index[begin])].process_block(some)
                prints[int(index[begin])].add(some)
        elif item is not None:
            i = int(parting([item.arbitration_id], [item.timestamp])[0])
            parts[i].process(item)
            prints[i].add(item)
    t0 = report.span_s[0] if report.span_s is not None else 0.0
    spans = parting.spans(report.span_s)
    names = [f"{report.path.name} {begin - t0:.0f}–{end - t0:.0f} s" for begin, end in spans]
    twice = repeated(prints, [(begin - t0, end - t0) for begin, end in spans], report.path.name)
    if twice is not None:
        return twice
    alone = []
    for pipeline, name in zip(parts, names, strict=True):
        pipeline.finish()
        headline = pipeline.snapshot().headline
        if headline is not None:
            alone.append(DriveResult(name, headline.c2n, headline.ci95))
    return disagreement(alone)
