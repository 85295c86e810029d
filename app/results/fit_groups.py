"""A regression's result in typed groups, one per effect: ``RegressionFit`` keeps C2n at its top
level and stores the rest here — the samples, d, ψ0, the model chosen, the softening, the slope,
the turn force, the yaw rate's bias and the term holding C2n open; a group is None where the fit
has no such effect to report. The result file flattens them again (app/sinks/summary.py)."""

import math
from dataclasses import dataclass
from typing import Literal


@dataclass(frozen=True)
class FitSamples:
    """The steady samples the fit rests on: how many, and the ranges they span."""

    count: int
    blocks: int  # the Newey–West time blocks they fill
    ay_range_mps2: tuple[float, float]  # |a_y| = |u·r|
    curvature_range_per_m: tuple[float, float]  # |κ| = |r/u|: 1/κ are the radii driven
    speed_range_mps: tuple[float, float] = (math.nan, math.nan)  # u
    duration_s: float = 0.0  # of driving the samples cover
    logs: int = 1  # drives pooled, each with its own ψ0 (Psi0Result: the first one's)
    transient_terms: bool = False  # the yaw inertia's and the speed's load transfer's terms kept
    tight_terms: tuple[str, ...] = ()  # on a small pad, TIGHT_TERMS fitted: "ay_u_dot", "k2_ay"


@dataclass(frozen=True)
class DResult:
    """The sensor's distance d ahead of the rear axle, fitted or held at the tape's."""

    m: float
    ci95_m: tuple[float, float]  # a point where held
    held: bool = False  # the tape's value held (the samples could not place d)
    held_tight: bool = False  # held because most samples turned tighter than TIGHT_WHEELBASES
    per_tape_cm_pct: float | None = None  # where held: how far 1 cm of d moves C2n, %
    free_m: float | None = None  # held, or under the marginal fit's tape prior: the top of d's
    # interval as the samples alone place it (marginal: where they place it as well as the tape);
    # below zero, the sensor is behind the axle: a role is the wrong way round
    information: float | None = None  # marginal, with a tape: what the drive tells of d, as its
    # information over the tape's (the posterior's precision less the prior's, over the prior's);
    # under 1 the tape places d better


@dataclass(frozen=True)
class Psi0Result:
    """The sensor head's yaw ψ0 on the car (pooled drives: the first one's)."""

    rad: float
    ci95_rad: tuple[float, float]


@dataclass(frozen=True)
class ModelFit:
    """C2n under one of the two models, with its own 95 % interval (None: no stiffness)."""

    c2n: float
    ci95: tuple[float, float] | None
    data_ci95: tuple[float, float] | None = None  # without the sensors' scales (None: ci95)


@dataclass(frozen=True)
class ModelChoice:
    """Linear tyres or softening ones: the model chosen, the evidence, and both models' C2n."""

    chosen: Literal["linear", "softening"]
    softening_t: float  # t statistic of the a_y³ term (|t| > threshold keeps it)
    linear: ModelFit
    softening: ModelFit | None  # a campaign decides softening over a tyre set's sessions together
    # (app/campaign/meta_analysis.py) and then needs the model its own fit did not choose
    resolved: bool = True  # False: the data cannot tell linear tyres from softening ones
    hidden_pct: float = 0.0  # the softening, % of C2n, that could hide in the data (2 se)


@dataclass(frozen=True)
class SofteningResult:
    """The tyres' softening with slip, where the a_y³ term is kept."""

    per_mps2_2: float  # s in α2 = a_y/(g·C2n)·(1 + s·a_y²)
    se_per_mps2_2: float
    # how far C2n reads high, %, with the series' next term (r·s²·a_y⁴, r = 1 at the least: a
    # stiffness falling with load) left out; 0 where the model has it ([priors] softening_ratio)
    next_term_pct: float = 0.0


@dataclass(frozen=True)
class SlopeResult:
    """The test pad's slope, where the headings let it be fitted."""

    pct: float
    ci95_pct: tuple[float, float]
    downhill_deg: float  # where it falls, from the start heading, left positive
    tilt: tuple[float, float, float, float] | None  # where the slope's terms were kept in the fit:
    # the sideslip it adds is tilt · (sin ψ, cos ψ, a_y·sin ψ, a_y·cos ψ) [rad]


@dataclass(frozen=True)
class TurnForceResult:
    """A rear force that follows the turn's direction, not its size, where one was found."""

    pct: float  # % of the axle's weight, + towards the turn's inside
    ci95_pct: tuple[float, float]
    step_rad: float  # the sideslip step δ·sign(κ) it makes
    step_se_rad: float


@dataclass(frozen=True)
class YawBiasResult:
    """The yaw rate's bias the quasi-steady samples show (it reads this much high), where fitted."""

    degps: float
    ci95_degps: tuple[float, float]


@dataclass(frozen=True)
class HeldOpen:
    """The marginal fit's term holding most of C2n's variance, which the drive cannot part from a_y."""

    by: str | None
    share: float  # of C2n's variance


@dataclass(frozen=True)
class RegressionFit:
    """C2n with its interval, and the rest of the fit in groups (above): one
    per effect, None where the fit has no such effect to report."""

    c2n: float
    c2n_se: float
    c2n_ci95: tuple[float, float]
    samples: FitSamples
    d: DResult
    psi0: Psi0Result | None  # None when the data cannot tell ψ0 from d (one direction, one radius)
    models: ModelChoice
    softening: SofteningResult | None = None  # where the a_y³ term is kept
    slope: SlopeResult | None = None  # where the headings let it be fitted
    turn_force: TurnForceResult | None = None  # where one was found
    yaw_bias: YawBiasResult | None = None  # where it was fitted
    held_open: HeldOpen | None = None  # the marginal fit's
    scale_se: float = 0.0  # C2n's relative error from the sensors' scales, in its intervals
    c2n_data_ci95: tuple[float, float] | None = None  # without the sensors' scales (None: c2n_ci95)
    estimator: Literal["cascade", "marginal"] = "cascade"  # terms chosen by tests, or all with priors
