"""The comparison a tyre programme asks for: C2n per group, the groups' differences, trends.

Sessions of one tyre set do not agree to within their own intervals: days, temperatures and
drivers differ. Pooling their samples would pretend they do, so each group is a random-effects
combination of its sessions: DerSimonian–Laird's between-session variance τ², the sessions
weighted 1/(sᵢ² + τ²), and the interval after Hartung–Knapp(–Sidik–Jonkman), a t interval on
k − 1 degrees of freedom whose scale is estimated from the sessions' own spread (never below the
sessions' stated precision: the modified form, max(1, q)), which holds its coverage with few
sessions where the normal interval does not. A trend against a numeric tag is the same on a
weighted line (meta-regression, k − 2 degrees of freedom).

Whether tyres soften is a property of the tyre set, not of one drive, so a group decides it over
its sessions together: a session's a_y³ term passes |t| > 2 by chance in about 1.5 % of drives on
linear tyres (C2n then 0.6–2.4 % high), and a campaign of 42 meets one about every second time.
The sessions' t statistics combine (Stouffer: z = Σt/√k, each t about N(0, 1) on linear tyres) and
face the same bar a session's t does. A session whose fit chose its model by that test (the
cascade, ``[priors] estimator = "cascade"``) is then compared on its fit of the group's model, the
linear one or the one with the softening term. A marginal fit (the default) chose nothing: its C2n
carries the softening under its prior, so it is pooled as it is, and z only says what the
sessions together show of the tyres.

A session's interval may hold the sensors' scale tolerance (``c2n_scale_se_pct``): one sensor
drove them all, so the sessions are pooled on their data's error alone (``Estimate.se``, which
each fit holds apart from the scales') and the scale is counted once in each
group's C2n (``with_scale``); the differences and trends are free of it.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import Literal, NamedTuple

import numpy as np
from scipy.special import stdtrit  # the t quantile: scipy.stats would add a second to the start

from app.units import Z95


@dataclass(frozen=True)
class Pooled:
    """The random-effects C2n of a group's sessions."""

    c2n: float
    ci95: tuple[float, float]
    se: float
    df: int  # of the t interval (k − 1); 0 for one session, whose own interval stands
    n_sessions: int
    tau: float  # between-session standard deviation [1/rad]
    i2_pct: float  # share of the spread that is between sessions, not within


@dataclass(frozen=True)
class Difference:
    a: str
    b: str
    c2n: float  # a − b
    ci95: tuple[float, float]


@dataclass(frozen=True)
class Trend:
    slope: float  # C2n per unit of the tag
    slope_ci95: tuple[float, float]
    intercept: float
    n_sessions: int


SOFTENING_T = 2.0  # the bar a session's a_y³ term passes (app/results/cascade.py), for z too

Model = Literal["linear", "softening"]


class Estimate(NamedTuple):
    """A session's C2n as a campaign compares it."""

    c2n: float
    ci95: tuple[float, float]  # the data's error and the sensors' scales'
    se: float  # the data's alone: sessions are pooled on it, the one sensor's scale counted once

    @classmethod
    def of(cls, c2n: float, ci95: tuple[float, float], data_ci95: tuple[float, float]) -> "Estimate":
        """From the 95 % intervals with and without the sensors' scales."""
        return cls(c2n, ci95, session_se(data_ci95))


@dataclass(frozen=True)
class Fits:
    """One session's two fits of the same samples: without and with the softening term."""

    softening_t: float  # the a_y³ term's t; negative where the tyres soften
    linear: Estimate
    softening: Estimate | None  # None: the term made no stiffness
    chosen: Model  # the session's own choice (|t| > 2 and softening: the softening model)

    def of(self, model: Model) -> Estimate | None:
        return self.linear if model == "linear" else self.softening


@dataclass(frozen=True)
class Softening:
    """A group's tyres: do they soften, on the evidence of its sessions together?"""

    model: Model
    z: float  # Stouffer's combination of the sessions' t: negative where they soften
    n_sessions: int  # sessions whose fit could take either model

    @property
    def shown(self) -> str:
        """The model and z as the terminal and the report show them (never "z −0.0")."""
        return f"{self.model} (z {round(self.z, 1) + 0.0:+.1f})"


def softening(t: Sequence[float]) -> Softening | None:
    """The group's model from its sessions' a_y³ t statistics (None without any)."""
    if not t:
        return None
    z = float(sum(t)) / math.sqrt(len(t))
    return Softening("softening" if z < -SOFTENING_T else "linear", z, len(t))


def session_se(ci95: tuple[float, float]) -> float:
    """The standard error of a normal interval as wide as a session's (a fit's t interval on its
    blocks' degrees of freedom is wider than 1.96 se: the width keeps what few blocks cannot tell)."""
    return (ci95[1] - ci95[0]) / (2 * Z95)


def pool(c2n: Sequence[float], se: Sequence[float]) -> Pooled:
    y, s2 = np.asarray(c2n, float), np.asarray(se, float) ** 2
    k = len(y)
    if k == 0:
        raise ValueError("no sessions to pool")
    if k == 1:
        return Pooled(float(y[0]), (y[0] - Z95 * se[0], y[0] + Z95 * se[0]), float(se[0]), 0, 1, 0.0, 0.0)
    w = 1 / s2
    fixed = float(w @ y / w.sum())
    q = float(w @ (y - fixed) ** 2)
    tau2 = max(0.0, (q - (k - 1)) / (w.sum() - (w**2).sum() / w.sum()))
    weights = 1 / (s2 + tau2)
    mean = float(weights @ y / weights.sum())
    spread = float(weights @ (y - mean) ** 2) / (k - 1)
    se_pooled = math.sqrt(max(1.0, spread) / weights.sum())
    half = float(stdtrit(k - 1, 0.975)) * se_pooled
    i2 = max(0.0, (q - (k - 1)) / q) * 100 if q > 0 else 0.0
    return Pooled(mean, (mean - half, mean + half), se_pooled, k - 1, k, math.sqrt(tau2), i2)


def with_scale(pooled: Pooled, relative_se: float) -> Pooled:
    """The group's C2n with the sensors' scale error counted once: one sensor drove every session,
    so its scale does not average out over them (nor does it enter their differences or trends)."""
    if not relative_se > 0:
        return pooled
    extra = relative_se * pooled.c2n
    half = math.hypot((pooled.ci95[1] - pooled.ci95[0]) / 2, Z95 * extra)
    return replace(pooled, ci95=(pooled.c2n - half, pooled.c2n + half), se=math.hypot(pooled.se, extra))


def difference(a: str, pa: Pooled, b: str, pb: Pooled) -> Difference:
    """a − b with a Welch–Satterthwaite t interval (each group's variance on its own df)."""
    d = pa.c2n - pb.c2n
    va, vb = pa.se**2, pb.se**2
    se = math.sqrt(va + vb)
    if pa.df and pb.df:
        df = (va + vb) ** 2 / (va**2 / pa.df + vb**2 / pb.df)
        q = float(stdtrit(df, 0.975))
    else:
        q = float(stdtrit(max(pa.df, pb.df), 0.975)) if (pa.df or pb.df) else Z95
    return Difference(a, b, d, (d - q * se, d + q * se))


# A tag's value as a spreadsheet holds it: Excel keeps 15 significant digits ("Excel
# specifications and limits", Microsoft: number precision, 15 digits), and 15 is what a double
# carries through decimal text and back (DBL_DIG). Digits past them are its rounding's (2.3 and
# 2.3000000000000003 are one tag value), and a line fitted through them alone had a slope of 1e14.
SIGNIFICANT_DIGITS = 15


def as_kept(x: float) -> float:
    """``x`` to ``SIGNIFICANT_DIGITS`` (as it is where rounding it to them would overflow)."""
    kept = float(f"{x:.{SIGNIFICANT_DIGITS}g}")
    return kept if math.isfinite(kept) else x


def no_trend(x: Sequence[float], no_value: int = 0) -> str:
    """Why ``trend`` fits no line against a tag whose values are x: said where it fits none;
    ``no_value``: the sessions with a C2n left out, their tag's cell empty."""
    left_out, with_value = "", ""
    if no_value:
        had = "1 session with a C2n has" if no_value == 1 else f"{no_value} sessions with a C2n have"
        left_out, with_value = f" ({had} no value: left out)", " and a value"
    if not x:
        return f"no session with a C2n{with_value}: no trend{left_out}"
    if len(x) == 1:
        return f"1 session with a C2n{with_value}: a trend needs three{left_out}"
    if len({as_kept(v) for v in x}) < 2:
        return f"takes one value: no trend{left_out}"
    if len(x) < 3:
        return f"{len(x)} sessions with a C2n{with_value}: a trend needs three{left_out}"
    return "the fit overflows: no trend"


def trend(x: Sequence[float], c2n: Sequence[float], se: Sequence[float]) -> Trend | None:
    """C2n = intercept + slope·x over the sessions, random effects (None where x has fewer than
    two distinct values to 15 significant digits, there are fewer than three sessions, or the
    fit overflows).

    The line is fitted on x centred on its middle and scaled by its half range, u = (x − c)/h in
    [−1, 1]: on raw x the normal equations of a date tag (20261124 … 20261126) lose every digit
    the slope needs, and a tag near 1e200 overflows. Slope and intercept are taken back to x
    exactly: slope = b/h, intercept = a − slope·c."""
    xs = np.array([as_kept(v) for v in x], float)
    y, s2 = np.asarray(c2n, float), np.asarray(se, float) ** 2
    k = len(y)
    if k < 3 or len(np.unique(xs)) < 2:
        return None
    low, high = float(xs.min()), float(xs.max())
    centre = low / 2 + high / 2  # halves first: (low + high) may overflow
    half_range = high / 2 - low / 2
    if not (math.isfinite(centre) and math.isfinite(half_range) and half_range > 0):
        return None
    design = np.column_stack([np.ones(k), (xs - centre) / half_range])

    def fit(weights: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
        xtw = design.T * weights
        inverse = np.linalg.inv(xtw @ design)
        coef = inverse @ xtw @ y
        return coef, inverse, float(weights @ (y - design @ coef) ** 2)

    w = 1 / s2
    _, inverse, q = fit(w)
    projection = np.trace(inverse @ (design.T * w**2) @ design)
    tau2 = max(0.0, (q - (k - 2)) / (w.sum() - projection))
    coef, inverse, q_star = fit(1 / (s2 + tau2))
    se_slope = math.sqrt(max(1.0, q_star / (k - 2)) * inverse[1, 1]) / half_range
    half = float(stdtrit(k - 2, 0.975)) * se_slope
    slope = float(coef[1]) / half_range
    intercept = float(coef[0]) - slope * centre
    if not all(math.isfinite(v) for v in (slope, half, intercept)):
        return None
    return Trend(slope, (slope - half, slope + half), intercept, k)
