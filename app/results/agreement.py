"""Do separate drives measure one C2n? The check before their results are pooled or merged.

Each drive alone gives a C2n with its 95 % interval (whatever its headline: crossings, paired
crossings, the regression, the quasi-steady fit). Two drives of one car on one set of tyres differ
only by their errors: z = (C2nₐ − C2n_b)/√(seₐ² + se_b²) is about N(0, 1). With m drives there are
m(m − 1)/2 pairs, so each pair's two-sided p is judged by Holm's step-down procedure, which holds
the chance of any false "disagree" at the stated 5 % over all pairs (Bonferroni's bar, less
conservative after the first rejection).
"""

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass

from scipy.special import ndtr

from app.units import Z95

FAMILY_ALPHA = 0.05  # the 95 % the intervals state, held over every pair together


@dataclass(frozen=True)
class DriveResult:
    name: str
    c2n: float
    ci95: tuple[float, float]

    @property
    def se(self) -> float:
        return (self.ci95[1] - self.ci95[0]) / (2 * Z95)


def disagreement(
    drives: Sequence[DriveResult], alpha: float = FAMILY_ALPHA, what: str = "the drives"
) -> str | None:
    """None where the drives can be one C2n; else one line naming each drive's result and the
    pair that differs most (the drives called ``what``)."""
    pairs = []
    for a, b in itertools.combinations(drives, 2):
        se = math.hypot(a.se, b.se)
        z = abs(a.c2n - b.c2n) / se if se > 0 else (math.inf if a.c2n != b.c2n else 0.0)
        pairs.append((2 * float(ndtr(-z)), a, b))
    pairs.sort(key=lambda p: p[0])
    m = len(pairs)
    rejected = []
    for rank, (p, a, b) in enumerate(pairs):  # Holm: the k-th smallest p against α/(m − k)
        if p > alpha / (m - rank):
            break
        rejected.append((p, a, b))
    if not rejected:
        return None
    _, a, b = rejected[0]
    each = "; ".join(f"{d.name} {d.c2n:.3f} [{d.ci95[0]:.3f}, {d.ci95[1]:.3f}]" for d in drives)
    return (
        f"{what} disagree, each alone: {each} — {a.name} and {b.name} differ beyond their "
        f"intervals (Holm, 95 % over {m} pair{'s' if m > 1 else ''}): not one car on one set of tyres"
    )
