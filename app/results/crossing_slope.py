"""A crossing with the pad's slope, as the regression last found it, taken out.

The detector takes the regression's slope out of each crossing's samples before the local fit —
the slope as known then. The first circles' crossings come before the regression has seen the
slope (it needs both directions and the headings), and each later one is corrected by the fit of
its moment. The local fit is linear in y = v/r, and the slope's share of y is linear in the four
tilt terms, so each crossing keeps its fit and each slope term's own line fit over the same
samples (``SlopeLever``); the pairing moves every crossing to the last slope found: the first
circles' too, and on a level pad a crossing that a passing fit's heading-borne misfit corrected
comes back to none.
"""

import math
from dataclasses import replace

from app.records import Crossing


def with_tilt(crossing: Crossing, tilt: tuple[float, float, float, float], d_m: float, g: float) -> Crossing:
    """The crossing as its local fit reads with ``tilt`` out instead of the one out when it was
    fitted (a crossing without a lever, or whose moved fit has no crossing, is returned as it is).
    Its error is the fit's: the slope's own is second order at the crossing."""
    lever = crossing.slope_lever
    if lever is None:
        return crossing
    delta = [new - old for new, old in zip(tilt, lever.tilt, strict=True)]
    if not any(delta):
        return crossing
    a = lever.a - sum(k * a_k for k, (a_k, _) in zip(delta, lever.levers, strict=True))
    b = lever.b - sum(k * b_k for k, (_, b_k) in zip(delta, lever.levers, strict=True))
    if not b < 0:  # v/r must fall with speed
        return crossing
    x0 = lever.x_mean - a / b
    if not x0 > 0:
        return crossing
    c2n = x0 / (g * d_m)
    shift = c2n - crossing.c2n
    u0 = math.sqrt(x0)
    du = u0 - crossing.u0_mps
    low, high = crossing.u0_ci95
    return replace(
        crossing,
        u0_mps=u0,
        u0_ci95=(max(low + du, 0.0), high + du),
        c2n=c2n,
        ci95=(crossing.ci95[0] + shift, crossing.ci95[1] + shift),
        slope_corrected=any(tilt),
        slope_lever=replace(lever, a=a, b=b, tilt=tilt),
    )
