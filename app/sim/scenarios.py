"""Manoeuvres as segments: the speed ramps linearly to each segment's end speed while the
driver holds a radius, a steering-wheel angle, or drives straight.

Radii and steering-wheel angles are signed: positive turns left (ISO 8855).
"""

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Literal

from app.sim.vehicle_model import BicycleParams


@dataclass(frozen=True)
class Steer:
    kind: Literal["radius", "wheel", "straight"]
    value: float = 0.0  # radius [m] or steering-wheel angle [rad], signed (+ left)


@dataclass(frozen=True)
class Segment:
    duration_s: float
    speed_end_mps: float
    steer: Steer


@dataclass(frozen=True)
class Scenario:
    name: str
    speed_start_mps: float
    segments: tuple[Segment, ...]

    @property
    def duration_s(self) -> float:
        return sum(s.duration_s for s in self.segments)


@dataclass(frozen=True)
class Part:
    """One manoeuvre of a session and when it runs."""

    kind: str  # "straight", "sweep", "step_steer" (standard); "corner" (track); "circle" (circles)
    start_s: float
    end_s: float
    direction: int = 0  # +1 left, −1 right, 0 straight
    radius_m: float | None = None
    speed_mps: float | None = None


@dataclass(frozen=True)
class Session:
    """A test session as the driver plans it: what to drive, and its manoeuvres with their times."""

    scenario: Scenario
    parts: tuple[Part, ...]


@dataclass(frozen=True)
class SweepPlan:
    """What the manoeuvre builders need to know: the speed range and the vehicle."""

    params: BicycleParams
    steering_ratio: float
    speed_lo_mps: float
    speed_hi_mps: float
    sweep_mps2: float = 0.3
    ay_max_mps2: float = 3.5
    directions: tuple[int, ...] = (1, -1)  # +1 left, −1 right


def constant_radius(plan: SweepPlan, radius_m: float | None = None) -> Scenario:
    """Constant radius, speed swept up then down, left then right (like the paper's Fig. 9)."""
    radius = radius_m or plan.speed_hi_mps**2 / plan.ay_max_mps2
    return _sweeps("constant_radius", plan, lambda sign: Steer("radius", sign * radius))


def radii(plan: SweepPlan, factors: tuple[float, ...] = (1.0, 2.0)) -> Scenario:
    """Constant-radius sweeps at several radii (multiples of the radius whose top speed gives
    ay_max): lateral acceleration spans a wider range, so tyre softening shows."""
    base = plan.speed_hi_mps**2 / plan.ay_max_mps2
    segments: list[Segment] = []
    for factor in factors:
        radius = factor * base

        def turn(sign: int, radius: float = radius) -> Steer:
            return Steer("radius", sign * radius)

        part = _sweeps("radii", plan, turn)
        segments += part.segments if not segments else part.segments[1:]
    return Scenario("radii", plan.speed_lo_mps, tuple(segments))


def constant_steer(plan: SweepPlan, wheel_deg: float | None = None) -> Scenario:
    """Constant steering-wheel angle, speed swept up then down (the paper's Fig. 2)."""
    if wheel_deg is None:
        # the angle whose radius at the top speed gives ay_max
        u = plan.speed_hi_mps
        radius = u * u / plan.ay_max_mps2
        wheel = plan.params.steady_steer(u, radius) * plan.steering_ratio
    else:
        wheel = math.radians(wheel_deg)
    return _sweeps("constant_steer", plan, lambda sign: Steer("wheel", sign * wheel))


def _sweeps(name: str, plan: SweepPlan, steer: Callable[[int], Steer]) -> Scenario:
    lo, hi = plan.speed_lo_mps, plan.speed_hi_mps
    sweep_s = (hi - lo) / plan.sweep_mps2
    segments: list[Segment] = [Segment(3.0, lo, Steer("straight"))]
    for sign in plan.directions:
        turn = steer(sign)
        segments += [
            Segment(6.0, lo, turn),  # turn in and settle
            Segment(sweep_s, hi, turn),  # sweep up
            Segment(2.0, hi, turn),
            Segment(sweep_s, lo, turn),  # sweep down
            Segment(2.0, lo, turn),
            Segment(4.0, lo, Steer("straight")),
        ]
    return Scenario(name, lo, tuple(segments))


def step_steer(
    plan: SweepPlan,
    speeds_mps: tuple[float, ...] | None = None,
    wheel_deg: float | None = None,
    hold_s: float = 5.0,
) -> Scenario:
    """Straight at constant speed, a quick step of the steering wheel, held until steady (Fig. 5),
    repeated at several speeds (Fig. 6); left and right."""
    if speeds_mps is None:
        n = 9
        speeds_mps = tuple(
            plan.speed_lo_mps + i * (plan.speed_hi_mps - plan.speed_lo_mps) / (n - 1) for i in range(n)
        )
    if wheel_deg is None:
        u = max(speeds_mps)
        radius = u * u / plan.ay_max_mps2
        wheel = plan.params.steady_steer(u, radius) * plan.steering_ratio
    else:
        wheel = math.radians(wheel_deg)
    segments: list[Segment] = []
    previous = speeds_mps[0]
    for sign in plan.directions:
        for speed in speeds_mps:
            change_s = max(abs(speed - previous) / 1.0, 2.0)  # 1 m/s² between steps, straight
            segments += [
                Segment(change_s, speed, Steer("straight")),
                Segment(1.0, speed, Steer("straight")),
                Segment(hold_s, speed, Steer("wheel", sign * wheel)),
            ]
            previous = speed
        segments.append(Segment(2.0, previous, Steer("straight")))
    return Scenario("step_steer", speeds_mps[0], tuple(segments))


SCENARIOS: dict[str, Callable[[SweepPlan], Scenario]] = {
    "constant_radius": constant_radius,
    "radii": radii,
    "constant_steer": constant_steer,
    "step_steer": step_steer,
}
