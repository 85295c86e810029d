"""Two sessions besides the standard one, for the same generators: track laps and one-speed circles.

Speeds are multiples of the nominal crossing speed u0 = √(C2n·g·d) and radii follow from a corner's
speed and lateral acceleration, so both scale with the car.

- **Track laps**: ordinary driving on a closed circuit of 8 corners (6 left, 2 right; the corners
  turn the car through 360° a lap) at 1.2–2.4·u0 and 1–4.4 m/s², with straights between them
  (acceleration 1–2.5 m/s², braking 2–4 m/s², one longer straight). Within a corner the speed
  changes slowly (from 1.02 of the corner's speed down to 0.98 at the apex, up to 1.03 out); each
  lap's corner speeds scatter by up to ±2.5 % with the seed, as a driver's laps do. Cornering is
  quasi-steady but the speed never sweeps through u0: no corner has a sideslip crossing.
  With the Mondeo config: radii 55–233 m, corners of 4–10 s, 6 laps, 9.3 minutes of driving
  (CommonRoad's car, u0 15.4 m/s: 81–344 m, 5–12 s, 10.7 minutes).
- **One-speed circles**: circles on 3 radii (2, 3 and 4 m/s² at the speed), each left then right,
  all at one speed (1.25·u0, the driver's foot within ±0.5 %), straights between. Every sample has
  a_y = u²·κ at that one speed: the degenerate design in which d and C2n cannot be told apart.
  With the Mondeo config: radii 63/84/127 m at 15.9 m/s, 5 minutes of driving.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from app.sim.scenarios import Part, Scenario, Segment, Session, Steer


@dataclass(frozen=True)
class Corner:
    direction: int  # +1 left, −1 right
    speed_factor: float  # the corner's speed, of u0
    ay_mps2: float  # steady lateral acceleration at that speed: sets the radius
    angle_deg: float  # the heading it turns through: sets how long it lasts


@dataclass(frozen=True)
class Straight:
    duration_s: float  # lengthened if the speed change needs longer at these rates
    accel_mps2: float
    brake_mps2: float


# Each corner with the straight that follows it; the last straight is the start–finish one.
CIRCUIT: tuple[tuple[Corner, Straight], ...] = (
    (Corner(1, 2.4, 4.3, 55.0), Straight(4.0, 2.0, 3.5)),  # fast sweeper at the end of the main straight
    (Corner(1, 1.3, 2.6, 40.0), Straight(3.0, 2.0, 2.5)),
    (Corner(1, 1.5, 3.4, 100.0), Straight(3.0, 2.0, 3.5)),
    (Corner(1, 1.22, 4.4, 150.0), Straight(6.0, 2.5, 3.0)),  # hairpin
    (Corner(-1, 1.7, 3.6, 40.0), Straight(3.0, 1.5, 3.0)),
    (Corner(1, 1.2, 1.0, 20.0), Straight(5.0, 2.0, 2.0)),  # slow kink of large radius
    (Corner(1, 2.0, 3.6, 75.0), Straight(3.0, 1.0, 4.0)),
    (Corner(-1, 1.4, 2.8, 40.0), Straight(10.0, 2.0, 3.0)),  # onto the main straight
)


@dataclass(frozen=True)
class TrackPlan:
    laps: int = 6
    circuit: tuple[tuple[Corner, Straight], ...] = CIRCUIT
    lap_scatter: float = 0.025  # a corner's speed from lap to lap: uniform within ±this
    corner_speeds: tuple[float, float, float] = (1.02, 0.98, 1.03)  # entry, apex, exit, of its speed
    top_speed_factor: float = 2.8  # of u0: the straights' top
    pit_speed_factor: float = 1.0  # of u0: the speed before the first lap and after the last
    pit_s: float = 5.0  # straight at that speed, before and after
    pit_accel_mps2: float = 2.0


TRACK_PLAN = TrackPlan()
QUICK_TRACK_PLAN = TrackPlan(laps=1)  # smoke tests: one lap


@dataclass(frozen=True)
class CirclesPlan:
    speed_factor: float = 1.25  # of u0, for the whole session
    ay_mps2: tuple[float, ...] = (2.0, 3.0, 4.0)  # at that speed: the radii
    settle_s: float = 6.0  # after turning in
    hold_s: float = 35.0  # steady on the circle after settling
    straight_s: float = 8.0
    speed_scatter: float = 0.005  # the driver's foot: each stretch ends within ±this of the speed
    stretch_s: float = 7.0  # how long the foot holds one speed


CIRCLES_PLAN = CirclesPlan()
QUICK_CIRCLES_PLAN = CirclesPlan(ay_mps2=(3.0,), hold_s=10.0, straight_s=4.0)  # smoke tests


@dataclass
class _Timeline:
    """Segments as they are driven, with the clock and the speed at the end of the last one."""

    speed_mps: float
    segments: list[Segment] = field(default_factory=list)
    parts: list[Part] = field(default_factory=list)
    clock_s: float = 0.0

    def drive(self, duration_s: float, speed_mps: float, steer: Steer) -> None:
        if duration_s < 1e-3:
            return
        self.segments.append(Segment(duration_s, speed_mps, steer))
        self.clock_s += duration_s
        self.speed_mps = speed_mps

    def session(self, name: str, start_mps: float) -> Session:
        return Session(Scenario(name, start_mps, tuple(self.segments)), tuple(self.parts))


def corner_radius_m(corner: Corner, u0_mps: float) -> float:
    """The corner's radius, rounded to metres as a circuit's map gives it."""
    speed = corner.speed_factor * u0_mps
    return float(round(speed * speed / corner.ay_mps2))


def track_session(u0_mps: float, plan: TrackPlan = TRACK_PLAN, seed: int = 0) -> Session:
    """Laps of the plan's circuit for a car whose expected crossing speed is ``u0_mps``."""
    rng = np.random.default_rng(seed)
    pit = plan.pit_speed_factor * u0_mps
    top = plan.top_speed_factor * u0_mps
    scatter = plan.lap_scatter
    radii = [corner_radius_m(corner, u0_mps) for corner, _ in plan.circuit]
    driven = [  # every corner of every lap: the corner, its radius, this lap's speed, the straight after
        (corner, radius, corner.speed_factor * u0_mps * (1.0 + rng.uniform(-scatter, scatter)), after)
        for _ in range(plan.laps)
        for (corner, after), radius in zip(plan.circuit, radii, strict=True)
    ]
    straight = Steer("straight")
    timeline = _Timeline(pit)
    timeline.drive(plan.pit_s, pit, straight)
    entry = plan.corner_speeds[0]
    _straight(timeline, plan.circuit[-1][1], entry * driven[0][2], top)  # out of the pits onto the circuit
    for k, (corner, radius, speed, after) in enumerate(driven):
        _corner(timeline, corner, radius, speed, plan)
        if k + 1 < len(driven):
            _straight(timeline, after, entry * driven[k + 1][2], top)
    timeline.drive(abs(timeline.speed_mps - pit) / plan.pit_accel_mps2, pit, straight)  # into the pits
    timeline.drive(plan.pit_s, pit, straight)
    return timeline.session("track", pit)


def _corner(timeline: _Timeline, corner: Corner, radius_m: float, speed_mps: float, plan: TrackPlan) -> None:
    """Braking a little to the apex and accelerating a little out, on one radius; it lasts as long
    as the corner's angle takes at its mean speed, so a lap turns the car by the circuit's angles."""
    entry, apex, exit_ = plan.corner_speeds
    mean = (entry + 2.0 * apex + exit_) / 4.0 * speed_mps  # of the two ramps
    half_s = 0.5 * math.radians(corner.angle_deg) * radius_m / mean
    turn = Steer("radius", corner.direction * radius_m)
    begin = timeline.clock_s
    timeline.drive(half_s, apex * speed_mps, turn)
    timeline.drive(half_s, exit_ * speed_mps, turn)
    timeline.parts.append(Part("corner", begin, timeline.clock_s, corner.direction, radius_m, speed_mps))


def _straight(timeline: _Timeline, straight: Straight, next_mps: float, top_mps: float) -> None:
    """Full acceleration to the highest speed that still brakes down to ``next_mps`` in the
    straight's time (the top speed at most, held), then braking."""
    begin, start = timeline.clock_s, timeline.speed_mps
    a, b = straight.accel_mps2, straight.brake_mps2
    peak = (straight.duration_s + start / a + next_mps / b) / (1.0 / a + 1.0 / b)
    peak = min(max(peak, start, next_mps), max(top_mps, start, next_mps))
    accel_s, brake_s = (peak - start) / a, (peak - next_mps) / b
    steer = Steer("straight")
    timeline.drive(accel_s, peak, steer)
    timeline.drive(straight.duration_s - accel_s - brake_s, peak, steer)
    timeline.drive(brake_s, next_mps, steer)
    timeline.parts.append(Part("straight", begin, timeline.clock_s))


def circles_session(u0_mps: float, plan: CirclesPlan = CIRCLES_PLAN, seed: int = 0) -> Session:
    """Circles at one speed on the plan's radii, each left then right, straights between."""
    rng = np.random.default_rng(seed)
    speed = plan.speed_factor * u0_mps
    timeline = _Timeline(speed)

    def hold(duration_s: float, steer: Steer) -> None:
        """The speed as a driver's foot holds it: stretches ending within ±speed_scatter."""
        stretches = max(1, math.ceil(duration_s / plan.stretch_s))
        for _ in range(stretches):
            scatter = rng.uniform(-plan.speed_scatter, plan.speed_scatter)
            timeline.drive(duration_s / stretches, speed * (1.0 + scatter), steer)

    straight = Steer("straight")
    hold(plan.straight_s, straight)
    for ay in plan.ay_mps2:
        radius = float(round(speed * speed / ay))
        for sign in (1, -1):
            begin = timeline.clock_s
            hold(plan.settle_s + plan.hold_s, Steer("radius", sign * radius))
            timeline.parts.append(Part("circle", begin, timeline.clock_s, sign, radius, speed))
            begin = timeline.clock_s
            hold(plan.straight_s, straight)
            timeline.parts.append(Part("straight", begin, timeline.clock_s, speed_mps=speed))
    return timeline.session("circles", speed)
