"""A crossing with the regression's turn step taken out.

A force that follows the turn's direction but not its size (a tyre formula's camber step, friction
in the suspension) adds a step δ·sign(κ) to the sideslip at every speed, so each crossing's zero
moves: on a circle of radius R its local fit of v/r against u² gains δ·R, and u0² moves by
δ·R/slope (``Crossing.u0sq_per_step``). A crossing cannot see δ (it is one radius, one speed);
the regression, over radii and directions, can (``RegressionFit.turn_force.step_rad``). So once the
regression has found a step, every crossing — also those found before it was known — is moved
back by it, its interval widened by the step's own error. On CommonRoad's car the step is
2–3 % of the rear axle's weight: 0.05–0.2 m of the sensor's d at the standard session's radii.
"""

import math
from dataclasses import replace

from app.records import Crossing
from app.units import Z95


def without_step(crossing: Crossing, step_rad: float, step_se_rad: float, d_m: float, g: float) -> Crossing:
    """The crossing as it would read without the sideslip step ``step_rad``·sign(κ) (a "beta"
    crossing, which has no lever, is returned as it is)."""
    per_step = crossing.u0sq_per_step
    if per_step is None or not math.isfinite(per_step):
        return crossing
    scale = 1.0 / (g * d_m)
    x0 = crossing.c2n / scale + step_rad * per_step
    if not x0 > 0:
        return crossing
    c2n = x0 * scale
    se = math.hypot(crossing.c2n_se, step_se_rad * per_step * scale)
    # the crossing's own interval multiplier (its t quantile), applied to the wider error
    half = crossing.ci95[1] - crossing.c2n
    k = half / crossing.c2n_se if crossing.c2n_se > 1e-9 * abs(crossing.c2n) and half > 0 else Z95
    u0 = math.sqrt(x0)
    du = k * se / scale / (2.0 * u0)  # u0's interval from u0²'s, to first order
    return replace(
        crossing,
        u0_mps=u0,
        u0_ci95=(max(u0 - du, 0.0), u0 + du),
        c2n=c2n,
        c2n_se=se,
        ci95=(c2n - k * se, c2n + k * se),
        step_corrected=True,
    )
