"""The unmodelled effects c2n gap names (its vocabulary) as parameters of the higher-fidelity simulator.

Each effect has one size in one unit, a range that packs draw from (uniformly in magnitude, with a
random sign where both signs are physical), and is applied either to the sensors (SensorSetup) or
to the car and road (TwoTrackParams). ``none`` switches every one of them off; sensor noise and
quantisation stay on in every case.

| effect                     | size: unit, pack range      | + means                                 |
|----------------------------|-----------------------------|-----------------------------------------|
| sensor_yaw_misalignment    | ψ: deg, ±0.2–1.0            | sensor head yawed left (it reads β − ψ) |
| sensor_position_error      | Δd: m, ±0.05–0.25           | sensor further forward than the config  |
| speed_scale_error          | s: %, ±1–4                  | vehicle and wheel speeds read (1+s) high |
| signal_latency             | τ: s, 0.05–0.3              | vehicle bus τ late vs the optical sensor |
| road_cross_slope           | grade: %, ±1–4              | road falls to the right of the start heading |
| load_transfer_nonlinearity | k: 1, 0.33–1.31             | stiffness falls with load transfer (k ≥ 0) |
| roll_steer                 | ε: deg/deg, ±0.05–0.25      | rear steers into the turn: roll understeer |
| tyre_ply_steer             | α_ply: deg, ±0.1–0.5 (rear) | rear tyres push left: the car crabs left |
"""

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Literal

from app.errors import C2nError

if TYPE_CHECKING:  # annotations only: `c2n simulate --help` lists the effects without the simulator
    import numpy as np

    from app.sim.sensors import SensorSetup
    from app.sim.two_track import TwoTrackParams


# the vocabulary of unmodelled effects (DESIGN's), "none" among them: ``EFFECTS`` holds each one's spec
EffectName = Literal[
    "none",
    "sensor_yaw_misalignment",
    "sensor_position_error",
    "speed_scale_error",
    "signal_latency",
    "road_cross_slope",
    "load_transfer_nonlinearity",
    "roll_steer",
    "tyre_ply_steer",
]


@dataclass(frozen=True)
class EffectSpec:
    name: "EffectName"
    unit: str
    low: float  # pack range of the magnitude
    high: float
    signed: bool  # both signs physical: packs draw either
    applies_to: Literal["nothing", "sensor", "vehicle", "road"]
    physics: str
    positive: str  # what a positive size means

    @property
    def typical(self) -> float:
        """Middle of the range: the size when none is given."""
        return 0.5 * (self.low + self.high)


EFFECTS: dict[EffectName, EffectSpec] = {
    spec.name: spec
    for spec in (
        EffectSpec("none", "", 0.0, 0.0, False, "nothing", "every effect off", ""),
        EffectSpec(
            "sensor_yaw_misalignment",
            "deg",
            0.2,
            1.0,
            True,
            "sensor",
            "the optical head is yawed on its mount: it sees the velocity turned by −ψ, a constant "
            "sideslip offset of the same sign in left and right turns",
            "head turned left (the sensor's sideslip reads ψ too low)",
        ),
        EffectSpec(
            "sensor_position_error",
            "m",
            0.05,
            0.25,
            True,
            "sensor",
            "the sensor's true distance ahead of the rear axle is config d + Δd (a tape error or a "
            "head moved since the config was written); the config keeps its d",
            "the sensor sits further forward than the config says",
        ),
        EffectSpec(
            "speed_scale_error",
            "%",
            1.0,
            4.0,
            True,
            "sensor",
            "the wheel-speed-based vehicle speed and the wheel speeds read (1 + s) times the true "
            "speed (rolling radius differs from the nominal one); the optical sensor is right",
            "vehicle speed reads high",
        ),
        EffectSpec(
            "signal_latency",
            "s",
            0.05,
            0.3,
            False,
            "sensor",
            "every vehicle-bus signal (yaw rate, lateral and longitudinal acceleration, speed, "
            "steering, wheel speeds) carries the value of τ seconds earlier; the optical sensor "
            "and its own gyro are on time",
            "the vehicle bus lags the optical sensor",
        ),
        EffectSpec(
            "road_cross_slope",
            "%",
            1.0,
            4.0,
            True,
            "road",
            "the test area is a plane tilted by θ (grade tan θ) towards a fixed world direction: "
            "g·sin θ acts in the road plane, turning with the heading (once per lap on a circle), "
            "and the accelerometer reads it",
            "the road falls to the right of the car's heading at the start of the session",
        ),
        EffectSpec(
            "load_transfer_nonlinearity",
            "1",
            0.33,
            1.31,
            False,
            "vehicle",
            "tyre load sensitivity k in C(F_z) = c·F_z·(1 − k·(F_z − F_z0)/F_z0): lateral load "
            "transfer lowers the axle stiffness by k·(ΔF_z/F_z0)²; the range gives 2–8 % less "
            "C2n at 3 m/s² on the default car (stronger sensitivity or a higher CG)",
            "stiffness falls with load transfer",
        ),
        EffectSpec(
            "roll_steer",
            "deg/deg",
            0.05,
            0.25,
            True,
            "vehicle",
            "the rear axle steers with body roll, δ2 = ε·φ (φ > 0 leaning right, δ2 > 0 left)",
            "rear wheels steer towards the inside of the turn: roll understeer",
        ),
        EffectSpec(
            "tyre_ply_steer",
            "deg",
            0.1,
            0.5,
            True,
            "vehicle",
            "a lateral force of the rear tyres independent of slip (ply-steer residual, thrust "
            "angle), as a slip-angle offset of both rear tyres; the car crabs by it on a straight "
            "and the driver steers it out (a front residual would be centred by the alignment)",
            "the rear tyres push left",
        ),
    )
}

EFFECT_NAMES: tuple[EffectName, ...] = tuple(EFFECTS)


def effect_name(text: str) -> EffectName:
    """``text`` as an effect of the vocabulary, or a C2nError naming them all."""
    for name in EFFECT_NAMES:
        if text == name:
            return name
    raise C2nError(f"unknown effect '{text}' — use one of {', '.join(EFFECT_NAMES)}")


@dataclass(frozen=True)
class Effect:
    name: EffectName = "none"
    size: float = 0.0
    unit: str = ""

    def __post_init__(self) -> None:
        spec = EFFECTS[effect_name(self.name)]  # (a name read from a file is checked here)
        if self.unit != spec.unit:
            raise C2nError(f"effect {self.name}: size is in '{spec.unit}', not '{self.unit}'")
        if not spec.signed and self.size < 0:
            raise C2nError(f"effect {self.name}: the size must be ≥ 0, not {self.size}")
        if self.name == "none" and self.size != 0:
            raise C2nError("effect none has no size")

    @classmethod
    def of(cls, name: str, size: float | None = None) -> "Effect":
        """The effect with its unit; size None: the middle of its pack range."""
        spec = EFFECTS[effect_name(name)]
        return cls(spec.name, spec.typical if size is None else float(size), spec.unit)

    @property
    def spec(self) -> EffectSpec:
        return EFFECTS[self.name]

    def describe(self) -> str:
        return self.name if self.name == "none" else f"{self.name} {self.size:+.4g} {self.unit}"


NO_EFFECT = Effect()


def draw_effect(rng: "np.random.Generator", names: tuple[EffectName, ...] = EFFECT_NAMES) -> Effect:
    """One effect of ``names``, each (none too) equally likely; magnitude uniform in its range, sign
    random."""
    spec = EFFECTS[names[int(rng.integers(len(names)))]]
    magnitude = float(rng.uniform(spec.low, spec.high))
    sign = -1.0 if rng.random() < 0.5 else 1.0
    return Effect(spec.name, (sign if spec.signed else 1.0) * magnitude, spec.unit)


def apply_to_vehicle(effect: Effect, params: "TwoTrackParams") -> "TwoTrackParams":
    """The car and road with the effect (unchanged for a sensor effect or none)."""
    size = effect.size
    match effect.name:
        case "road_cross_slope":
            # downhill to the right of the start heading for a positive size, to the left otherwise
            return replace(
                params,
                cross_slope_grade=abs(size) / 100.0,
                slope_downhill_rad=-math.copysign(math.pi / 2, size),
            )
        case "load_transfer_nonlinearity":
            return replace(params, load_sensitivity=size)
        case "roll_steer":
            return replace(params, roll_steer=size)  # deg/deg = rad/rad
        case "tyre_ply_steer":
            return replace(params, rear_ply_steer_rad=math.radians(size))
    return params


def apply_to_sensor(effect: Effect, setup: "SensorSetup") -> "SensorSetup":
    """The sensors with the effect (unchanged for a vehicle or road effect or none)."""
    size = effect.size
    match effect.name:
        case "sensor_yaw_misalignment":
            return replace(setup, yaw_misalignment_deg=size)
        case "sensor_position_error":
            return replace(setup, d_m=setup.d_m + size)
        case "speed_scale_error":
            scale = 1.0 + size / 100.0
            return replace(setup, speed_scale=scale, wheel_speed_scale=scale)
        case "signal_latency":
            return replace(setup, vehicle_latency_s=size)
    return setup
