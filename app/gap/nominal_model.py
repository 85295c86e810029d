"""The nominal bicycle model driven by the measured inputs, with the calibrated nuisances and each
candidate effect as a modification.

Each axle's cornering stiffness is its normalised stiffness times its load, and the load moves
rearward by m·h·a_x/L when the car speeds up (longitudinal load transfer: the CG height is the
config's ``cg_height_m``; without it the loads stay static).

The sensor head rides the body above its roll axis: a roll rate p moves it sideways at −p·h, h
its height above the roll axis (config ``sensor_height_m`` − ``roll_axis_height_m``, with the
measured roll rate where the config maps the ``roll_rate`` role). In a step steer that is a
sideslip of a tenth of a degree the planar model would otherwise not have.

Linear tyres make the lateral dynamics a linear time-varying system in x = [v, r] (lateral velocity
at the CG and yaw rate): ẋ = M(u)·x + f(δ, …). It is discretised per grid step (fourth-order
series of exp(M·h), forcing held over the step) and stepped in one compiled loop, so a whole
session simulates in about a millisecond and the nuisances and effects can be fitted by least
squares.

The model runs on the optical speed (no scale error, no lag); the vehicle's own speed signal is an
output it predicts, (1 + s)·u(t − τ), so a speed scale error or a late vehicle bus shows there
directly instead of being absorbed by the calibration. The nuisances act on the inputs and the
measured yaw rate: the steering is read with its centre offset and effective ratio taken out,
the yaw rate with its bias and scale; C1n and C2n are the config's times a factor.
"""

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numba import njit

from app.gap.measured import Measured
from app.sim.vehicle_model import BicycleParams

U_MIN_MPS = 3.0  # below this the model is not driven (and not compared)
TURN_AY_MPS2 = 0.2  # a force that follows the turn switches sides over this much lateral acceleration


@dataclass(frozen=True)
class Mods:
    """What the model adds to the config's nominal car. Zero (and factors of 1) is the nominal
    model itself. The first seven are the nuisances every real drive has, calibrated before any
    effect is attributed; the rest are the unmodelled effects of the vocabulary."""

    # nuisances
    yaw_bias_radps: float = 0.0  # the yaw-rate sensor reads this much high ...
    yaw_scale: float = 0.0  # ... and (1 + this) times the true rate
    steer_offset_rad: float = 0.0  # road-wheel angle the steering reads with the wheels straight
    ratio_error: float = 0.0  # the effective steering ratio is the config's × (1 + this)
    c1n_factor: float = 1.0  # the car's front axle: the config's C1n × this
    c2n_factor: float = 1.0  # the car's rear axle: the config's C2n × this
    turn_force_g: float = 0.0  # a lateral force towards the turn's centre, in g, that follows the
    # turn: a pad banked towards the centre, or the tyres' camber thrust as the body rolls
    # effects
    misalignment_rad: float = 0.0  # sensor head yawed left: it reads the sideslip this much low
    d_error_m: float = 0.0  # the true sensor position is the config's d plus this
    speed_scale: float = 0.0  # the vehicle speed signal reads (1 + s) times the true speed
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
    r: np.ndarray  # the model's yaw rate
    u: np.ndarray  # true speed the model was driven with
    r_measured: np.ndarray  # the measured yaw rate on the model's clock, its bias and scale taken out
    ay: np.ndarray
    speed_reading: np.ndarray  # what the vehicle's speed signal would read: its scale and its lag


def _shift(values: np.ndarray, t: np.ndarray, by_s: float) -> np.ndarray:
    """values(t + by_s): a signal that arrives ``by_s`` late, put back on time."""
    if by_s == 0.0:
        return values
    return np.asarray(np.interp(t + by_s, t, values))


@dataclass(frozen=True)
class Prepared:
    """What the model takes from the drive and the nominal car, worked out once: every fit runs
    the model thousands of times and only the modifications change between runs."""

    params: BicycleParams
    t: np.ndarray
    dt: float
    u_optical: np.ndarray  # NaN as 0: the speed signal the vehicle's is compared with
    u: np.ndarray  # the speed the model runs at
    delta: np.ndarray  # road-wheel steer as read (offset and ratio not taken out)
    delta_late: bool  # the steering rides the vehicle bus (its latency)
    r: np.ndarray  # the yaw rate as read
    r_late: bool
    c1_nominal: np.ndarray  # axle stiffnesses with the longitudinal load transfer, N/rad
    c2_nominal: np.ndarray
    sway: np.ndarray  # the head's lateral velocity from rolling, p·h
    transfer_kg_s2: float = 0.0  # the load moved rearward per m/s² of specific force, m·h/L


def prepare(
    p: BicycleParams, m: Measured, cg_height_m: float | None = None, roll_lever_m: float = 0.0
) -> Prepared:
    # the load moved rearward by speeding up, m·h·a_x/L, never more than 70 % of an axle's load
    transfer = p.mass_kg * cg_height_m * m.ax / p.wheelbase_m if cg_height_m else np.zeros(len(m.t))
    transfer = np.clip(transfer, -0.7 * p.w2_n, 0.7 * p.w1_n)
    u_optical = np.nan_to_num(m.u_optical)
    return Prepared(
        params=p,
        t=m.t,
        dt=m.dt,
        u_optical=u_optical,
        u=np.maximum(u_optical, U_MIN_MPS),  # the optical speed: no scale error, no lag
        delta=np.nan_to_num(m.delta),
        delta_late="steer" in m.vehicle_roles,
        r=m.r,
        r_late="yaw_rate" in m.vehicle_roles,
        c1_nominal=p.c1n * (p.w1_n - transfer),
        c2_nominal=p.c2n * (p.w2_n + transfer),
        sway=m.p * roll_lever_m,
        transfer_kg_s2=p.mass_kg * cg_height_m / p.wheelbase_m if cg_height_m else 0.0,
    )


def simulate(
    p: BicycleParams,
    m: Measured,
    d_m: float,
    mods: Mods = NOMINAL,
    cg_height_m: float | None = None,
    roll_lever_m: float = 0.0,
) -> Simulated:
    """The model on the drive ``m`` (``run_model`` on a ``prepare``d drive, for one run)."""
    return run_model(prepare(p, m, cg_height_m, roll_lever_m), d_m, mods)


def run_model(w: Prepared, d_m: float, mods: Mods = NOMINAL) -> Simulated:
    """The model on a ``prepare``d drive with ``mods``: every step of ``run_model_reference`` in one
    compiled loop (a fit runs it a thousand times; the numpy version spends most of its time
    between the arrays)."""
    p = w.params
    beta, yaw, r_meas, ay, speed_reading = _run_steps(
        w.t,
        w.u_optical,
        w.u,
        w.delta,
        w.delta_late,
        w.r,
        w.r_late,
        w.c1_nominal,
        w.c2_nominal,
        w.sway,
        w.dt,
        np.array(
            [
                p.c1n,
                p.c2n,
                p.a_m,
                p.b_m,
                p.mass_kg,
                p.yaw_inertia_kgm2,
                w.transfer_kg_s2,
                d_m + mods.d_error_m - p.b_m,
                *(getattr(mods, name) for name in _MOD_FIELDS),
                p.g,
            ]
        ),
    )
    return Simulated(beta=beta, r=yaw, u=w.u, r_measured=r_meas, ay=ay, speed_reading=speed_reading)


_MOD_FIELDS = (  # what ``_run_steps`` reads from k[8:]: Mods' fields in this order
    "yaw_bias_radps",
    "yaw_scale",
    "steer_offset_rad",
    "ratio_error",
    "c1n_factor",
    "c2n_factor",
    "turn_force_g",
    "misalignment_rad",
    "d_error_m",
    "speed_scale",
    "latency_s",
    "slope_sin_mps2",
    "slope_cos_mps2",
    "softening1_per_mps4",
    "softening2_per_mps4",
    "roll_steer_rad_per_mps2",
    "ply_rad",
)


def run_model_reference(w: Prepared, d_m: float, mods: Mods = NOMINAL) -> Simulated:
    """``run_model`` in numpy around ``step_lateral``: the reference ``run_model``'s one compiled loop is
    held to (tests/test_gap.py)."""
    p, t = w.params, w.t
    late = mods.latency_s
    delta = _shift(w.delta, t, late) if w.delta_late else w.delta
    delta = (delta - mods.steer_offset_rad) / (1.0 + mods.ratio_error)
    r_meas = _shift(w.r, t, late) if w.r_late else w.r
    r_meas = (r_meas - mods.yaw_bias_radps) / (1.0 + mods.yaw_scale)
    ay = np.nan_to_num(w.u_optical * r_meas)  # steady lateral acceleration u·r
    # the vehicle's speed signal; a head yawed by ψ reads the speed cos ψ low, so the true speed
    # the vehicle's signal measures is the optical one over cos ψ
    speed_reading = (1.0 + mods.speed_scale) * _shift(w.u_optical, t, -late) / math.cos(mods.misalignment_rad)
    n = len(t)
    c1, c2, lateral = w.c1_nominal, w.c2_nominal, np.zeros(n)
    specific = ay  # what the body feels sideways, and rolls with: a_y less a slope's gravity
    if mods.slope_sin_mps2 or mods.slope_cos_mps2:
        heading = np.cumsum(np.nan_to_num(r_meas)) * w.dt
        lateral = mods.slope_sin_mps2 * np.sin(heading) + mods.slope_cos_mps2 * np.cos(heading)
        # its gravity along the heading (the lateral component's turned by a quarter) moves load
        # between the axles as braking does, m·h·(a_x − g_x)/L with a_x the speed's own
        g_x = mods.slope_cos_mps2 * np.sin(heading) - mods.slope_sin_mps2 * np.cos(heading)
        rearward = -w.transfer_kg_s2 * g_x
        c1, c2 = c1 - p.c1n * rearward, c2 + p.c2n * rearward
        specific = ay - lateral
    c1, c2 = c1 * mods.c1n_factor, c2 * mods.c2n_factor
    if mods.softening1_per_mps4 or mods.softening2_per_mps4:
        ay2 = ay * ay
        c1 = c1 * np.clip(1.0 - mods.softening1_per_mps4 * ay2, 0.2, 2.0)
        c2 = c2 * np.clip(1.0 - mods.softening2_per_mps4 * ay2, 0.2, 2.0)
    delta2 = mods.roll_steer_rad_per_mps2 * ay + mods.ply_rad if mods.roll_steer_rad_per_mps2 else None
    if mods.turn_force_g:
        # a force that follows the body's lean (camber thrust as it rolls): on a slope the body
        # leans with the lateral specific force, so also on a straight across the slope
        lateral = lateral + p.g * mods.turn_force_g * np.tanh(specific / TURN_AY_MPS2)
    v_cg, yaw = step_lateral(
        w.u,
        np.ascontiguousarray(c1, dtype=np.float64),
        np.ascontiguousarray(c2, dtype=np.float64),
        np.ascontiguousarray(delta, dtype=np.float64),
        np.ascontiguousarray(delta2 if delta2 is not None else np.full(n, mods.ply_rad), dtype=np.float64),
        lateral,
        p.a_m,
        p.b_m,
        p.mass_kg,
        p.yaw_inertia_kgm2,
        w.dt,
    )
    x_sensor = d_m + mods.d_error_m - p.b_m
    beta = np.arctan2(v_cg + yaw * x_sensor - w.sway, w.u) - mods.misalignment_rad
    return Simulated(beta=beta, r=yaw, u=w.u, r_measured=r_meas, ay=ay, speed_reading=speed_reading)


def _compiled(function: Any) -> Any:
    """numba's ``njit``, its machine code cached beside this file."""
    return njit(cache=True)(function)


def _compiled_fast(function: Any) -> Any:
    """``_compiled`` allowed to reorder and fuse arithmetic (not to assume away NaN or to
    approximate sin, tanh or atan2): a run agrees with ``run_model_reference`` to about 1e-15."""
    return njit(cache=True, fastmath={"nsz", "arcp", "contract", "reassoc"})(function)


@_compiled
def step_lateral(
    u: np.ndarray,
    c1: np.ndarray,
    c2: np.ndarray,
    delta1: np.ndarray,
    delta2: np.ndarray,
    lateral: np.ndarray,
    a: float,
    b: float,
    mass: float,
    iz: float,
    h: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Lateral velocity at the CG and yaw rate of the linear bicycle model, step by step:

        ẋ = M(u)·x + f,   M = −[[(C1+C2)/(m·u), (a·C1 − b·C2)/(m·u) + u],
                                [(a·C1 − b·C2)/(I_z·u), (a²·C1 + b²·C2)/(I_z·u)]],
        f = [(C1·δ1 + C2·δ2)/m + g_y, (a·C1·δ1 − b·C2·δ2)/I_z]

    with the inputs held over each step: x ← exp(M·h)·x + ∫₀ʰ exp(M·s) ds·f, both as their
    series to the fourth power of M·h (tests/test_gap.py holds it to scipy's expm). The start
    is the steady state of the first step's inputs."""
    n = len(u)
    v_out = np.empty(n)
    r_out = np.empty(n)
    v = 0.0
    r = 0.0
    for k in range(n):
        uk, k1, k2 = u[k], c1[k], c2[k]
        m00 = -(k1 + k2) / (mass * uk)
        m01 = -(a * k1 - b * k2) / (mass * uk) - uk
        m10 = -(a * k1 - b * k2) / (iz * uk)
        m11 = -(a * a * k1 + b * b * k2) / (iz * uk)
        f0 = (k1 * delta1[k] + k2 * delta2[k]) / mass + lateral[k]
        f1 = (a * k1 * delta1[k] - b * k2 * delta2[k]) / iz
        if k == 0:
            det = m00 * m11 - m01 * m10
            if abs(det) > 1e-12:  # x0 = −M⁻¹·f
                v = -(m11 * f0 - m01 * f1) / det
                r = -(-m10 * f0 + m00 * f1) / det
        v_out[k] = v
        r_out[k] = r
        # A = M·h and its powers
        a00, a01, a10, a11 = m00 * h, m01 * h, m10 * h, m11 * h
        b00, b01 = a00 * a00 + a01 * a10, a00 * a01 + a01 * a11  # A²
        b10, b11 = a10 * a00 + a11 * a10, a10 * a01 + a11 * a11
        c00, c01 = b00 * a00 + b01 * a10, b00 * a01 + b01 * a11  # A³
        c10, c11 = b10 * a00 + b11 * a10, b10 * a01 + b11 * a11
        d00, d01 = c00 * a00 + c01 * a10, c00 * a01 + c01 * a11  # A⁴
        d10, d11 = c10 * a00 + c11 * a10, c10 * a01 + c11 * a11
        e00 = 1.0 + a00 + b00 / 2.0 + c00 / 6.0 + d00 / 24.0  # exp(A)
        e01 = a01 + b01 / 2.0 + c01 / 6.0 + d01 / 24.0
        e10 = a10 + b10 / 2.0 + c10 / 6.0 + d10 / 24.0
        e11 = 1.0 + a11 + b11 / 2.0 + c11 / 6.0 + d11 / 24.0
        g00 = h * (1.0 + a00 / 2.0 + b00 / 6.0 + c00 / 24.0)  # h·(I + A/2 + A²/6 + A³/24)
        g01 = h * (a01 / 2.0 + b01 / 6.0 + c01 / 24.0)
        g10 = h * (a10 / 2.0 + b10 / 6.0 + c10 / 24.0)
        g11 = h * (1.0 + a11 / 2.0 + b11 / 6.0 + c11 / 24.0)
        v, r = (
            e00 * v + e01 * r + g00 * f0 + g01 * f1,
            e10 * v + e11 * r + g10 * f0 + g11 * f1,
        )
    return v_out, r_out


@_compiled_fast
def _interp_at(values: np.ndarray, t: np.ndarray, x: float, j: int) -> tuple[float, int]:
    """np.interp(x, t, values), its search started at ``j`` (x only grows from one call to the
    next): the value and where the search ended."""
    n = len(t)
    if x <= t[0]:
        return values[0], j
    if x >= t[n - 1]:
        return values[n - 1], j
    while t[j + 1] <= x:
        j += 1
    if x == t[j]:
        return values[j], j
    slope = (values[j + 1] - values[j]) / (t[j + 1] - t[j])
    out = slope * (x - t[j]) + values[j]
    if math.isnan(out):
        out = slope * (x - t[j + 1]) + values[j + 1]
        if math.isnan(out) and values[j] == values[j + 1]:
            out = values[j]
    return out, j


@_compiled_fast
def _run_steps(
    t: np.ndarray,
    u_optical: np.ndarray,
    u: np.ndarray,
    delta_read: np.ndarray,
    delta_late: bool,
    r_read: np.ndarray,
    r_late: bool,
    c1_nominal: np.ndarray,
    c2_nominal: np.ndarray,
    sway: np.ndarray,
    h: float,
    k: np.ndarray,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``run_model_reference`` step by step: the car's numbers and the mods in ``k`` (c1n, c2n, a, b,
    mass, I_z, the rearward transfer, the sensor's x, then Mods' fields in their order, then g). Returns
    the sideslip at the sensor, the yaw rate, the measured yaw rate, a_y and the speed reading."""
    c1n, c2n, a, b, mass, iz, transfer, x_sensor = k[0], k[1], k[2], k[3], k[4], k[5], k[6], k[7]
    yaw_bias, yaw_scale, steer_offset, ratio_error = k[8], k[9], k[10], k[11]
    c1n_factor, c2n_factor, turn_force, misalignment = k[12], k[13], k[14], k[15]
    speed_scale, late, slope_sin, slope_cos = k[17], k[18], k[19], k[20]  # k[16]: d's, in x_sensor
    softening1, softening2, roll_steer, ply, g = k[21], k[22], k[23], k[24], k[25]
    n = len(u)
    beta = np.empty(n)
    r_out = np.empty(n)
    r_meas_out = np.empty(n)
    ay_out = np.empty(n)
    speed_out = np.empty(n)
    sloped = slope_sin != 0.0 or slope_cos != 0.0
    softened = softening1 != 0.0 or softening2 != 0.0
    cos_misalignment = math.cos(misalignment)
    j_late, j_early = 0, 0
    turned = 0.0  # the cumulative sum of the measured yaw rate: the heading over h
    v = 0.0
    r = 0.0
    for i in range(n):
        delta = delta_read[i]
        r_meas = r_read[i]
        if late != 0.0:
            if delta_late:
                delta, j_late = _interp_at(delta_read, t, t[i] + late, j_late)
            if r_late:
                r_meas, j_late = _interp_at(r_read, t, t[i] + late, j_late)
        delta = (delta - steer_offset) / (1.0 + ratio_error)
        r_meas = (r_meas - yaw_bias) / (1.0 + yaw_scale)
        ay = u_optical[i] * r_meas
        if math.isnan(ay):
            ay = 0.0
        speed = u_optical[i]
        if late != 0.0:
            speed, j_early = _interp_at(u_optical, t, t[i] - late, j_early)
        speed_out[i] = (1.0 + speed_scale) * speed / cos_misalignment
        c1, c2, lateral, specific = c1_nominal[i], c2_nominal[i], 0.0, ay
        if sloped:
            if not math.isnan(r_meas):
                turned += r_meas
            heading = turned * h
            sin, cos = math.sin(heading), math.cos(heading)
            lateral = slope_sin * sin + slope_cos * cos
            rearward = -transfer * (slope_cos * sin - slope_sin * cos)
            c1, c2 = c1 - c1n * rearward, c2 + c2n * rearward
            specific = ay - lateral
        c1, c2 = c1 * c1n_factor, c2 * c2n_factor
        if softened:
            ay2 = ay * ay
            c1 = c1 * min(max(1.0 - softening1 * ay2, 0.2), 2.0)
            c2 = c2 * min(max(1.0 - softening2 * ay2, 0.2), 2.0)
        delta2 = roll_steer * ay + ply if roll_steer != 0.0 else ply
        if turn_force != 0.0:
            lateral = lateral + g * turn_force * math.tanh(specific / TURN_AY_MPS2)
        uk = u[i]
        m00 = -(c1 + c2) / (mass * uk)
        m01 = -(a * c1 - b * c2) / (mass * uk) - uk
        m10 = -(a * c1 - b * c2) / (iz * uk)
        m11 = -(a * a * c1 + b * b * c2) / (iz * uk)
        f0 = (c1 * delta + c2 * delta2) / mass + lateral
        f1 = (a * c1 * delta - b * c2 * delta2) / iz
        if i == 0:
            det = m00 * m11 - m01 * m10
            if abs(det) > 1e-12:  # x0 = −M⁻¹·f
                v = -(m11 * f0 - m01 * f1) / det
                r = -(-m10 * f0 + m00 * f1) / det
        beta[i] = math.atan2(v + r * x_sensor - sway[i], uk) - misalignment
        r_out[i] = r
        r_meas_out[i] = r_meas
        ay_out[i] = ay
        # as step_lateral: A = M·h, exp(A) and h·(I + A/2 + A²/6 + A³/24) by their series (written
        # out again on purpose: step_lateral is run_model_reference's, and a reference that shared this
        # code could not catch a fault in it)
        a00, a01, a10, a11 = m00 * h, m01 * h, m10 * h, m11 * h
        b00, b01 = a00 * a00 + a01 * a10, a00 * a01 + a01 * a11  # A²
        b10, b11 = a10 * a00 + a11 * a10, a10 * a01 + a11 * a11
        c00, c01 = b00 * a00 + b01 * a10, b00 * a01 + b01 * a11  # A³
        c10, c11 = b10 * a00 + b11 * a10, b10 * a01 + b11 * a11
        d00, d01 = c00 * a00 + c01 * a10, c00 * a01 + c01 * a11  # A⁴
        d10, d11 = c10 * a00 + c11 * a10, c10 * a01 + c11 * a11
        e00 = 1.0 + a00 + b00 / 2.0 + c00 / 6.0 + d00 / 24.0
        e01 = a01 + b01 / 2.0 + c01 / 6.0 + d01 / 24.0
        e10 = a10 + b10 / 2.0 + c10 / 6.0 + d10 / 24.0
        e11 = 1.0 + a11 + b11 / 2.0 + c11 / 6.0 + d11 / 24.0
        g00 = h * (1.0 + a00 / 2.0 + b00 / 6.0 + c00 / 24.0)
        g01 = h * (a01 / 2.0 + b01 / 6.0 + c01 / 24.0)
        g10 = h * (a10 / 2.0 + b10 / 6.0 + c10 / 24.0)
        g11 = h * (1.0 + a11 / 2.0 + b11 / 6.0 + c11 / 24.0)
        v, r = (
            e00 * v + e01 * r + g00 * f0 + g01 * f1,
            e10 * v + e11 * r + g10 * f0 + g11 * f1,
        )
    return beta, r_out, r_meas_out, ay_out, speed_out


def deg(x: float) -> float:
    return x * 180.0 / math.pi
