"""Crossings paired so that a sensor misalignment and a lag cancel, and both are estimated.

A head yawed left by ψ reads β − ψ: turning left the sign change moves to u² = u0²(1 − ψ·R/d),
turning right (R < 0) the other way. A lag τ between speed and sideslip moves it by τ·u̇: later
sweeping up, earlier sweeping down. So each crossing reads

    C2n_i = C2n · (1 − ψ·R_i/d + 2·τ·u̇_i/u0)

and a weighted least-squares fit over the crossings' signed radius R_i and sweep rate u̇_i gives
C2n with both errors removed — for equal radii and rates, simply the mean of the left/right and
up/down pairs — and ψ and τ themselves. A term enters only when the crossings vary in it.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from app.records import Crossing


@dataclass(frozen=True)
class Paired:
    c2n: float
    se: float
    misalignment_rad: float | None  # sensor head yawed left by this (None: only one direction)
    misalignment_se: float | None
    lag_s: float | None  # sideslip lags speed by this (None: only one sweep direction)
    lag_se: float | None
    cells: dict[str, float]  # "left up" etc.: the cells' weighted mean C2n
    n: int
    birge_ratio: float

    @property
    def cancels(self) -> tuple[str, ...]:
        """What the pairing removed: a misalignment needs both directions, a lag both sweeps."""
        return tuple(
            name
            for name, value in (("misalignment", self.misalignment_rad), ("lag", self.lag_s))
            if value is not None
        )

    @property
    def ci95(self) -> tuple[float, float]:
        return (self.c2n - 1.96 * self.se, self.c2n + 1.96 * self.se)


def pair(crossings: Sequence[Crossing], d_m: float, g: float) -> Paired | None:
    usable = [c for c in crossings if c.c2n_se > 0 and math.isfinite(c.c2n_se) and math.isfinite(c.radius_m)]
    if not usable:
        return None
    y = np.array([c.c2n for c in usable])
    w = np.array([1.0 / c.c2n_se**2 for c in usable])
    columns = [np.ones(len(usable))]
    has_both_directions = len({c.direction for c in usable}) == 2
    rates = np.array([c.sweep_rate_mps2 for c in usable])
    has_both_sweeps = rates.max() > 0.02 and rates.min() < -0.02
    if has_both_directions:
        columns.append(np.array([c.radius_m for c in usable]))
    if has_both_sweeps:
        columns.append(rates)
    x = np.column_stack(columns)
    if len(usable) < x.shape[1]:
        return None
    xtw = x.T * w
    try:
        inverse = np.linalg.inv(xtw @ x)
    except np.linalg.LinAlgError:
        return None
    coef = inverse @ (xtw @ y)
    dof = len(usable) - x.shape[1]
    birge = 1.0
    if dof > 0:
        residual = y - x @ coef
        birge = math.sqrt(float(residual @ (w * residual)) / dof)
    cov = inverse * max(1.0, birge) ** 2
    c2n = float(coef[0])
    u0 = math.sqrt(max(c2n * g * d_m, 0.0))
    misalignment = misalignment_se = lag = lag_se = None
    index = 1
    if has_both_directions:
        misalignment = -float(coef[index]) * d_m / c2n
        misalignment_se = math.sqrt(cov[index, index]) * d_m / c2n
        index += 1
    if has_both_sweeps:
        lag = float(coef[index]) * u0 / (2.0 * c2n)
        lag_se = math.sqrt(cov[index, index]) * u0 / (2.0 * c2n)
    cells: dict[str, float] = {}
    for direction in ("left", "right"):
        for sweep in ("up", "down"):
            members = [c for c in usable if c.direction == direction and c.sweep == sweep]
            if members:
                weights = [1.0 / c.c2n_se**2 for c in members]
                cells[f"{direction} {sweep}"] = sum(
                    wi * c.c2n for wi, c in zip(weights, members, strict=True)
                ) / sum(weights)
    return Paired(
        c2n, math.sqrt(cov[0, 0]), misalignment, misalignment_se, lag, lag_se, cells, len(usable), birge
    )
