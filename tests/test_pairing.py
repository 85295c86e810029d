"""Pairing crossings: a misalignment and a lag, put in by the closed form, come back out."""

import math

import pytest

from app import paper
from app.records import Crossing, Direction, Sweep
from app.results.pairing import pair
from app.units import Z95
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
    # one sweep direction: the lag is under its prior alone (not reported), and the head's prior
    # shrinks ψ by a few millionths of itself, which the radii's mean carries into C2n
    assert paired is not None and paired.c2n == pytest.approx(14.0, rel=1e-5) and paired.lag_s is None
    assert paired.misalignment_rad == pytest.approx(0.004, rel=1e-5)


def test_one_direction_cannot_give_a_misalignment() -> None:
    crossings = [crossing(14.0, "left", s, 80.0, rate, 0.0, 0.1) for s, rate in (("up", 0.3), ("down", -0.3))]
    paired = pair(crossings, D, G)
    assert paired is not None and paired.misalignment_rad is None and paired.lag_s is not None


def test_one_direction_on_one_radius_leaves_the_misalignment_to_its_prior() -> None:
    """Left circles of one radius: ψ·R/d and C2n move every crossing alike, so nothing in them tells
    a yawed head from the tyres. The head's prior (±1° at 95 %) stays in C2n's interval: at
    R/d = 73 that is ±0.64 of C2n at 1σ, and the interval holds the truth the crossings miss by 29 %."""
    psi = 0.004
    crossings = [crossing(14.0, "left", s, 80.0, rate, psi, 0.0) for s, rate in (("up", 0.3), ("down", -0.3))]
    paired = pair(crossings, D, G)
    assert paired is not None and paired.misalignment_rad is None
    assert paired.c2n == pytest.approx(14.0 * (1 - psi * 80.0 / D), rel=1e-6)  # the prior's mean: no yaw
    assert paired.se == pytest.approx(paired.c2n * math.radians(0.5) * 80.0 / D, rel=0.02)
    assert paired.ci95[0] <= 14.0 <= paired.ci95[1]


def test_one_direction_on_two_radii_measures_the_misalignment() -> None:
    """Left circles on 80 and 120 m: the crossings' error grows with the radius (ψ·R/d), which
    places ψ apart from C2n (CommonRoad's sweeps, four left crossings on 112 and 157 m, read 39–55 %
    low with ψ left out of the pairing)."""
    crossings = [crossing(14.0, "left", "up", radius, 0.3, 0.004, 0.0) for radius in (80.0, 120.0)]
    paired = pair(crossings, D, G)
    assert paired is not None and paired.misalignment_rad == pytest.approx(0.004, rel=1e-3)
    assert paired.c2n == pytest.approx(14.0, rel=2e-4) and paired.ci95[0] <= 14.0 <= paired.ci95[1]


def test_a_crossings_interval_is_every_c2n_that_reads_it_within_its_share() -> None:
    """A crossing reads C2n·(1 + ε), its errors shares of C2n (combine.ratio_ci95): the interval
    is every C2n within Z95·se/ĉ of the reading, [ĉ/(1 + Z95·r), ĉ/(1 − Z95·r)]. On a 40 m circle
    turning one way, with the head's ±0.5° prior, that reaches higher above ĉ than below it."""
    paired = pair([crossing(14.0, "left", "up", 40.0, 0.3, 0.0, 0.0)], D, G)
    assert paired is not None and paired.bounded
    share = Z95 * paired.se / paired.c2n
    low, high = paired.ci95
    assert (low, high) == pytest.approx((paired.c2n / (1 + share), paired.c2n / (1 - share)), rel=1e-12)
    for end in (low, high):  # both ends read ĉ at exactly their own share
        assert abs(paired.c2n - end) == pytest.approx(share * end, rel=1e-9)
    assert high > paired.c2n + Z95 * paired.se and low > paired.c2n - Z95 * paired.se


def test_one_crossing_on_a_wide_circle_does_not_bound_c2n() -> None:
    """On 150 m (R/d = 135) a head yawed by its prior's 0.5° moves the crossing by 1.2 of C2n:
    no reading rules out a C2n far above it. ĉ ± Z95·se read below zero (−4.4 … 34.2 once)."""
    paired = pair([crossing(14.0, "left", "up", 150.0, 0.3, 0.0, 0.0)], D, G)
    assert paired is not None and Z95 * paired.se > paired.c2n
    assert not paired.bounded
    assert paired.ci95 == (pytest.approx(paired.c2n / (1 + Z95 * paired.se / paired.c2n)), math.inf)
