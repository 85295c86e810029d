"""What the gap diagnosis fits: the nuisances every real drive has (calibrated first) and the
candidate effects of the vocabulary, each one or two parameters in units people quote, with
physical bounds on both sides and what tells it apart from the others."""

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

from app.config import Config
from app.gap.nominal_model import Mods
from app.paper import G
from app.sim.effects import EffectName

_DEG = math.pi / 180.0


@dataclass(frozen=True)
class Param:
    name: str  # as reported, with its unit in the name
    scale: float  # a typical size, for the optimiser
    to_mods: Callable[[float], dict[str, float]]
    low: float  # physical bounds: a fit that ends on one is not a diagnosis
    high: float
    starts: tuple[float, ...] = (0.0,)  # where the fit may start (the best start wins)
    nominal: float = 0.0  # the value that adds nothing (a nuisance: the config's own)
    prior: float | None = None  # a nuisance's typical spread about its nominal on a test day:
    # it holds the fit where the data cannot tell one nuisance from another
    optional: bool = False  # a nuisance most drives do not have: held at its nominal value unless
    # the drive shows it (its 95 % interval excludes the nominal)

    @property
    def free(self) -> bool:
        return self.low < self.high

    def fixed(self) -> "Param":
        """This parameter held at its nominal value (a fit leaves it there)."""
        return replace(self, low=self.nominal, high=self.nominal, starts=(self.nominal,), prior=None)

    def at_bound(self, value: float) -> bool:
        """The fit ended on a physical bound (not the one that means "no effect")."""
        tolerance = 1e-3 * (self.high - self.low)
        return any(
            abs(value - bound) <= tolerance and bound != self.nominal for bound in (self.low, self.high)
        )


@dataclass(frozen=True)
class Candidate:
    effect: EffectName
    params: tuple[Param, ...]
    action: Callable[[tuple[float, ...]], str]  # what the fitted size means, and what to do


def mods_of(fields: dict[str, float], *more: dict[str, float]) -> Mods:
    """The model's modifications from fits' fields, the later ones overriding the earlier."""
    merged = dict(fields)
    for extra in more:
        merged.update(extra)
    return Mods(**merged)


def nuisances(config: Config) -> tuple[Param, ...]:
    """The calibration: yaw-rate sensor bias, steering-wheel centre offset and effective ratio, the
    nominal C1n and C2n (a handbook or rig value may be 20 % off the car's axle), and a lateral
    force that follows the turn (a pad banked towards the circle's centre, or tyres whose camber
    thrust grows quickly as the body rolls: both axles' slip angles move by a constant that
    changes sign with the turn; several radii tell it from a sensor position error, whose offset
    grows with the curvature), each in the units a test engineer reads them, starting from the
    config's values.

    The gyro's scale is not among them: no signal of a drive tells it from the steering ratio
    (both scale the yaw rate the model is compared with), so a scale error shows as a ratio off
    by as much."""
    ratio = config.vehicle.steering_ratio or 15.0
    c1n, c2n = config.tyres.c1n_per_rad or 13.0, config.tyres.c2n_per_rad or 15.0
    calibrated = (
        Param("yaw_rate_bias_degps", 0.05, lambda x: {"yaw_bias_radps": x * _DEG}, -0.5, 0.5, prior=0.1),
        Param(
            "steering_offset_deg",  # at the steering wheel
            1.0,
            lambda x: {"steer_offset_rad": x * _DEG / ratio},
            -10.0,
            10.0,
            prior=2.0,
        ),
        Param(
            "steering_ratio",
            0.3,
            lambda x: {"ratio_error": x / ratio - 1.0},
            0.85 * ratio,
            1.15 * ratio,
            starts=(ratio,),
            nominal=ratio,
            prior=0.04 * ratio,
        ),
        Param(
            "c1n_per_rad",
            0.05 * c1n,
            lambda x: {"c1n_factor": x / c1n},
            0.5 * c1n,
            2.0 * c1n,
            starts=(c1n,),
            nominal=c1n,
            prior=0.2 * c1n,
        ),
        Param(
            "c2n_per_rad",
            0.05 * c2n,
            lambda x: {"c2n_factor": x / c2n},
            0.5 * c2n,
            2.0 * c2n,
            starts=(c2n,),
            nominal=c2n,
            prior=0.2 * c2n,
        ),
        Param(
            "turn_force_pct",  # of the car's weight, towards the turn's centre
            0.5,
            lambda x: {"turn_force_g": x / 100.0},
            -6.0,
            6.0,
            prior=2.0,
            optional=True,
        ),
    )
    # the camber step is CommonRoad's multi-body model's quirk (its camber thrust switches with
    # the turn); Magic-Formula tyres have none, and on the radii driven it takes up what a sensor
    # position error does: calibrated only where the config asks ([gap] turn_force = true)
    return calibrated if config.gap.turn_force else calibrated[:-1]


def _side(value: float, positive: str, negative: str) -> str:
    return positive if value >= 0 else negative


def _downhill(slope: tuple[float, ...]) -> str:
    """Where a slope falls, from its lateral gravity A·sin ψ + B·cos ψ (ψ the heading, left turns
    positive): the direction D it falls to gives A = −g_s·cos D, B = g_s·sin D."""
    angle = math.degrees(math.atan2(slope[1], -slope[0]))
    if abs(angle) < 0.5 or abs(angle) > 179.5:
        return "straight ahead of the start heading" if abs(angle) < 90 else "behind the start heading"
    return f"{abs(angle):.0f}° {_side(angle, 'left', 'right')} of the start heading"


CANDIDATES: tuple[Candidate, ...] = (
    Candidate(
        "sensor_yaw_misalignment",
        (Param("misalignment_deg", 0.3, lambda x: {"misalignment_rad": x * _DEG}, -3.0, 3.0),),
        lambda v: (
            f"the sensor head is yawed {abs(v[0]):.2f}° to the {_side(v[0], 'left', 'right')}: re-align it, "
            "or keep it and let left/right pairing and the regression's ψ0 cancel it"
        ),
    ),
    Candidate(
        "sensor_position_error",
        (Param("d_error_m", 0.1, lambda x: {"d_error_m": x}, -0.3, 0.3),),
        lambda v: (
            f"the sensor sits {abs(v[0]):.3f} m {_side(v[0], 'further forward', 'further back')} than the "
            "config's d: measure sensor_ahead_of_rear_axle_m again (the crossings' C2n scales with d)"
        ),
    ),
    Candidate(
        "speed_scale_error",
        (Param("speed_scale_pct", 2.0, lambda x: {"speed_scale": x / 100.0}, -10.0, 10.0),),
        lambda v: (
            f"the vehicle speed reads {abs(v[0]):.1f} % {_side(v[0], 'high', 'low')}: check the wheel-speed "
            "calibration (tyre rolling radius); c2n takes its speed from the optical sensor"
        ),
    ),
    Candidate(
        "signal_latency",
        (
            Param(
                "latency_s",
                0.1,
                lambda x: {"latency_s": x},
                0.0,
                0.5,
                starts=(0.0, 0.05, 0.1, 0.2, 0.3),
            ),
        ),
        lambda v: (
            f"the vehicle bus lags the optical sensor by {v[0]:.3f} s: pair up and down sweeps "
            "(the pairing cancels it) and timestamp both buses on one clock"
        ),
    ),
    Candidate(
        "road_cross_slope",
        (
            # a slope of x % pulls the car sideways with x % of g (the paper's, as the reports read it)
            Param("slope_sin_pct", 2.0, lambda x: {"slope_sin_mps2": G * x / 100}, -8.0, 8.0),
            Param("slope_cos_pct", 2.0, lambda x: {"slope_cos_mps2": G * x / 100}, -8.0, 8.0),
        ),
        lambda v: (
            f"the test area slopes {math.hypot(*v):.1f} % (falling towards {_downhill(v)}): drive full "
            "circles both ways, or find a level pad"
        ),
    ),
    Candidate(
        "load_transfer_nonlinearity",
        (
            Param(
                "front_softening_pct_at_3mps2",
                3.0,
                lambda x: {"softening1_per_mps4": x / 100 / 9},
                0.0,
                60.0,
                starts=(0.0, 5.0),
            ),
            Param(
                "rear_softening_pct_at_3mps2",
                3.0,
                lambda x: {"softening2_per_mps4": x / 100 / 9},
                0.0,
                60.0,
                starts=(0.0, 5.0),
            ),
        ),
        lambda v: (
            f"the axles soften with lateral acceleration (front {v[0]:.1f} %, rear {v[1]:.1f} % at 3 m/s²): "
            "c2n reports the linear value at zero a_y; sweep at two radii to separate it"
        ),
    ),
    Candidate(
        "roll_steer",
        (
            Param(
                "rear_steer_deg_per_mps2",
                0.05,
                lambda x: {"roll_steer_rad_per_mps2": x * _DEG},
                -0.3,
                0.3,
            ),
        ),
        lambda v: (
            f"the rear axle steers {abs(v[0]):.3f}° per m/s² {_side(v[0], 'into', 'out of')} the turn with "
            "roll: the axle's C2n (what c2n measures) differs from the tyre's"
        ),
    ),
    Candidate(
        "tyre_ply_steer",
        (Param("ply_steer_deg", 0.2, lambda x: {"ply_rad": x * _DEG}, -1.0, 1.0),),
        lambda v: (
            f"the rear tyres push {_side(v[0], 'left', 'right')} ({abs(v[0]):.2f}° of slip at zero force): "
            "left/right pairing cancels it; swap the tyres on their rims to confirm"
        ),
    ),
)


# Which manoeuvre separates two effects the data could not tell apart.
SEPARATE: dict[frozenset[str], str] = {
    frozenset({"sensor_yaw_misalignment", "tyre_ply_steer"}): (
        "rolling the tyres the other way round on their rims (ply steer turns with them, a yawed "
        "head does not); with the steering centre calibrated the drive cannot tell them apart"
    ),
    frozenset({"sensor_position_error", "roll_steer"}): (
        "constant-radius sweeps at a second, larger radius (d acts per curvature, roll steer per "
        "lateral acceleration)"
    ),
    frozenset({"sensor_position_error", "load_transfer_nonlinearity"}): (
        "constant-radius sweeps at a second radius up to 4 m/s²"
    ),
    frozenset({"roll_steer", "load_transfer_nonlinearity"}): (
        "sweeps up to 4 m/s² at two radii (softening grows with a_y², roll steer with a_y)"
    ),
    frozenset({"signal_latency", "speed_scale_error"}): "step steers at two speeds",
    frozenset({"road_cross_slope", "sensor_yaw_misalignment"}): (
        "full circles in both directions (a slope turns with the heading, a yawed head does not)"
    ),
}

# Which calibrated nuisance has an effect's signature: the drive alone cannot tell them apart.
NUISANCE_TWINS: dict[str, str] = {
    "roll_steer": "c2n_per_rad",  # in steady state a rear steer ∝ a_y is a change of the axle's C2n
    "tyre_ply_steer": "steering_offset_deg",  # the car crabs and the driver steers it out
}
# Effects the calibration absorbs whole: a drive the calibrated model explains may still carry
# them, so a verdict of "none" names them as confounded, with what would tell them apart.
HIDDEN_BY_CALIBRATION: dict[str, str] = {
    "roll_steer": (
        "a C2n from a tyre rig or the axle's kinematics-and-compliance data (in steady state a rear "
        "steer ∝ a_y is a change of the axle's C2n, which the drive calibrates)"
    ),
}


# A nuisance that imitates an effect on a drive without the manoeuvre that tells them apart: the
# effect is fitted with the nuisance held at its nominal value and named only where it explains
# the drive better than the calibrated nuisance does.
RIVAL_NUISANCE: dict[EffectName, str] = {
    # a force that follows the turn moves the sideslip by a constant per turn direction, a sensor
    # position error by d·κ: on one radius they are the same; radii apart tell them apart
    "sensor_position_error": "turn_force_pct",
    # softening moves it by a term ∝ a_y³, which over a sweep a constant per direction and a
    # calibrated C2n take much of; sweeps to 4 m/s² tell them apart
    "load_transfer_nonlinearity": "turn_force_pct",
}
# What tells each such effect apart from its rival, said where a verdict of "none" rests on a
# calibrated rival: the drive showed the nuisance, and the effect could be inside it.
HIDDEN_BY_RIVAL: dict[str, str] = {
    "sensor_position_error": (
        "d measured with a tape, or radii further apart at the same a_y (a sensor off by Δd moves the "
        "sideslip by Δd·κ, a force that follows the turn by as much at every radius)"
    ),
    "load_transfer_nonlinearity": (
        "sweeps to 4 m/s² and beyond (softening grows with a_y³, a force that follows the turn does not)"
    ),
}


def separating_manoeuvre(a: str, b: str) -> str:
    return SEPARATE.get(
        frozenset({a, b}),
        "the standard session in both directions at two radii, with step steers and a straight run",
    )
