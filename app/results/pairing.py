"""Crossings paired so that a sensor misalignment and a lag cancel, and both are estimated.

A head yawed left by ψ reads β − ψ: turning left the sign change moves to u² = u0²(1 − ψ·R/d),
turning right (R < 0) the other way. A lag τ between speed and sideslip moves it by τ·u̇: later
sweeping up, earlier sweeping down. So each crossing reads

    C2n_i = C2n · (1 − ψ·R_i/d + 2·τ·u̇_i/u0)

and a weighted regression over the crossings' signed radius R_i and sweep rate u̇_i gives C2n with
both errors removed — for equal radii and rates, simply the mean of the left/right and up/down
pairs — and ψ and τ themselves.

Both terms are always in the model, ψ under the head's prior (as the regression's ψ0) and τ, where
one sweep direction cannot place it, under the steady-state gate's (``pair``), so crossings that
cannot tell ψ or τ from C2n (one direction on one radius, one sweep direction) widen C2n's
interval by what the prior allows instead of leaving the term out: CommonRoad's sweeps, four left
crossings on radii of 112 and 157 m, read 39–55 % low with intervals that held nothing when ψ was
left out. The priors' coefficients are ratios to C2n (−C2n·ψ/d, 2·C2n·τ/u0), so they follow the fit
before until it settles. ψ and τ are reported as the crossings alone measure them (the posterior's
information less the prior's), and only where that is more than the prior's.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from app.records import Crossing
from app.results.combine import ratio_ci95
from app.results.marginal import Posterior, data_alone
from app.units import Z95


@dataclass(frozen=True)
class Paired:
    c2n: float
    se: float
    misalignment_rad: float | None  # sensor head yawed left by this (None: the crossings cannot tell)
    misalignment_se: float | None
    lag_s: float | None  # sideslip lags speed by this (None: the crossings cannot tell: one sweep)
    lag_se: float | None
    cells: dict[str, float]  # "left up" etc.: the cells' weighted mean C2n
    n: int
    birge_ratio: float
    data_se: float | None = None  # C2n's error from the crossings alone, where se holds the
    # sensors' scales too (None: se is the crossings' alone)

    @property
    def data_ci95(self) -> tuple[float, float] | None:
        """C2n's 95 % interval from the crossings alone, where ci95 holds the sensors' scales too."""
        return None if self.data_se is None else ratio_ci95(self.c2n, self.data_se)

    @property
    def cancels(self) -> tuple[str, ...]:
        """What the crossings measured and the pairing removed (both directions or two radii place a
        misalignment, both sweeps a lag; otherwise its prior stays in C2n's interval)."""
        return tuple(
            name
            for name, value in (("misalignment", self.misalignment_rad), ("lag", self.lag_s))
            if value is not None
        )

    @property
    def ci95(self) -> tuple[float, float]:
        """C2n's 95 % interval, a share of C2n (``combine.ratio_ci95``): no upper bound (inf)
        where the priors' share reaches C2n itself."""
        return ratio_ci95(self.c2n, self.se)

    @property
    def bounded(self) -> bool:
        """Does the interval bound C2n above?"""
        return math.isfinite(self.ci95[1])

    @property
    def misalignment_ci95_rad(self) -> tuple[float, float] | None:
        """The head's yaw's 95 % interval, where the crossings place it."""
        return _interval(self.misalignment_rad, self.misalignment_se)

    @property
    def lag_ci95_s(self) -> tuple[float, float] | None:
        """The sideslip's lag's 95 % interval, where the crossings place it."""
        return _interval(self.lag_s, self.lag_se)


def _interval(value: float | None, se: float | None) -> tuple[float, float] | None:
    if value is None or se is None:
        return None
    return (value - Z95 * se, value + Z95 * se)


_PASSES = 5  # the priors follow C2n: settled in two or three
_SETTLED = 1e-9  # C2n settled: far inside any crossing's error
_SWEEPING = 0.02  # m/s²: a sweep up or down (a constant speed's drift is 100 times slower)


def pair(
    crossings: Sequence[Crossing], d_m: float, g: float, head_yaw_deg: float = 0.5, settle_s: float = 1.0
) -> Paired | None:
    """The crossings' C2n with a head's yaw ψ (prior N(0, ``head_yaw_deg``²)) and a lag τ taken
    out. τ is the data's own where both sweep directions were driven (flat: a lag beyond the
    steady-state gate's ``settle_s`` is the premise failing, ``support.py``, which a prior must not
    hide — on ice it explained the sweeps' disagreement away as noise); with one sweep direction it
    is under N(0, (settle_s/2)²), the longest lag the gate lets the car settle at 95 %."""
    usable = [c for c in crossings if c.c2n_se > 0 and math.isfinite(c.c2n_se) and math.isfinite(c.radius_m)]
    if not usable:
        return None
    y = np.array([c.c2n for c in usable])
    w = np.array([1.0 / c.c2n_se**2 for c in usable])
    rates = np.array([c.sweep_rate_mps2 for c in usable])
    x = np.column_stack([np.ones(len(usable)), [c.radius_m for c in usable], rates])
    c2n = float(w @ y / w.sum())  # to start: the crossings' weighted mean
    both_sweeps = rates.max() > _SWEEPING and rates.min() < -_SWEEPING
    head_yaw, lag_sd = math.radians(head_yaw_deg), math.inf if both_sweeps else settle_s / 2.0
    found: _Fit | None = None
    for _ in range(_PASSES):
        u0 = math.sqrt(max(c2n * g * d_m, 1e-12))
        size = max(abs(c2n), 1e-12)
        prior_sd = np.array([math.inf, size * head_yaw / d_m, 2.0 * size * lag_sd / u0])
        try:
            found = _fit(x, y, w, prior_sd)
        except np.linalg.LinAlgError:
            return None
        settled = abs(found.coef[0] - c2n) <= _SETTLED * size
        c2n = float(found.coef[0])
        if settled:
            break
    assert found is not None
    u0 = math.sqrt(max(c2n * g * d_m, 0.0))
    misalignment = misalignment_se = lag = lag_se = None
    own = found.own(1)
    if own is not None and c2n != 0:
        misalignment, misalignment_se = -own[0] * d_m / c2n, own[1] * d_m / abs(c2n)
    own = found.own(2)
    if own is not None and c2n != 0:
        lag, lag_se = own[0] * u0 / (2.0 * c2n), own[1] * u0 / (2.0 * abs(c2n))
    cells: dict[str, float] = {}
    for direction in ("left", "right"):
        for sweep in ("up", "down"):
            members = [c for c in usable if c.direction == direction and c.sweep == sweep]
            if members:
                weights = [1.0 / c.c2n_se**2 for c in members]
                cells[f"{direction} {sweep}"] = sum(
                    wi * c.c2n for wi, c in zip(weights, members, strict=True)
                ) / sum(weights)
    return Paired(
        c2n,
        math.sqrt(found.cov[0, 0]),
        misalignment,
        misalignment_se,
        lag,
        lag_se,
        cells,
        len(usable),
        found.birge,
    )


@dataclass(frozen=True)
class _Fit:
    """The weighted regression's posterior under Gaussian priors (``prior_sd``, mean zero, inf for
    a flat one): coefficients, covariance, the Birge ratio, and the priors' precisions."""

    coef: np.ndarray
    cov: np.ndarray
    birge: float
    precision: np.ndarray

    def own(self, term: int) -> tuple[float, float] | None:
        """What the crossings alone say of ``term`` (mean, se): the posterior's information less
        the prior's (``data_alone``, the regression's), where it is more than the prior's (else
        None: the value is the prior's)."""
        prior = float(self.precision[term])
        prior_sd = 1.0 / math.sqrt(prior) if prior > 0 else math.inf
        posterior = Posterior([0, 1, 2], self.coef, self.cov, 1.0, 1.0)
        alone = data_alone(posterior, term, 0.0, prior_sd)
        if alone is None or not alone[1] * prior < 1.0:  # the data's variance under the prior's
            return None
        return alone[0], math.sqrt(alone[1])


def _fit(x: np.ndarray, y: np.ndarray, w: np.ndarray, prior_sd: np.ndarray) -> _Fit:
    """Ridge on the weighted crossings: where they scatter beyond their own errors (the Birge ratio
    of the residuals over the effective degrees of freedom above 1), their weights are scaled
    down by its square and the fit made again."""
    finite = np.isfinite(prior_sd) & (prior_sd > 0)
    precision = np.where(finite, 1.0 / np.square(np.where(finite, prior_sd, 1.0)), 0.0)
    birge = 1.0
    for _ in range(2):
        xtw = x.T * (w / birge**2)
        data = xtw @ x
        inverse = np.linalg.inv(data + np.diag(precision))
        coef = inverse @ (xtw @ y)
        if birge > 1.0:
            break
        dof = len(y) - float(np.trace(inverse @ data))
        residual = y - x @ coef
        measured = math.sqrt(float(residual @ (w * residual)) / dof) if dof > 1e-9 else 1.0
        if measured <= 1.0:
            return _Fit(coef, inverse, measured, precision)
        birge = measured
    return _Fit(coef, inverse, birge, precision)
