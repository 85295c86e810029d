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
from app.results.log_clock import clock_notes
from app.sources.blocks import FrameBlock, rows
from app.sources.logs import LogReport, LogSource
from app.sources.triage import Triage


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


def parts_disagree(report: LogReport, config: Config, part: Callable[[Config], Part]) -> str | None:
    """One line naming each part's result and the pair that differs most, where the parts of
    ``report``'s file between its pauses (``report.spacing.pauses``) disagree, each alone (each
    run through its own ``part(config)``); None where they agree, where the file did not pause
    (it is not read again), and where its clock is not in seconds (every frame is a pause then,
    and ``log_clock`` says why)."""
    pauses = report.spacing.pauses
    if not pauses or clock_notes([report], config):
        return None
    cut = cuts(pauses)
    parts = [part(config) for _ in range(len(pauses) + 1)]
    for item in LogSource([report.path], triage=parts[0].decoder).items(blocks=True):
        if isinstance(item, FrameBlock):
            index = part_of(cut, item.t)
            edges = [0, *(np.flatnonzero(np.diff(index)) + 1), len(index)]
            for begin, end in itertools.pairwise(edges):
                parts[int(index[begin])].process_block(rows(item, begin, end))
        elif item is not None:
            parts[int(part_of(cut, [item.timestamp])[0])].process(item)
    t0 = report.span_s[0] if report.span_s is not None else 0.0
    bounds = [t0, *(t for pause in pauses for t in pause), report.span_s[1] if report.span_s else math.nan]
    alone = []
    for k, pipeline in enumerate(parts):
        pipeline.finish()
        headline = pipeline.snapshot().headline
        if headline is not None:
            begin, end = bounds[2 * k] - t0, bounds[2 * k + 1] - t0
            name = f"{report.path.name} {begin:.0f}–{end:.0f} s"
            alone.append(DriveResult(name, headline.c2n, headline.ci95))
    return disagreement(alone)
