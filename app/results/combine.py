"""The running combined C2n over all crossings so far."""

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
        return (self.c2n - Z95 * self.se, self.c2n + Z95 * self.se)

    @property
    def data_ci95(self) -> tuple[float, float] | None:
        """C2n's 95 % interval from the crossings alone, where ci95 holds the sensors' scales too."""
        if self.data_se is None:
            return None
        return (self.c2n - Z95 * self.data_se, self.c2n + Z95 * self.data_se)


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
