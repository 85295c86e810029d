"""Straight-line fits with intervals that respect autocorrelated samples (pure numpy).

Samples at 50–250 Hz are not independent: a slow wander of the residual makes plain OLS
intervals far too narrow. The covariance is inflated by the lag-1 autocorrelation ρ of the
residuals, (1 + ρ)/(1 − ρ), the large-sample factor for AR(1) errors on a smooth regressor,
and the t quantile uses the matching effective sample size.
"""

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class LineFit:
    """y = a + b·(x − x_mean), with a and b uncorrelated by construction."""

    x_mean: float
    a: float
    b: float
    var_a: float
    var_b: float
    n: int
    n_eff: float
    residual_sigma: float
    rho: float

    def zero(self) -> "Zero":
        """Where the line crosses y = 0, with its standard error (delta method)."""
        x0 = self.x_mean - self.a / self.b
        var = self.var_a / self.b**2 + self.a**2 * self.var_b / self.b**4
        return Zero(x0, math.sqrt(var), self.t95)

    @property
    def slope_t(self) -> float:
        return abs(self.b) / math.sqrt(self.var_b) if self.var_b > 0 else math.inf

    @property
    def t95(self) -> float:
        from scipy.special import stdtrit  # the t quantile; imported at the first fit, not at the start

        return float(stdtrit(max(self.n_eff - 2.0, 1.0), 0.975))

    def at(self, x: float) -> float:
        return self.a + self.b * (x - self.x_mean)


@dataclass(frozen=True)
class Zero:
    x0: float
    se: float
    t95: float

    @property
    def ci95(self) -> tuple[float, float]:
        return (self.x0 - self.t95 * self.se, self.x0 + self.t95 * self.se)


def lag1_autocorrelation(residuals: np.ndarray) -> float:
    if len(residuals) < 3:
        return 0.0
    denominator = float(residuals @ residuals)
    if denominator == 0:
        return 0.0
    return float(residuals[1:] @ residuals[:-1]) / denominator


def fit_line(x: np.ndarray, y: np.ndarray) -> LineFit:
    """OLS of y on x (samples in time order), covariance inflated for AR(1) residuals."""
    n = len(x)
    if n < 3:
        raise ValueError("a line fit needs at least 3 samples")
    x_mean = float(np.mean(x))
    dx = x - x_mean
    sxx = float(dx @ dx)
    if sxx == 0:
        raise ValueError("a line fit needs x to vary")
    a = float(np.mean(y))
    b = float(dx @ (y - a)) / sxx
    residuals = y - a - b * dx
    sigma2 = float(residuals @ residuals) / (n - 2)
    rho = min(max(lag1_autocorrelation(residuals), 0.0), 0.99)
    inflation = (1.0 + rho) / (1.0 - rho)
    return LineFit(
        x_mean=x_mean,
        a=a,
        b=b,
        var_a=sigma2 / n * inflation,
        var_b=sigma2 / sxx * inflation,
        n=n,
        n_eff=n / inflation,
        residual_sigma=math.sqrt(sigma2),
        rho=rho,
    )
