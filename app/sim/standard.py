"""The standard test session, driven by the two-track model with one effect (or none).

What a diagnosis needs, in an order a test driver can drive on a proving ground (speeds relative
to the config's nominal crossing speed u0 = √(C2n·g·d), radii from the top speed):

1. straight: 5 s at the low speed, up to u0 at 0.5 m/s², 30 s at u0 (sideslip offset, speed
   scale, the road's cross slope at a known heading), back down to the low speed;
2. constant-radius sweeps on 3 radii (R1 = u_hi²/4 m/s², 1.4·R1, 2·R1), each left then right:
   turn in and settle at the low speed (6 s), speed swept up through u0 to u_hi at 0.3 m/s², held
   3 s, swept down, held 3 s, 4 s straight;
3. step steers at 0.8·u0 and 1.2·u0, left then right at each: straight 2 s, the wheel stepped to
   the angle that gives 3 m/s² at the higher speed and held 6 s, 3 s straight.

With the Mondeo config: u0 12.7 m/s, speeds 7.6–16.5 m/s, radii 68/96/137 m, 9.4 minutes of driving.

``StandardOptions.session`` drives this session or one of app/sim/laps_and_circles.py's (track laps,
one-speed circles) on either generator.
"""

import copy
import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, replace
from typing import Any, Literal

import numpy as np

from app import paper
from app.config import Config
from app.dbc import load_dbc
from app.errors import C2nError
from app.sim import commonroad
from app.sim.axle import STEADY_UDOT_MPS2, axle_c2n
from app.sim.effects import NO_EFFECT, Effect, apply_to_sensor, apply_to_vehicle
from app.sim.imperfections import NO_IMPERFECTIONS, Imperfections
from app.sim.laps_and_circles import (
    CIRCLES_PLAN,
    TRACK_PLAN,
    CirclesPlan,
    TrackPlan,
    circles_session,
    track_session,
)
from app.sim.scenarios import Part, Scenario, Segment, Session, Steer
from app.sim.sensors import SensorSetup, frames
from app.sim.simulated_drive import DBC_DIR, SimulatedDrive
from app.sim.two_track import TwoTrackParams, TwoTrackTrace, simulate_two_track
from app.sim.vehicle_model import BicycleParams


@dataclass(frozen=True)
class StandardPlan:
    speed_lo_factor: float = 0.6  # of the nominal u0
    speed_hi_factor: float = 1.3
    ay_top_mps2: float = 4.0  # at the top speed of the smallest radius
    radius_factors: tuple[float, ...] = (1.0, 1.4, 2.0)
    radii_ay_at_u0_mps2: tuple[float, ...] = ()  # radii on which u0 takes these a_y (rounded to
    # metres); () for radius_factors of the base
    ay_max_mps2: float | None = None  # each sweep's top speed held to this a_y on its radius
    sweep_mps2: float = 0.3
    settle_s: float = 6.0  # after turning in
    hold_s: float = 3.0  # at the ends of a sweep
    straight_s: float = 30.0
    straight_accel_mps2: float = 0.5
    step_speed_factors: tuple[float, ...] = (0.8, 1.2)
    step_ay_mps2: float = 3.0  # steady lateral acceleration of the step at the highest speed
    step_hold_s: float = 6.0


STANDARD_PLAN = StandardPlan()

# The standard session on a small test area: radii on which u0 takes 6.5, 5.4 and 4.5 m/s² (25, 30
# and 36 m for the Mondeo), each swept up to 7 m/s², deep into the tyres' non-linear range (issue 23)
TIGHT_PLAN = StandardPlan(radii_ay_at_u0_mps2=(6.5, 5.4, 4.5), ay_max_mps2=7.0)

# A short session for smoke tests (one radius, fast sweeps): too coarse for a diagnosis.
QUICK_PLAN = StandardPlan(
    radius_factors=(1.0,),
    sweep_mps2=1.0,
    settle_s=4.0,
    hold_s=1.0,
    straight_s=5.0,
    straight_accel_mps2=1.0,
    step_speed_factors=(1.2,),
    step_hold_s=4.0,
)


def standard_session(
    u0_mps: float, params: BicycleParams, steering_ratio: float, plan: StandardPlan = STANDARD_PLAN
) -> Session:
    """The session for a car whose expected crossing speed is ``u0_mps`` (radii rounded to metres,
    as a test area marks them)."""
    lo, hi = plan.speed_lo_factor * u0_mps, plan.speed_hi_factor * u0_mps
    segments: list[Segment] = []
    parts: list[Part] = []
    clock = [0.0]

    def add(duration: float, speed: float, steer: Steer) -> None:
        segments.append(Segment(duration, speed, steer))
        clock[0] += duration

    straight = Steer("straight")
    add(5.0, lo, straight)
    ramp = max(abs(u0_mps - lo) / plan.straight_accel_mps2, 1.0)
    add(ramp, u0_mps, straight)
    steady = clock[0]
    add(plan.straight_s, u0_mps, straight)
    parts.append(Part("straight", steady, clock[0], speed_mps=u0_mps))
    add(ramp, lo, straight)

    base = hi * hi / plan.ay_top_mps2
    factors = tuple(u0_mps**2 / (ay * base) for ay in plan.radii_ay_at_u0_mps2) or plan.radius_factors
    radii = tuple(float(round(factor * base)) for factor in factors)
    for radius in radii:
        top = hi if plan.ay_max_mps2 is None else min(hi, math.sqrt(plan.ay_max_mps2 * radius))
        sweep_s = (top - lo) / plan.sweep_mps2
        for sign in (1, -1):
            turn = Steer("radius", sign * radius)
            begin = clock[0]
            add(plan.settle_s, lo, turn)
            add(sweep_s, top, turn)
            add(plan.hold_s, top, turn)
            add(sweep_s, lo, turn)
            add(plan.hold_s, lo, turn)
            parts.append(Part("sweep", begin, clock[0], sign, radius))
            add(4.0, lo, straight)

    top = max(plan.step_speed_factors) * u0_mps
    wheel = params.steady_steer(top, top * top / plan.step_ay_mps2) * steering_ratio
    previous = lo
    for factor in plan.step_speed_factors:
        speed = factor * u0_mps
        for sign in (1, -1):
            add(max(abs(speed - previous) / 1.0, 2.0), speed, straight)  # 1 m/s² between steps
            add(2.0, speed, straight)
            begin = clock[0]
            add(plan.step_hold_s, speed, Steer("wheel", sign * wheel))
            parts.append(Part("step_steer", begin, clock[0], sign, speed_mps=speed))
            add(3.0, speed, straight)
            previous = speed
    return Session(Scenario("standard", lo, tuple(segments)), tuple(parts))


@dataclass(frozen=True)
class StandardOptions:
    seed: int = 0
    effect: Effect = NO_EFFECT
    c2n: float | None = None  # truth; None: the config's [tyres] c2n_per_rad
    c1n: float | None = None
    plan: StandardPlan = STANDARD_PLAN
    dt_s: float = 0.002
    sensor: Mapping[str, Any] = field(default_factory=dict)  # SensorSetup overrides (the effect wins)
    imperfections: Imperfections = NO_IMPERFECTIONS  # a real test day's (``sensor`` wins over them)
    plan_c2n: float | None = None  # the C2n the driver plans speeds from (None: the config's)
    model: Literal["two_track", "commonroad"] = "two_track"  # the generator
    commonroad_set: str = commonroad.DEFAULT_SET  # its parameter set
    downhill_deg: float | None = None  # a cross slope's fall, from the start heading (left positive);
    # None: to the side the effect's sign says (+: the right)
    session: Literal["standard", "track", "circles"] = "standard"  # what the driver drives (its plan:
    # plan, track_plan or circles_plan)
    track_plan: TrackPlan = TRACK_PLAN
    circles_plan: CirclesPlan = CIRCLES_PLAN
    car: Mapping[str, float] = field(default_factory=dict)  # the two-track car's own figures
    # (TwoTrackParams' fields: a roll gradient, the tyres' load sensitivity), over the config's

    @property
    def session_plan(self) -> StandardPlan | TrackPlan | CirclesPlan:
        """The plan of the session driven."""
        plans: dict[str, StandardPlan | TrackPlan | CirclesPlan] = {
            "standard": self.plan,
            "track": self.track_plan,
            "circles": self.circles_plan,
        }
        return plans[self.session]


def simulate_standard(config: Config, options: StandardOptions = StandardOptions()) -> SimulatedDrive:
    """The options' session (the standard one, track laps or one-speed circles) on the options'
    generator (our two-track, or CommonRoad's multi-body model) with the options' effect, as CAN
    frames + truth."""
    if options.model == "commonroad":
        return _on_commonroad(config, options)
    imperfect = options.imperfections
    c2n = options.c2n if options.c2n is not None else config.tyres.c2n_per_rad
    c1n = options.c1n if options.c1n is not None else config.tyres.c1n_per_rad
    nominal = replace(
        TwoTrackParams.from_config(
            config,
            c2n * (1.0 + imperfect.c2n_error) if c2n is not None else None,
            c1n * (1.0 + imperfect.c1n_error) if c1n is not None else None,
        ),
        **options.car,
    )
    params = apply_to_vehicle(options.effect, nominal)
    if options.downhill_deg is not None:
        params = replace(params, slope_downhill_rad=math.radians(options.downhill_deg))
    ratio = config.vehicle.steering_ratio or 15.0
    session = _session(config, options, nominal.bicycle(), nominal.c2n)
    trace = simulate_two_track(params, session.scenario, ratio, options.dt_s)
    extra = {
        "understeer_rad_per_mps2": params.understeer_rad_per_mps2,
        "c2n_load_transfer_ratio_at_3mps2": params.rear_stiffness_ratio(3.0),
        "vehicle": asdict(params),
    }
    return _drive(config, options, session, trace, params.c1n, params.c2n, "two_track", extra)


def _on_commonroad(config: Config, options: StandardOptions) -> SimulatedDrive:
    """The session on CommonRoad's model: its parameter set, its tyres a few per cent off when
    the day is imperfect (both axles share one tyre there), the road's slope as gravity."""
    name = options.effect.name
    if name not in commonroad.EFFECTS:
        raise C2nError(
            f"effect {name} is not in CommonRoad's model — use one of {', '.join(commonroad.EFFECTS)}"
        )
    p = copy.deepcopy(commonroad.parameters(options.commonroad_set))
    tyre = 1.0 + options.imperfections.c2n_error
    if options.c2n is not None:
        tyre = options.c2n / abs(float(p.tire.p_ky1))
    p.tire.p_ky1 = float(p.tire.p_ky1) * tyre
    car = commonroad.CommonRoadCar(options.commonroad_set, p)
    if abs((config.vehicle.wheelbase_m or 0.0) - car.wheelbase_m) > 0.01 * car.wheelbase_m:
        raise C2nError(
            f"{config.path}: a wheelbase of {config.vehicle.wheelbase_m} m is not CommonRoad's "
            f"{options.commonroad_set} ({car.wheelbase_m:.3f} m) — "
            f"use config/commonroad_{options.commonroad_set}.toml"
        )
    road = commonroad.Road()
    if name == "road_cross_slope":
        size = options.effect.size
        falls = -math.copysign(math.pi / 2, size)
        if options.downhill_deg is not None:
            falls = math.radians(options.downhill_deg)
        road = commonroad.Road(abs(size) / 100.0, falls)
    ratio = config.vehicle.steering_ratio or 15.0
    session = _session(config, options, car.bicycle(), car.cn_per_rad)
    trace = commonroad.simulate_commonroad(car, session.scenario, ratio, road)
    extra = {"parameter_set": options.commonroad_set, "road": asdict(road)}
    return _drive(config, options, session, trace, car.cn_per_rad, car.cn_per_rad, "commonroad", extra)


def _session(config: Config, options: StandardOptions, bicycle: BicycleParams, c2n: float) -> Session:
    """The options' session as the driver plans it: from the config's C2n (or ``plan_c2n``), not the
    car's."""
    planning_c2n = options.plan_c2n or config.tyres.c2n_per_rad or c2n
    u0_plan = paper.crossing_speed(planning_c2n, config.d_m, config.vehicle.gravity_mps2)
    if options.session == "track":
        return track_session(u0_plan, options.track_plan, options.seed)
    if options.session == "circles":
        return circles_session(u0_plan, options.circles_plan, options.seed)
    return standard_session(u0_plan, bicycle, config.vehicle.steering_ratio or 15.0, options.plan)


def _axle(options: StandardOptions, trace: TwoTrackTrace, session: Session, g: float) -> float | None:
    """The car's rear axle read on its sweeps (``axle_c2n``), None where they run faster than the
    steady gate's |u̇| (``--quick``'s 1 m/s²): its few samples under the gate are the turns of the
    speed, not steady, and read 7.3 for an axle of 14.9."""
    plan = options.session_plan
    if isinstance(plan, StandardPlan) and plan.sweep_mps2 > STEADY_UDOT_MPS2:
        return None
    return axle_c2n(trace, session.parts, g)


def _drive(
    config: Config,
    options: StandardOptions,
    session: Session,
    trace: TwoTrackTrace,
    c1n: float,
    c2n: float,
    model: str,
    extra: dict[str, Any],
) -> SimulatedDrive:
    """The trace through the sensors (the test day's imperfections, the sensor effects) into
    CAN frames, and the truth."""
    imperfect = options.imperfections
    ratio = config.vehicle.steering_ratio or 15.0
    g = config.vehicle.gravity_mps2
    sensor = imperfect.sensor(ratio) | dict(options.sensor)
    setup = apply_to_sensor(options.effect, SensorSetup.from_config(config, **sensor))
    kistler = load_dbc(DBC_DIR / "kistler_smotion.dbc").database
    ford = load_dbc(DBC_DIR / "vehicle_ford.dbc").database
    messages = frames(trace, setup, kistler, ford, np.random.default_rng(options.seed))
    truth: dict[str, Any] = {
        "session": options.session,
        "model": model,
        "effect": {"name": options.effect.name, "size": options.effect.size, "unit": options.effect.unit},
        "c2n": c2n,
        "c2n_axle": _axle(options, trace, session, g),  # the car's own rear axle (app/sim/axle.py)
        "c1n": c1n,
        "d_m": setup.d_m,
        "config_d_m": config.d_m,
        "u0_mps": paper.crossing_speed(c2n, setup.d_m, g),
        "g_mps2": g,
        "seed": options.seed,
        "imperfections": asdict(imperfect),
        "duration_s": float(trace.t[-1]),
        "frames": len(messages),
        "max_ay_mps2": float(np.max(np.abs(trace.ay))),
        "max_roll_deg": math.degrees(float(np.max(np.abs(trace.roll)))),
        "sensor": asdict(setup),
        "plan": asdict(options.session_plan),
        "parts": [asdict(part) for part in session.parts],
    } | extra
    return SimulatedDrive(messages, truth, trace)
