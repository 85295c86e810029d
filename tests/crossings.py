"""Crossings as the detector would report them, for the tests of what the results do with them."""

import math
from typing import Any

from app.records import Crossing, Direction, Sweep
from app.units import Z95

G, D = 9.81, 1.11


def read_crossing(
    x0: float,
    radius: float,
    se: float = 0.02,
    direction: Direction = "left",
    sweep: Sweep = "up",
    rate: float = 0.3,
    **fields: Any,
) -> Crossing:
    """A crossing whose local fit put u² = ``x0`` on a circle of ``radius``: C2n = x0/(g·d) (eq. 7),
    its interval ±1.96·se, a_y = x0/|R|; ``fields`` as the detector adds them."""
    c2n, u0 = x0 / (G * D), math.sqrt(x0)
    return Crossing(
        t=0.0,
        direction=direction,
        sweep=sweep,
        u0_mps=u0,
        u0_ci95=(u0 - 0.05, u0 + 0.05),
        c2n=c2n,
        c2n_se=se,
        ci95=(c2n - Z95 * se, c2n + Z95 * se),
        ay_mps2=x0 / abs(radius),
        radius_m=radius,
        sweep_rate_mps2=rate,
        n_samples=500,
        method="v/r",
        **fields,
    )
