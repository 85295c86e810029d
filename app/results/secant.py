"""A crossing's C2n at zero lateral acceleration, from the regression's softening term.

A crossing reads C2n = u0²/(g·d) (eq. 7). Where the tyres soften with slip, α2 = a_y/(g·C2n)·(1 +
s·a_y²), the sideslip changes sign where u0²/(g·d) meets the tyres' secant, C2n/(1 + s·a0²) at the
crossing's own a0 — below the slope at zero that the regression reports (Magic-Formula tyres at
μ = 1: about 1 % at 2.5 m/s², 3 % at 4). A crossing, at one a_y, cannot see s; the regression, over
every steady sample, can (``RegressionFit.softening.per_mps2_2``). So where it keeps the softening
term, the pairing and the combination scale each crossing by 1 + s·a0², its interval widened by
s's own error. Beyond the regression's a_y (the steady gate's 4 m/s²) the a_y³ term extrapolates
and under-reads the secant.
"""

import math
from dataclasses import replace

from app.records import Crossing
from app.units import Z95


def at_zero_ay(crossing: Crossing, s: float, s_se: float) -> Crossing:
    """The crossing as the slope at zero a_y: C2n·(1 + s·a0²), u0 as it would be on linear tyres."""
    a2 = crossing.ay_mps2 * crossing.ay_mps2
    factor = 1.0 + s * a2
    if not (factor > 0 and math.isfinite(factor)):
        return crossing
    c2n = crossing.c2n * factor
    se = math.hypot(crossing.c2n_se * factor, crossing.c2n * a2 * s_se)
    half = crossing.ci95[1] - crossing.c2n
    # the crossing's own interval multiplier (its t quantile), applied to the wider error
    k = half / crossing.c2n_se if crossing.c2n_se > 1e-9 * abs(crossing.c2n) and half > 0 else Z95
    root = math.sqrt(factor)
    low, high = crossing.u0_ci95
    return replace(
        crossing,
        u0_mps=crossing.u0_mps * root,
        u0_ci95=(low * root, high * root),
        c2n=c2n,
        c2n_se=se,
        ci95=(c2n - k * se, c2n + k * se),
        secant_corrected=True,
    )
