"""Pairing crossings: a misalignment and a lag, put in by the closed form, come back out."""

import math

import pytest

from app import paper
from app.records import Crossing, Direction, Sweep
from app.results.pairing import pair
from tests.crossings import D, G, read_crossing


def crossing(
    c2n: float, direction: Direction, sweep: Sweep, radius: float, rate: float, psi: float, tau: float
) -> Crossing:
    """What a crossing reads: C2n·(1 − ψ·R/d + 2·τ·u̇/u0)."""
    u0 = paper.crossing_speed(c2n, D, G)
    measured = c2n * (1 - psi * radius / D + 2 * tau * rate / u0)
    return read_crossing(measured * G * D, radius, 0.05, direction, sweep, rate)


def four(psi: float, tau: float, c2n: float = 14.0) -> list[Crossing]:
    return [
        crossing(c2n, "left", "up", 80.0, 0.3, psi, tau),
        crossing(c2n, "left", "down", 80.0, -0.3, psi, tau),
        crossing(c2n, "right", "up", -80.0, 0.3, psi, tau),
        crossing(c2n, "right", "down", -80.0, -0.3, psi, tau),
    ]


def test_misalignment_and_lag_cancel_and_are_estimated() -> None:
    paired = pair(four(math.radians(0.3), 0.15), D, G)
    assert paired is not None
    assert paired.c2n == pytest.approx(14.0, rel=1e-9)
    assert paired.misalignment_rad == pytest.approx(math.radians(0.3), rel=1e-9)
    assert paired.lag_s == pytest.approx(0.15, rel=0.02)  # the lag's first-order form
    assert paired.cells["left up"] < 14.0 < paired.cells["right up"]  # the raw per-direction errors


def test_unequal_radii_still_cancel() -> None:
    crossings = [
        crossing(14.0, "left", "up", 60.0, 0.3, 0.004, 0.0),
        crossing(14.0, "right", "up", -120.0, 0.3, 0.004, 0.0),
    ]
    paired = pair(crossings, D, G)
    assert paired is not None and paired.c2n == pytest.approx(14.0, rel=1e-9) and paired.lag_s is None


def test_one_direction_cannot_give_a_misalignment() -> None:
    crossings = [crossing(14.0, "left", s, 80.0, rate, 0.0, 0.1) for s, rate in (("up", 0.3), ("down", -0.3))]
    paired = pair(crossings, D, G)
    assert paired is not None and paired.misalignment_rad is None and paired.lag_s is not None
