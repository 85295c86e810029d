"""One line per event, the same on a terminal and in a pipe (plain text there)."""

import math

from app.pipeline import SessionState
from app.records import Crossing, CrossingRejected


def crossing_line(c: Crossing, t0: float) -> str:
    lo, hi = c.ci95
    return (
        f"{c.t - t0:8.1f} s  {c.direction:<5} {c.sweep:<4}  "
        f"u0 {c.u0_mps:6.3f} m/s = {c.u0_kmh:6.2f} km/h  a_y {c.ay_mps2:4.2f} m/s²  "
        f"C2n {c.c2n:6.3f} [{lo:.3f}, {hi:.3f}] 1/rad"
    )


def rejected_line(r: CrossingRejected, t0: float) -> str:
    direction = r.direction or "?"
    return (
        f"{r.t - t0:8.1f} s  {direction:<5} {r.sweep:<4}  "
        f"sign change near {r.u_mps * 3.6:.1f} km/h not used: {r.reason}"
    )


def result_line(state: SessionState, g: float, d_m: float) -> str:
    """The run's result: the headline C2n and how it was found, and the crossings beside it."""
    headline = state.headline
    if headline is None:
        return "C2n: no result (no usable sideslip sign change or steady samples)"
    lo, hi = headline.ci95
    u0 = math.sqrt(headline.c2n * g * d_m)
    how = headline.method
    if state.regression is not None:
        how = f"regression over {state.regression.n_samples:,} steady samples"
        if state.regression.model == "softening":
            how += ", extrapolated to zero a_y"
    text = (
        f"C2n = {headline.c2n:.3f} 1/rad [{lo:.3f}, {hi:.3f}] (95 %, {how}); "
        f"u0 = {u0:.3f} m/s = {u0 * 3.6:.2f} km/h"
    )
    crossings = state.paired or state.combined
    if crossings is not None and headline.method == "regression":
        clo, chi = crossings.ci95
        paired = " paired" if state.paired is not None else ""
        text += f"; {crossings.n}{paired} crossings: {crossings.c2n:.3f} [{clo:.3f}, {chi:.3f}]"
    return text
