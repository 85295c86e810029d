"""The nominal bicycle model driven by the measured inputs, with each candidate effect as a
modification (DESIGN §6 vocabulary).

Each axle's cornering stiffness is its normalised stiffness times its load, and the load moves
rearward by m·h·a_x/L when the car speeds up (longitudinal load transfer: the CG height is the
config's ``cg_height_m``; without it the loads stay static).

The sensor head rides the body above its roll axis: a roll rate p moves it sideways at −p·h, h
its height above the roll axis (config ``sensor_height_m`` − ``roll_axis_height_m``, with the
measured roll rate where the config maps the ``roll_rate`` role). In a step steer that is a
sideslip of a tenth of a degree the planar model would otherwise not have.

Linear tyres make the lateral dynamics a linear time-varying system in x = [v, r] (lateral velocity
at the CG and yaw rate): ẋ = M(u)·x + f(δ, …). It is discretised per grid step (fourth-order
series of exp(M·h), forcing held over the step) and stepped in one tight loop, so a whole session
simulates in a few tens of milliseconds and effects can be fitted by least squares.
"""

import math
from dataclasses import dataclass

import numpy as np

from app.gap.measured import Measured
from app.sim.vehicle_model import BicycleParams

U_MIN_MPS = 3.0  # below this the model is not driven (and not compared)


@dataclass(frozen=True)
class Mods:
    """Unmodelled effects added to the nominal model; zero is the nominal model itself."""

    misalignment_rad: float = 0.0  # sensor head yawed left: it reads the sideslip this much low
    d_error_m: float = 0.0  # the true sensor position is the config's d plus this
    speed_scale: float = 0.0  # the vehicle speed reads (1 + s) times the true speed
    latency_s: float = 0.0  # vehicle-bus signals arrive this late
    slope_sin_mps2: float = 0.0  # lateral gravity of a cross-slope: A·sin ψ + B·cos ψ
    slope_cos_mps2: float = 0.0
    softening1_per_mps4: float = 0.0  # C1 (1 − k1·a_y²): load transfer / tyre nonlinearity
    softening2_per_mps4: float = 0.0  # C2 (1 − k2·a_y²)
    roll_steer_rad_per_mps2: float = 0.0  # rear axle steer per lateral acceleration (roll steer)
    ply_rad: float = 0.0  # slip-angle offset of the rear tyres (ply steer: a force at zero slip)


NOMINAL = Mods()


@dataclass(frozen=True)
class Simulated:
    beta: np.ndarray  # sideslip at the sensor as the sensor would read it
    r: np.ndarray
    u: np.ndarray  # true speed the model was driven with
    r_measured: np.ndarray  # the measured yaw rate on the model's clock
    ay: np.ndarray


def _shift(values: np.ndarray, t: np.ndarray, by_s: float) -> np.ndarray:
    """values(t + by_s): a signal that arrives ``by_s`` late, put back on time."""
    if by_s == 0.0:
        return values
    return np.asarray(np.interp(t + by_s, t, values))


def simulate(
    p: BicycleParams,
    m: Measured,
    d_m: float,
    mods: Mods = NOMINAL,
    cg_height_m: float | None = None,
    roll_lever_m: float = 0.0,
) -> Simulated:
    t, h = m.t, m.dt
    late = m.vehicle_roles

    def vehicle(values: np.ndarray, role: str) -> np.ndarray:
        return _shift(values, t, mods.latency_s) if role in late else values

    u_in = vehicle(m.u_vehicle, "speed") if m.speed_source == "vehicle speed" else m.u_optical
    u = np.maximum(u_in / (1.0 + mods.speed_scale), U_MIN_MPS)
    delta = np.nan_to_num(vehicle(m.delta, "steer"))
    ay = np.nan_to_num(m.ay)
    r_meas = vehicle(m.r, "yaw_rate")
    heading = np.cumsum(np.nan_to_num(r_meas)) * h

    transfer = p.mass_kg * cg_height_m * m.ax / p.wheelbase_m if cg_height_m else 0.0  # N, to the rear
    c1 = p.c1n * (p.w1_n - transfer) * np.clip(1.0 - mods.softening1_per_mps4 * ay * ay, 0.2, 2.0)
    c2 = p.c2n * (p.w2_n + transfer) * np.clip(1.0 - mods.softening2_per_mps4 * ay * ay, 0.2, 2.0)
    a, b, mass, iz = p.a_m, p.b_m, p.mass_kg, p.yaw_inertia_kgm2
    delta1 = delta
    delta2 = mods.roll_steer_rad_per_mps2 * ay + mods.ply_rad
    lateral = mods.slope_sin_mps2 * np.sin(heading) + mods.slope_cos_mps2 * np.cos(heading)

    n = len(t)
    mat = np.empty((n, 2, 2))
    mat[:, 0, 0] = -(c1 + c2) / (mass * u)
    mat[:, 0, 1] = -(a * c1 - b * c2) / (mass * u) - u
    mat[:, 1, 0] = -(a * c1 - b * c2) / (iz * u)
    mat[:, 1, 1] = -(a * a * c1 + b * b * c2) / (iz * u)
    force = np.stack(
        [(c1 * delta1 + c2 * delta2) / mass + lateral, (a * c1 * delta1 - b * c2 * delta2) / iz], axis=1
    )
    hm = mat * h
    hm2 = hm @ hm
    hm3 = hm2 @ hm
    eye = np.eye(2)
    step = eye + hm + hm2 / 2 + hm3 / 6 + hm3 @ hm / 24  # exp(M·h)
    gain = h * (eye + hm / 2 + hm2 / 6 + hm3 / 24)  # ∫ exp(M·s) ds over the step
    drive = np.einsum("kij,kj->ki", gain, force)

    x0 = -np.linalg.solve(mat[0], force[0]) if abs(np.linalg.det(mat[0])) > 1e-12 else np.zeros(2)
    a11, a12, a21, a22 = (step[:, i, j].tolist() for i, j in ((0, 0), (0, 1), (1, 0), (1, 1)))
    g1, g2 = drive[:, 0].tolist(), drive[:, 1].tolist()
    v_out, r_out = [0.0] * n, [0.0] * n
    v, r = float(x0[0]), float(x0[1])
    for k in range(n):
        v_out[k], r_out[k] = v, r
        v, r = a11[k] * v + a12[k] * r + g1[k], a21[k] * v + a22[k] * r + g2[k]
    v_cg, yaw = np.array(v_out), np.array(r_out)
    x_sensor = d_m + mods.d_error_m - b
    beta = np.arctan2(v_cg + yaw * x_sensor - m.p * roll_lever_m, u) - mods.misalignment_rad
    return Simulated(beta=beta, r=yaw, u=u, r_measured=r_meas, ay=ay)


def deg(x: float) -> float:
    return x * 180.0 / math.pi
