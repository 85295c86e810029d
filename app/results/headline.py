"""The one C2n a drive reports, and which of the drive's estimates it is.

There is one estimator: the regression of every steady sample's sideslip on the model
β = ψ0 + d·κ − a_y/(g·C2n) + the nuisances' terms (``regression.py``), its interval counting what
the drive cannot tell. The crossings are samples of the same drive (those where β changes sign),
so they are not a second measurement to average in: combining the two would count those samples
twice. What the headline is depends only on what the drive held, never on which estimate reads
best:

- a sweep crossed zero and the steady samples support a fit: the regression;
- no sweep crossed zero: the same regression over the quasi-steady samples (corners held at
  several speeds, their slow transients' terms fitted);
- crossings but too few steady samples for a fit (under 200, ten blocks or 0.5 m/s² of a_y): the
  crossings paired (misalignment and lag taken out), else their inverse-variance mean.

A C2n that is not positive is no stiffness, and none is reported; nor is one whose interval has no
upper end: a fit's whose a_y coefficient's interval reaches zero (``marginal.reciprocal_mixture``;
``refusal.unbounded_fit`` says why), or the crossings' where a head's yaw they cannot tell from C2n
may cancel the whole sideslip (``combine.ratio_ci95``; ``support.unbounded_crossings``).
"""

import math
from dataclasses import dataclass
from enum import StrEnum
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the fits' modules load numpy: `c2n --help` reads Method without them
    from app.results.combine import Combined
    from app.results.pairing import Paired
    from app.results.regression import RegressionFit


class Method(StrEnum):
    """Which estimate the headline is (``c2n_method`` in the summary)."""

    REGRESSION = "regression"
    QUASI_STEADY = "quasi-steady"
    PAIRED = "paired crossings"
    CROSSINGS = "crossings"

    @property
    def is_fit(self) -> bool:
        """A regression's (with its fit's terms), not the crossings'."""
        return self in (Method.REGRESSION, Method.QUASI_STEADY)


@dataclass(frozen=True)
class Headline:
    c2n: float
    ci95: tuple[float, float]  # the data's error and the sensors' scales' ([calibration])
    method: Method
    data_ci95: tuple[float, float] | None = None  # the data's alone, where ci95 holds the scales too

    @property
    def data_only_ci95(self) -> tuple[float, float]:
        """The 95 % interval from the data alone: what a campaign pools sessions on, the scales
        of the one sensor that drove them all counted once in the group's."""
        return self.ci95 if self.data_ci95 is None else self.data_ci95


def positive(c2n: float) -> bool:
    return math.isfinite(c2n) and c2n > 0.0


def headline(
    regression: "RegressionFit | None",
    quasi: "RegressionFit | None",
    paired: "Paired | None",
    combined: "Combined | None",
) -> Headline | None:
    """The drive's C2n by what it held (the module's list); ``quasi`` is given only where no sweep
    crossed zero. Refusals (a sign the wrong way round, drives that disagree, crossings whose sweeps
    disagree) are the caller's: they decide whether there is a result, not which one."""
    fit, method = (quasi, Method.QUASI_STEADY) if quasi is not None else (regression, Method.REGRESSION)
    if fit is not None:
        bounded = positive(fit.c2n) and math.isfinite(fit.c2n_ci95[1])
        return Headline(fit.c2n, fit.c2n_ci95, method, fit.c2n_data_ci95) if bounded else None
    if paired is not None and positive(paired.c2n):  # unbounded: the mean would hide what it counts
        return Headline(paired.c2n, paired.ci95, Method.PAIRED, paired.data_ci95) if paired.bounded else None
    if combined is not None and positive(combined.c2n) and combined.bounded:
        return Headline(combined.c2n, combined.ci95, Method.CROSSINGS, combined.data_ci95)
    return None
