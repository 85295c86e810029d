"""The running combined C2n over all crossings so far, and the crossings' interval form.

A crossing reads C2n·(1 + ε): the pairing's misalignment and lag terms are shares of C2n
(C2n_i = C2n·(1 − ψ·R_i/d + 2·τ·u̇_i/u0)), and so is the crossing's own error (C2n = u0²/(g·d)).
An error of se on a reading ĉ is then a share r = se/ĉ of C2n, and the 95 % interval is every C2n
that reads ĉ within Z95·r of itself: [ĉ/(1 + Z95·r), ĉ/(1 − Z95·r)] (ĉ ± Z95·se to first order).
Where Z95·r reaches 1 an error as large as C2n itself is not ruled out — a head yawed within its
tolerance on a wide circle can cancel the whole sideslip — and C2n has no upper bound: the
crossings then give no result (``support.unbounded_crossings``), where ĉ ± Z95·se read
[−4.4, 34.2] for one crossing.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass

from app.records import Crossing
from app.units import Z95


@dataclass(frozen=True)
class Combined:
    c2n: float
    se: float
    n: int
    birge_ratio: float  # √(χ²/dof): > 1 when crossings scatter more than their intervals say
    data_se: float | None = None  # the crossings' alone, where se holds the sensors' scales too

    @property
    def ci95(self) -> tuple[float, float]:
        return ratio_ci95(self.c2n, self.se)

    @property
    def bounded(self) -> bool:
        """Does the interval bound C2n above (the module's doc)?"""
        return math.isfinite(self.ci95[1])

    @property
    def data_ci95(self) -> tuple[float, float] | None:
        """C2n's 95 % interval from the crossings alone, where ci95 holds the sensors' scales too."""
        return None if self.data_se is None else ratio_ci95(self.c2n, self.data_se)


def bracket(ci95: tuple[float, float]) -> str:
    """An interval as the results print it: [low, high], or [low, no upper bound]."""
    high = f"{ci95[1]:.3f}" if math.isfinite(ci95[1]) else "no upper bound"
    return f"[{ci95[0]:.3f}, {high}]"


def ratio_ci95(c2n: float, se: float) -> tuple[float, float]:
    """The 95 % interval of a C2n read as a share of itself (the module's doc); the upper end is
    inf where the error reaches C2n. A reading that is not positive is no stiffness (no result
    stands on it): its interval is the plain ĉ ± Z95·se."""
    if not (c2n > 0.0 and math.isfinite(se)):
        return (c2n - Z95 * se, c2n + Z95 * se)
    share = Z95 * se / c2n
    return (c2n / (1.0 + share), c2n / (1.0 - share) if share < 1.0 else math.inf)


def combine(crossings: Sequence[Crossing]) -> Combined | None:
    """Inverse-variance weighted mean; its error is widened by the Birge ratio when the
    crossings disagree beyond their own intervals (e.g. an uncorrected sensor misalignment)."""
    usable = [c for c in crossings if c.c2n_se > 0 and math.isfinite(c.c2n_se)]
    if not usable:
        return None
    weights = [1.0 / c.c2n_se**2 for c in usable]
    total = sum(weights)
    mean = sum(w * c.c2n for w, c in zip(weights, usable, strict=True)) / total
    se = math.sqrt(1.0 / total)
    birge = 1.0
    if len(usable) > 1:
        chi2 = sum(w * (c.c2n - mean) ** 2 for w, c in zip(weights, usable, strict=True))
        birge = math.sqrt(chi2 / (len(usable) - 1))
    return Combined(mean, se * max(1.0, birge), len(usable), birge)
