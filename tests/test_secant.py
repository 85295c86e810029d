"""A crossing's C2n at zero a_y from the regression's softening term, in closed form."""

import math

import pytest

from app import paper
from app.records import Crossing
from app.results.secant import at_zero_ay
from app.units import Z95
from tests.crossings import D, G, read_crossing


def crossing_on_softening_tyres(c2n: float, s: float, radius: float) -> Crossing:
    """The crossing eq. 7 reads where α2 = a_y/(g·C2n)·(1 + s·a_y²): d = u0²/(g·C2n)·(1 + s·a0²)
    with a0 = u0²/R, solved for u0² by fixed point; it reads the secant C2n/(1 + s·a0²)."""
    x = paper.crossing_speed(c2n, D, G) ** 2
    for _ in range(200):
        x = G * c2n * D / (1.0 + s * (x / radius) ** 2)
    return read_crossing(x, radius)


def test_a_crossing_on_softening_tyres_reads_the_secant_and_is_scaled_to_zero_a_y() -> None:
    c2n, s = 14.0, 0.002
    read = crossing_on_softening_tyres(c2n, s, 50.0)
    a0 = read.ay_mps2
    assert read.c2n == pytest.approx(c2n / (1.0 + s * a0 * a0), rel=1e-12)
    assert read.c2n < 0.985 * c2n  # 1.8 % low at 3 m/s²
    out = at_zero_ay(read, s, 0.0004)
    assert out.secant_corrected and not read.secant_corrected
    assert out.c2n == pytest.approx(c2n, rel=1e-12)
    assert out.u0_mps == pytest.approx(paper.crossing_speed(c2n, D, G), rel=1e-12)
    factor = 1.0 + s * a0 * a0
    assert out.c2n_se == pytest.approx(math.hypot(0.02 * factor, read.c2n * a0 * a0 * 0.0004), rel=1e-12)
    assert out.ci95[1] - out.c2n == pytest.approx(Z95 * out.c2n_se, rel=1e-9)


def test_without_softening_a_crossing_is_left_as_read() -> None:
    read = crossing_on_softening_tyres(14.0, 0.0, 50.0)
    out = at_zero_ay(read, 0.0, 0.0)
    assert (out.c2n, out.c2n_se, out.u0_mps) == (read.c2n, read.c2n_se, read.u0_mps)
