"""Line fits and their intervals, including autocorrelated residuals."""

import numpy as np
import pytest

from app.detect.line_fit import fit_line, lag1_autocorrelation


def test_exact_line_and_its_zero() -> None:
    x = np.linspace(100.0, 200.0, 50)
    y = 1.11 - x / (9.81 * 14.99)  # v/r = d − u²/(g·C2n)
    fit = fit_line(x, y)
    assert fit.b == pytest.approx(-1 / (9.81 * 14.99), rel=1e-12)
    assert fit.zero().x0 == pytest.approx(1.11 * 9.81 * 14.99, rel=1e-12)


def test_needs_three_samples_and_varying_x() -> None:
    with pytest.raises(ValueError):
        fit_line(np.array([1.0, 2.0]), np.array([1.0, 2.0]))
    with pytest.raises(ValueError):
        fit_line(np.ones(5), np.arange(5.0))


def test_lag1_autocorrelation_of_ar1() -> None:
    rng = np.random.default_rng(1)
    e = np.zeros(20000)
    for i in range(1, len(e)):
        e[i] = 0.8 * e[i - 1] + rng.normal()
    assert lag1_autocorrelation(e) == pytest.approx(0.8, abs=0.02)


@pytest.mark.parametrize("rho", [0.0, 0.9])
def test_zero_interval_covers_truth_with_autocorrelated_noise(rho: float) -> None:
    """95 % intervals for the crossing cover the truth about 95 % of the time, also when the
    residuals wander (plain OLS would claim far too narrow intervals at ρ = 0.9)."""
    rng = np.random.default_rng(42)
    x = np.linspace(120.0, 210.0, 600)
    truth = 163.3
    covered = 0
    trials = 300
    for _ in range(trials):
        e = np.zeros(len(x))
        noise = rng.normal(0.0, 0.05, len(x))
        for i in range(len(x)):
            e[i] = (rho * e[i - 1] if i else 0.0) + noise[i]
        fit = fit_line(x, -(x - truth) / 150.0 + e)
        lo, hi = fit.zero().ci95
        covered += lo <= truth <= hi
    assert 0.88 <= covered / trials <= 0.99
