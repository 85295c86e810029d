"""One line per event, the same on a terminal and in a pipe (plain text there)."""

import math

from app.combine import Combined
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


def result_line(combined: Combined | None, g: float, d_m: float) -> str:
    if combined is None:
        return "C2n: no result (no usable sideslip sign change)"
    lo, hi = combined.ci95
    u0 = math.sqrt(combined.c2n * g * d_m)
    crossings = "crossing" if combined.n == 1 else "crossings"
    return (
        f"C2n = {combined.c2n:.3f} 1/rad [{lo:.3f}, {hi:.3f}] (95 %) from {combined.n} {crossings}; "
        f"u0 = {u0:.3f} m/s = {u0 * 3.6:.2f} km/h at d = {d_m:g} m"
    )
