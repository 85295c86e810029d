"""The candidate effects (DESIGN §6 vocabulary): each is one or two parameters of ``Mods``, in
units people quote, with what tells it apart from the others."""

import math
from collections.abc import Callable
from dataclasses import dataclass

from app.gap.model import Mods

_DEG = math.pi / 180.0


@dataclass(frozen=True)
class Param:
    name: str  # as reported, with its unit in the name
    scale: float  # a typical size, for the optimiser
    to_mods: Callable[[float], dict[str, float]]
    low: float = -math.inf  # physical bound (a latency cannot be negative)
    starts: tuple[float, ...] = (0.0,)  # where the fit may start (the best start wins)


@dataclass(frozen=True)
class Candidate:
    effect: str
    params: tuple[Param, ...]

    def mods(self, values: tuple[float, ...]) -> Mods:
        fields: dict[str, float] = {}
        for param, value in zip(self.params, values, strict=True):
            fields.update(param.to_mods(value))
        return Mods(**fields)


CANDIDATES: tuple[Candidate, ...] = (
    Candidate(
        "sensor_yaw_misalignment",
        (Param("misalignment_deg", 0.3, lambda x: {"misalignment_rad": x * _DEG}),),
    ),
    Candidate("sensor_position_error", (Param("d_error_m", 0.1, lambda x: {"d_error_m": x}),)),
    Candidate("speed_scale_error", (Param("speed_scale_pct", 2.0, lambda x: {"speed_scale": x / 100}),)),
    Candidate(
        "signal_latency",
        (Param("latency_s", 0.1, lambda x: {"latency_s": x}, low=0.0, starts=(0.0, 0.05, 0.1, 0.2, 0.3)),),
    ),
    Candidate(
        "road_cross_slope",
        (
            Param("slope_sin_pct", 2.0, lambda x: {"slope_sin_mps2": 9.81 * x / 100}),
            Param("slope_cos_pct", 2.0, lambda x: {"slope_cos_mps2": 9.81 * x / 100}),
        ),
    ),
    Candidate(
        "load_transfer_nonlinearity",
        (
            Param("front_softening_pct_at_3mps2", 3.0, lambda x: {"softening1_per_mps4": x / 100 / 9}),
            Param("rear_softening_pct_at_3mps2", 3.0, lambda x: {"softening2_per_mps4": x / 100 / 9}),
        ),
    ),
    Candidate(
        "roll_steer",
        (Param("rear_steer_deg_per_mps2", 0.05, lambda x: {"roll_steer_rad_per_mps2": x * _DEG}),),
    ),
    Candidate("tyre_ply_steer", (Param("ply_steer_deg", 0.2, lambda x: {"ply_rad": x * _DEG}),)),
)

EFFECTS = ("none", *(c.effect for c in CANDIDATES))

# Which manoeuvre separates two effects the data could not tell apart.
SEPARATE: dict[frozenset[str], str] = {
    frozenset({"sensor_yaw_misalignment", "tyre_ply_steer"}): (
        "a straight run at constant speed with the steering angle logged (ply steer needs steering "
        "to go straight, a yawed head does not)"
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


def separating_manoeuvre(a: str, b: str) -> str:
    return SEPARATE.get(
        frozenset({a, b}),
        "the standard session in both directions at two radii, with step steers and a straight run",
    )
