"""Integrate the bicycle model through a manoeuvre (RK4, fixed step) with a simple driver."""

from dataclasses import dataclass

import numpy as np

from app.sim.scenarios import Scenario
from app.sim.vehicle_model import BicycleParams

_MAX_STEER_RATE = 0.5  # rad/s at the road wheels (≈ 430 °/s at the steering wheel)
_KP, _KI = 1.0, 0.5  # radius-holding driver: gains on the curvature error times the wheelbase


@dataclass(frozen=True)
class DriveTrace:
    """The motion at each integration step (ISO 8855, body axes at the CG)."""

    params: BicycleParams
    t: np.ndarray
    u: np.ndarray  # longitudinal velocity
    u_dot: np.ndarray
    v: np.ndarray  # lateral velocity at the CG
    r: np.ndarray  # yaw rate
    delta: np.ndarray  # road-wheel steer angle
    ay: np.ndarray  # lateral acceleration v̇ + u·r

    def lateral_velocity_at(self, x_m: float) -> np.ndarray:
        """Lateral velocity at x metres ahead of the CG: v + r·x."""
        return self.v + self.r * x_m


def simulate(
    params: BicycleParams, scenario: Scenario, steering_ratio: float, dt: float = 0.002
) -> DriveTrace:
    n = round(scenario.duration_s / dt) + 1
    t = np.arange(n) * dt
    u, u_dot = _speed_profile(scenario, t)
    if np.any(u <= 0.5):
        raise ValueError("the bicycle model needs a speed above 0.5 m/s throughout")
    v_out, r_out, delta_out, ay_out = (np.empty(n) for _ in range(4))
    kinds, values = _steer_commands(scenario, t)
    v = r = delta = integral = 0.0
    p = params
    length = p.wheelbase_m
    for k in range(n):
        uk = float(u[k])
        if kinds[k] == 1:  # hold a radius
            radius = float(values[k])
            error = 1.0 / radius - r / uk
            integral += _KI * length * error * dt
            target = p.steady_steer(uk, radius) + _KP * length * error + integral
        else:
            integral = 0.0
            target = float(values[k]) / steering_ratio if kinds[k] == 2 else 0.0
        step = _MAX_STEER_RATE * dt
        delta += min(max(target - delta, -step), step)
        v_dot, r_dot = p.derivatives(uk, v, r, delta)
        v_out[k], r_out[k], delta_out[k], ay_out[k] = v, r, delta, v_dot + uk * r
        if k == n - 1:
            break
        # RK4 with the steer held over the step and the speed ramping with the manoeuvre
        u_mid, u_end = uk + 0.5 * dt * float(u_dot[k]), float(u[k + 1])
        k1 = (v_dot, r_dot)
        k2 = p.derivatives(u_mid, v + 0.5 * dt * k1[0], r + 0.5 * dt * k1[1], delta)
        k3 = p.derivatives(u_mid, v + 0.5 * dt * k2[0], r + 0.5 * dt * k2[1], delta)
        k4 = p.derivatives(u_end, v + dt * k3[0], r + dt * k3[1], delta)
        v += dt / 6.0 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        r += dt / 6.0 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
    return DriveTrace(params, t, u, u_dot, v_out, r_out, delta_out, ay_out)


def _speed_profile(scenario: Scenario, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    times = [0.0]
    speeds = [scenario.speed_start_mps]
    for segment in scenario.segments:
        times.append(times[-1] + segment.duration_s)
        speeds.append(segment.speed_end_mps)
    u = np.interp(t, times, speeds)
    slopes = np.diff(speeds) / np.diff(times)
    index = np.clip(np.searchsorted(times, t, side="right") - 1, 0, len(slopes) - 1)
    return u, slopes[index]


def _steer_commands(scenario: Scenario, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per step: kind (0 straight, 1 radius, 2 steering-wheel angle) and its value."""
    kinds = np.zeros(len(t), dtype=np.int8)
    values = np.zeros(len(t))
    start = 0.0
    codes = {"straight": 0, "radius": 1, "wheel": 2}
    for segment in scenario.segments:
        end = start + segment.duration_s
        inside = (t >= start) & (t < end + (1e-9 if segment is scenario.segments[-1] else 0.0))
        kinds[inside] = codes[segment.steer.kind]
        values[inside] = segment.steer.value
        start = end
    return kinds, values
