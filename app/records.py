"""The record that flows through the pipeline, and the events the detector adds to it.

source → decode → estimate → detect → sinks: the decoder makes a Record from a frame; the
pipeline fills in the estimate, the steady-state verdict and any events. All immutable.

The three made for every filtered frame (Record, Estimate, SteadyState) are named tuples: a
frozen dataclass sets each field through ``object.__setattr__``, several times the cost of
making a tuple, on the per-frame path (``tools/bench.py --only parts``: whole pipeline). The
events are rare and stay dataclasses.
"""

from collections.abc import Mapping
from dataclasses import dataclass
from enum import Enum
from types import MappingProxyType
from typing import Literal, NamedTuple

Direction = Literal["left", "right"]
Sweep = Literal["up", "down"]


class Estimate(NamedTuple):
    """Filtered motion at the sensor's longitudinal position, on the centre line (ISO 8855)."""

    u_mps: float  # longitudinal velocity
    u_dot_mps2: float  # its rate: the speed sweep
    v_mps: float  # lateral velocity at the sensor position d ahead of the rear axle
    v_dot_mps2: float  # its rate: large in transients
    r_radps: float | None  # yaw rate; None while unobserved
    r_dot_radps2: float | None
    sideslip_rad: float  # atan2(v, u): the sign the method watches
    sideslip_sigma_rad: float  # its standard deviation, scaled by the measured innovation
    ay_mps2: float | None  # u·r (steady lateral acceleration), or the measured ay without a yaw rate
    health: float  # mean normalised innovation² per dimension: ≈1 when the noise model fits
    v_meas_mps: float | None = None  # this frame's measured lateral velocity at the sensor position
    sideslip_meas_rad: float | None = None  # this frame's measured sideslip


class Reason(Enum):
    """Why the steady-state gate dropped a sample: what the driver's advice is keyed by."""

    SENSOR = "sensor"  # the sensor status is bad
    SPEED_LOW = "speed low"
    AY_HIGH = "lateral acceleration high"
    STRAIGHT = "driving straight"
    TIGHT = "radius too tight"  # the steer angle beyond the bicycle model's small angles
    SWEEP_FAST = "sweep too fast"
    TRANSIENT = "steering transient"
    SETTLING = "settling"


class SteadyState(NamedTuple):
    steady: bool
    direction: Direction | None
    reasons: tuple[str, ...] = ()  # why not steady, in words, for the dashboard
    causes: tuple[Reason, ...] = ()  # the same reasons as codes, one per word: the advice's key


@dataclass(frozen=True, slots=True)
class SignChange:
    """The filtered sideslip changed sign: a crossing is being fitted."""

    t: float
    direction: Direction | None
    sweep: Sweep
    u_mps: float


@dataclass(frozen=True, slots=True)
class Crossing:
    """A sideslip sign change fitted locally: u0 and C2n = u0²/(g·d) (paper eq. 7)."""

    t: float
    direction: Direction
    sweep: Sweep
    u0_mps: float
    u0_ci95: tuple[float, float]
    c2n: float
    c2n_se: float  # standard error, autocorrelation-corrected
    ci95: tuple[float, float]
    ay_mps2: float  # steady lateral acceleration at the crossing
    radius_m: float  # signed path radius at the crossing (+ left)
    sweep_rate_mps2: float  # mean du/dt over the fitted samples (+ up)
    n_samples: int
    method: Literal["v/r", "beta"]  # fitted quantity against u²
    slope_corrected: bool = False  # the pad's slope (the regression's) taken out before the fit
    # how far a sideslip step δ·sign(κ) (a force that follows the turn) moves the local fit's
    # zero: u0² moves by δ times this [m²/s² per rad] (R/slope of v/r against u²); None for "beta"
    u0sq_per_step: float | None = None
    step_corrected: bool = False  # the regression's turn step taken out (``without_step``)
    slope_lever: "SlopeLever | None" = None  # how any slope moves its local fit ("v/r" only)
    secant_corrected: bool = False  # scaled to zero a_y by the regression's softening (``at_zero_ay``)

    @property
    def u0_kmh(self) -> float:
        return self.u0_mps * 3.6


@dataclass(frozen=True, slots=True)
class SlopeLever:
    """A crossing's local fit of y = v/r against x = u² (y = a + b·(x − x̄)) and what a pad's slope
    adds to it: the sideslip tilt · (sin ψ, cos ψ, a_y·sin ψ, a_y·cos ψ) puts tilt_k·X_k into y, and
    the line fit is linear in y, so the fit with ``tilt`` out is a − Σ Δ_k·a_k, b − Σ Δ_k·b_k with
    Δ the tilt less the one already out (``app/results/crossing_slope.py``)."""

    x_mean: float
    a: float
    b: float
    levers: tuple[tuple[float, float], ...]  # (a_k, b_k): each slope column's own line fit
    tilt: tuple[float, float, float, float]  # the slope already out of the fit (zeros: none)


@dataclass(frozen=True, slots=True)
class CrossingRejected:
    t: float
    direction: Direction | None
    sweep: Sweep
    u_mps: float
    reason: str


Event = SignChange | Crossing | CrossingRejected


NOTHING_REJECTED: Mapping[str, str] = MappingProxyType({})


class Record(NamedTuple):
    """One decoded frame with what the pipeline made of it."""

    t: float
    channel: object
    frame_id: int
    signals: Mapping[str, float]  # role -> value in SI units, only values fit to use
    rejected: Mapping[str, str] = NOTHING_REJECTED  # role -> why it was dropped
    estimate: Estimate | None = None
    steady: SteadyState | None = None
    events: tuple[Event, ...] = ()
