"""The rear axle's own C2n: what the simulated car's state says, with no sensor in between.

A tyre's cornering stiffness (a rig's number, the simulator's parameter) is not the car's axle
cornering stiffness that a driving test measures: roll camber, load transfer and a tyre model's own
shifts all change the rear slip per m/s² of lateral acceleration. CommonRoad's multi-body car is
the case in point — its tyre formula adds a camber thrust p_hy3·γ, p_vy3·γ (γ follows the roll,
so the lateral acceleration) and a step sign(γ)·(p_hy1, p_vy1) that flips with the turn; its rear
axle is 8–10 % stiffer in the car than p_ky1 says.

``axle_c2n`` reads the truth a vehicle test should find from the simulated trace itself: the
rear axle's slip angle α2 = −(v − b·r)/u against a_y on the trace's steady cornering, fitted as
α2 = s·sign(a_y) + a_y/(g·C2n) + k·a_y³ over |a_y| of 0.3–4 m/s², the slope at zero a_y.
"""

from collections.abc import Sequence

import numpy as np

from app.sim.drive import DriveTrace
from app.sim.scenarios import Part

AY_RANGE_MPS2 = (0.3, 4.0)  # the steady gate's linear range, bar the smallest a_y (the step)
_SETTLE_S = 4.0  # after a sweep's circle begins: turned in and settled
STEADY_UDOT_MPS2 = 0.6  # |u̇| [m/s²]: the steady gate's limit


def axle_c2n(trace: DriveTrace, parts: Sequence[Part], g: float) -> float | None:
    """The rear axle's C2n at zero a_y from the trace's own state on the session's speed sweeps,
    or None without them (under 1000 samples). Only sweeps reach down to small a_y on one circle:
    track corners (1–4.4 m/s²) leave the cubic too far to extrapolate (the two-track's 14.87 read
    14.43 from them)."""
    t, u, v, r = trace.t, trace.u, trace.v, trace.r
    cornering = np.zeros(len(t), bool)
    for part in parts:
        if part.kind == "sweep":
            cornering |= (t >= part.start_s + _SETTLE_S) & (t <= part.end_s)
    ay = u * r
    low, high = AY_RANGE_MPS2
    keep = (
        cornering
        & (np.abs(np.gradient(u, t)) < STEADY_UDOT_MPS2)
        & (np.abs(ay) >= low)
        & (np.abs(ay) <= high)
    )
    if np.count_nonzero(keep) < 1000:
        return None
    ay = ay[keep]
    alpha2 = -(v[keep] - trace.params.b_m * r[keep]) / u[keep]
    turn = np.sign(ay) if (ay > 0).any() and (ay < 0).any() else np.ones_like(ay)
    coef, *_ = np.linalg.lstsq(np.column_stack([turn, ay, ay**3]), alpha2, rcond=None)
    return float(1.0 / (g * coef[1])) if coef[1] > 0 else None
