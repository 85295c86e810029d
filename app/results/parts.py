"""A live run's parts between its optical sensor's pauses, each alone: do they measure one C2n?

``c2n live`` left running through a tyre change (the car parked, the sensor off) pooled both sets
of tyres into one C2n, between the two and outside both. Where the sensor's frames pause beyond
``gap_reset_s`` (the filter restarts there) the run is in parts, as ``c2n analyze`` reads a log
that paused (``within_file.py``): each part is also run alone (``app.pipeline.PartedPipeline``), and
parts that disagree (``agreement.disagreement``, Holm) leave the run no one C2n, each part's own
named instead. Parts that agree pool, without a word: a dropout of seconds in a sweep splits a
drive into parts too short for a C2n of their own, or into parts that agree.
"""

from collections.abc import Sequence
from dataclasses import dataclass

from app.results.agreement import DriveResult, disagreement
from app.results.headline import Headline, positive


@dataclass(frozen=True)
class Part:
    """One part of the run: from its first frame to its optical sensor's last before the pause
    (frame times), and its own C2n as it stood then (None: none yet, or none it supports)."""

    begin_t: float
    end_t: float
    headline: Headline | None


def parts_disagree(parts: Sequence[Part], t0: float) -> str | None:
    """One line naming each part's C2n (its seconds from ``t0``, the run's first frame) and the
    pair that differs most, where the parts' own results disagree; None where they can be one
    C2n, or fewer than two have one."""
    alone = [
        DriveResult(f"{p.begin_t - t0:.0f}–{p.end_t - t0:.0f} s", p.headline.c2n, p.headline.ci95)
        for p in parts
        if p.headline is not None and positive(p.headline.c2n)
    ]
    why = disagreement(alone, what="the parts between the optical sensor's pauses")
    if why is None:
        return None
    return (
        f"{why} — a tyre change while the sensor was off? Each part's C2n is its own: split the "
        "session's recording at its pauses (c2n split) and analyse each part alone"
    )
