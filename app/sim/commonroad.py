"""A vehicle model nobody here wrote: CommonRoad's multi-body model, driven through our sessions.

``vehiclemodels.vehicle_dynamics_mb`` (Althoff and Würsching, TUM; package
``commonroad-vehicle-models``, the optional extra ``crosscheck``): 29 states — the sprung mass
in roll, pitch and heave, front and rear unsprung masses, four wheel speeds, compliant joints —
and Pacejka tyres, with its own parameter sets (``parameters_vehicle1…3``). Nothing of it is
changed or copied here: the model's own function is integrated (scipy's LSODA: it is stiff,
its wheel spin settles in milliseconds), driven by the same driver as our two-track model
(``app.sim.two_track``): the speed follows the session's plan, the steering holds a radius (PI
on the path curvature around the steady steer of the car's bicycle equivalent), a steering-wheel
angle, or a straight line. Its inputs are a steering rate and an acceleration, so the driver
steers towards its target at up to the model's own rate limit and accelerates with the plan's
rate plus a speed correction.

The car's linear cornering stiffness is its tyres': each gives K_y = p_ky1·F_z at small slip
and no camber, so C1n = C2n = |p_ky1| (21.92 1/rad for every parameter set). Its config
(``config/commonroad_vehicle2.toml``) has the car's geometry and these values; a realistic pack
perturbs them as for the two-track.

What the model allows of the effects: the sensor's own (misalignment, position, speed scale,
latency) act on the sensors as for the two-track; a road cross slope is gravity, added to the
model's accelerations (every mass feels it); roll steer, ply steer and load sensitivity are not
in the model (its rear axle does not steer, its tyres have no slip offset at zero camber and a
stiffness in proportion to the load), so packs of this generator do not draw them.
"""

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
from scipy.integrate import solve_ivp

from app.errors import C2nError
from app.sim.drive import _KI, _KP
from app.sim.effects import EffectName
from app.sim.scenarios import Scenario
from app.sim.two_track import TwoTrackParams, TwoTrackTrace, _path
from app.sim.vehicle_model import BicycleParams

PARAMETER_SETS = ("vehicle1", "vehicle2", "vehicle3")
DEFAULT_SET = "vehicle2"
EFFECTS: tuple[EffectName, ...] = (
    "none",
    "sensor_yaw_misalignment",
    "sensor_position_error",
    "speed_scale_error",
    "signal_latency",
    "road_cross_slope",
)
G = 9.81  # the model's own gravity
_SPEED_GAIN = 2.0  # 1/s: the driver's correction of a speed off the plan
_STEER_TIME_S = 0.05  # the driver closes a steering error at this time constant (rate-limited)
_DT_OUT_S = 0.005


def parameters(name: str = DEFAULT_SET) -> Any:
    """CommonRoad's parameter set ``name`` (vehicle1 … vehicle3)."""
    if name not in PARAMETER_SETS:
        raise C2nError(f"CommonRoad parameter set '{name}' — use one of {', '.join(PARAMETER_SETS)}")
    try:
        from importlib import import_module

        module = import_module(f"vehiclemodels.parameters_{name}")
    except ImportError as error:
        raise C2nError(
            "the CommonRoad cross-check needs commonroad-vehicle-models — pip install -e '.[crosscheck]'"
        ) from error
    return getattr(module, f"parameters_{name}")()


@dataclass(frozen=True)
class CommonRoadCar:
    """A parameter set, and what our configs and sensors need of it."""

    name: str
    p: Any

    @property
    def wheelbase_m(self) -> float:
        return float(self.p.a + self.p.b)

    @property
    def w1_n(self) -> float:
        return float(self.p.m * G * self.p.b / self.wheelbase_m)

    @property
    def w2_n(self) -> float:
        return float(self.p.m * G * self.p.a / self.wheelbase_m)

    @property
    def cn_per_rad(self) -> float:
        """Each axle's normalised cornering stiffness at small slip: |p_ky1|."""
        return abs(float(self.p.tire.p_ky1))

    def bicycle(self) -> BicycleParams:
        """The car's bicycle equivalent (the driver's feed-forward, the sensors' geometry)."""
        return replace(
            BicycleParams.from_axle_loads(
                self.wheelbase_m, self.w1_n, self.w2_n, self.cn_per_rad, self.cn_per_rad, g=G
            ),
            yaw_inertia_kgm2=float(self.p.I_z),
        )

    def two_track(self) -> TwoTrackParams:
        """Our two-track description of the car: what the sensors read of its geometry (the
        sprung mass rolls about its own centre of mass's height)."""
        b = self.bicycle()
        return TwoTrackParams(
            mass_kg=b.mass_kg,
            yaw_inertia_kgm2=b.yaw_inertia_kgm2,
            a_m=b.a_m,
            b_m=b.b_m,
            c1n=self.cn_per_rad,
            c2n=self.cn_per_rad,
            cg_height_m=float(self.p.h_s),
            track_front_m=float(self.p.T_f),
            track_rear_m=float(self.p.T_r),
            roll_centre_front_m=float(self.p.h_s),
            roll_centre_rear_m=float(self.p.h_s),
            g=G,
        )


@dataclass(frozen=True)
class Road:
    grade: float = 0.0  # tan θ of a planar cross slope
    downhill_rad: float = -math.pi / 2  # world direction it falls to (heading 0 = the start)


def _dynamics(car: CommonRoadCar, road: Road) -> Callable[[list[float], list[float]], list[float]]:
    """The model's right-hand side, with a planar slope's gravity added to every mass."""
    from vehiclemodels.vehicle_dynamics_mb import vehicle_dynamics_mb

    p = car.p
    g_plane = G * math.sin(math.atan(road.grade))

    def f(x: list[float], u: list[float]) -> list[float]:
        out = list(vehicle_dynamics_mb(list(x), u, p))  # it may change x: a copy
        if g_plane:
            rel = road.downhill_rad - x[4]
            g_y, g_x = g_plane * math.sin(rel), g_plane * math.cos(rel)
            out[3] += g_x
            out[10] += g_y  # sprung mass, front and rear unsprung masses
            out[15] += g_y
            out[20] += g_y
        return out

    return f


def simulate_commonroad(
    car: CommonRoadCar, scenario: Scenario, steering_ratio: float, road: Road = Road()
) -> TwoTrackTrace:
    """The session on CommonRoad's model, segment by segment (the driver's integral starts
    afresh with each command, as in our two-track), sampled every 5 ms."""
    from vehiclemodels.init_mb import init_mb

    f = _dynamics(car, road)
    driver = car.bicycle()
    length = car.wheelbase_m
    times = np.concatenate([[0.0], np.cumsum([s.duration_s for s in scenario.segments])])
    grid = np.arange(0.0, times[-1] + 1e-9, _DT_OUT_S)
    limit = float(car.p.steering.v_max)
    x = list(init_mb([0.0, 0.0, 0.0, scenario.speed_start_mps, 0.0, 0.0, 0.0], car.p))
    out_t, out_x, out_f = [], [], []
    for k, segment in enumerate(scenario.segments):
        t0, t1 = float(times[k]), float(times[k + 1])
        kind = {"straight": 0, "radius": 1, "wheel": 2}[segment.steer.kind]
        value = segment.steer.value
        u_start = scenario.speed_start_mps if k == 0 else scenario.segments[k - 1].speed_end_mps
        slope = (segment.speed_end_mps - u_start) / segment.duration_s

        def inputs(
            t: float,
            y: list[float],
            *,
            kind: int = kind,
            value: float = value,
            t0: float = t0,
            u0: float = u_start,
            slope: float = slope,
        ) -> tuple[list[float], float]:
            speed, r = y[3], y[5]
            accel = slope + _SPEED_GAIN * (u0 + slope * (t - t0) - speed)
            if kind == 2:
                target, d_integral = value / steering_ratio, 0.0
            else:
                curvature = 1.0 / value if kind == 1 else 0.0
                error = curvature - r / max(speed, 0.5)
                d_integral = _KI * length * error
                feedforward = driver.steady_steer(speed, value) if kind == 1 else 0.0
                target = feedforward + _KP * length * error + y[29]
            rate = min(max((target - y[2]) / _STEER_TIME_S, -limit), limit)
            return [rate, accel], d_integral

        def rhs(t: float, y: np.ndarray) -> list[float]:
            state = y.tolist()
            u, d_integral = inputs(t, state)
            return [*f(state[:29], u), d_integral]

        last = k == len(scenario.segments) - 1
        inside = (grid >= t0 - 1e-9) & ((grid < t1 - 1e-9) | last)
        sample = np.clip(grid[inside], t0, t1)  # a grid point a rounding error before t0 is at t0
        ends = bool(len(sample)) and sample[-1] >= t1 - 1e-9
        t_eval = sample if ends else np.append(sample, t1)  # the segment's end: where the next starts
        solution = solve_ivp(
            rhs, (t0, t1), [*x, 0.0], method="LSODA", t_eval=t_eval, rtol=1e-6, atol=1e-8, max_step=0.5
        )
        if not solution.success:
            raise C2nError(f"the CommonRoad model did not integrate segment {k + 1}: {solution.message}")
        for j in range(len(sample)):
            state = solution.y[:, j].tolist()
            u, _ = inputs(float(solution.t[j]), state)
            out_t.append(float(solution.t[j]))
            out_x.append(state[:29])
            out_f.append(f(state[:29], u))
        x = solution.y[:29, -1].tolist()
    return _trace(car, np.array(out_t), np.array(out_x), np.array(out_f), road)


def _trace(car: CommonRoadCar, t: np.ndarray, x: np.ndarray, f: np.ndarray, road: Road) -> TwoTrackTrace:
    """Our two-track trace of the run: ISO 8855 axes, roll positive leaning right."""
    u, v, r, delta, psi = x[:, 3], x[:, 10], x[:, 5], x[:, 2], x[:, 4]
    roll, roll_rate = -x[:, 6], -x[:, 7]  # the model's roll is positive leaning left
    v_dot, u_dot = f[:, 10], f[:, 3]
    g_plane = G * math.sin(math.atan(road.grade))
    rel = road.downhill_rad - psi
    g_y, g_x = g_plane * np.sin(rel), g_plane * np.cos(rel)
    specific = v_dot + u * r - g_y  # what an accelerometer on the sprung mass reads, road plane
    x_pos, y_pos = _path(t, u, v, psi)
    n = len(t)
    return TwoTrackTrace(
        params=car.bicycle(),
        t=t,
        u=u,
        u_dot=u_dot,
        v=v,
        r=r,
        delta=delta,
        ay=v_dot + u * r,
        two_track=car.two_track(),
        roll=roll,
        roll_rate=roll_rate,
        heading=psi,
        x_m=x_pos,
        y_m=y_pos,
        delta_rear=np.zeros(n),
        ay_accelerometer=specific * np.cos(roll) + G * np.sin(roll),
        ax_accelerometer=u_dot - v * r - g_x,
        wheel_load_n=np.zeros((n, 4)),
        tyre_force_n=np.zeros((n, 4)),
    )
