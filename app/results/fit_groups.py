"""A regression's result in typed groups: the slope, the softening, the turn force, d.

``RegressionFit`` keeps its flat fields (the result file's keys); these are views of them, one
group per effect, None where the fit has no such effect to report."""

from dataclasses import dataclass


@dataclass(frozen=True)
class SlopeResult:
    pct: float  # the pad's slope
    ci95_pct: tuple[float, float]
    downhill_deg: float  # where it falls, from the start heading, left positive
    tilt: (
        tuple[float, float, float, float] | None
    )  # the sideslip it adds per (sin ψ, cos ψ, a_y·sin ψ, a_y·cos ψ)


@dataclass(frozen=True)
class SofteningResult:
    per_mps2_2: float  # s in α2 = a_y/(g·C2n)·(1 + s·a_y²)
    se_per_mps2_2: float | None
    t: float  # the a_y³ term's t statistic


@dataclass(frozen=True)
class TurnForceResult:
    pct: float  # % of the axle's weight, + towards the turn's inside
    ci95_pct: tuple[float, float] | None
    step_rad: float | None  # the sideslip step δ·sign(κ) it makes
    step_se_rad: float | None


@dataclass(frozen=True)
class DResult:
    m: float  # the sensor's distance ahead of the rear axle
    ci95: tuple[float, float]
    held: bool  # the tape's value held (the fit could not place d)
    per_tape_cm_pct: float | None  # where held: how far 1 cm of d moves C2n, %
