"""The motion filter compiled: ``app.estimate.reference.MotionFilter``'s step as one numba function.

A filtered frame used to cost ~15 µs of plain Python (Kalman predict and scalar updates, the
innovation gate, the learned noise, the estimate), most of it the interpreter's per-operation
cost on a dozen floats. Compiled, the same arithmetic in the same order costs ~2 µs, the call
included (tools/bench.py: the motion filter and the parts). ``MotionFilter`` on filterpy's
``KalmanFilter`` stays the readable reference: tests/test_kalman.py holds every estimate of whole
drives, the counts and the learned noise of this filter to it within 1e-9, and the behaviour
tests of tests/test_estimator.py run on both.

The filter's whole state is one float64 array (layout below), the settings another; absent
signals are NaN (the decoder passes only finite values). ``cache=True`` keeps the machine code
beside this file, so a process compiles it once per install.
"""

import math
from collections.abc import Callable, Mapping
from typing import Any, TypeVar, cast

import numpy as np
from numba import njit

from app.config import FilterSettings
from app.estimate.motion_model import (  # the shared constants: numba compiles them in as they are
    HEALTH_ALPHA,
    LATE_TOLERANCE_S,
    MAX_CONSECUTIVE_REJECTS,
    MIN_SPEED_FOR_ANGLE,
    NOISE_ALPHA,
    NOISE_CEILING,
    YAW_TIMEOUT_S,
    FilterCounts,
    transition,
)
from app.records import Estimate, Record

_F = TypeVar("_F", bound=Callable[..., Any])


def _compiled(function: _F) -> _F:
    """numba's ``njit``, its machine code cached beside this file (typed for mypy)."""
    return cast(_F, njit(cache=True)(function))


# settings: where each sits in the parameter array
_QU, _QV, _QR, _YS, _GAP, _GATE, _SIGMA_V, _SIGMA_BETA, _SIGMA_SPEED, _SIGMA_YAW, _SIGMA_AY = range(11)
_SOURCE, _HAS_YAW, _AY_GIVES_YAW, _RES_VX, _RES_VY, _RES_BETA = range(11, 17)
_N_PARAMS = 17
Array = np.ndarray[Any, np.dtype[Any]]
_SOURCES = {"auto": 0, "beta": 1, "vy": 2}

# state: x (6), P row-major (36), then the filter's bookkeeping
_X, _P = 0, 6
_T, _T_OPTICAL, _T_YAW, _LAST_AY, _HEALTH, _NOISE_VX, _NOISE_LAT = range(42, 49)
_REJECTS = 49  # consecutive gate rejections: vx, lateral, speed, yaw
_ANGLE, _LAST_DT = 53, 54
_COUNTS = 55  # resets, time_jumps, late_frames, outliers, then lost: vx, lateral, speed, yaw
_N_COUNTS = 8
_LOST_NOW = 63  # 1.0 where the last step lost the car on a sensor
_N_STATE = 64
_VX, _LAT, _SPEED, _YAW = range(4)  # the kinds of measurement row
_STEP_ROLES = ("vx", "vy", "beta", "speed", "yaw_rate", "ay")  # _step's arguments after t


class CompiledMotionFilter:
    """``MotionFilter``'s interface (step, counts, health, noise_sigma, state, last_transition)."""

    def __init__(
        self,
        settings: FilterSettings,
        sensor_lateral_m: float,
        roles: frozenset[str],
        resolutions: Mapping[str, float] | None = None,
    ) -> None:
        resolutions = resolutions or {}
        has_yaw = "yaw_rate" in roles or "ay" in roles
        params = np.zeros(_N_PARAMS)
        params[[_QU, _QV, _QR]] = settings.q_u, settings.q_v, settings.q_r if has_yaw else 0.0
        params[_YS] = sensor_lateral_m if has_yaw else 0.0
        params[_GAP], params[_GATE] = settings.gap_reset_s, settings.innovation_gate
        params[_SIGMA_V] = settings.sigma_velocity_mps
        params[_SIGMA_BETA] = math.nan if settings.sigma_beta_deg is None else settings.sigma_beta_deg
        params[_SIGMA_SPEED] = settings.sigma_speed_mps
        params[_SIGMA_YAW], params[_SIGMA_AY] = settings.sigma_yaw_rate_radps, settings.sigma_ay_mps2
        params[_SOURCE] = _SOURCES[settings.sideslip_source]
        params[_HAS_YAW], params[_AY_GIVES_YAW] = has_yaw, "yaw_rate" not in roles
        params[[_RES_VX, _RES_VY, _RES_BETA]] = [resolutions.get(r, 0.0) for r in ("vx", "vy", "beta")]
        self._params = params
        self.q = (float(params[_QU]), float(params[_QV]), float(params[_QR]))
        self._state = np.zeros(_N_STATE)
        self._state[_T] = math.nan
        self._state[[_T_OPTICAL, _T_YAW]] = -math.inf
        self._state[[_LAST_AY, _LAST_DT]] = math.nan
        self._state[_HEALTH] = 1.0
        self._state[[_NOISE_VX, _NOISE_LAT]] = settings.sigma_velocity_mps**2
        _prepare(self._state.copy(), params)

    def step(self, record: Record) -> Estimate | None:
        """Predict to the record's time and update with its measurements."""
        get, nan = record.signals.get, math.nan
        out = _step(
            self._state,
            self._params,
            record.t,
            get("vx", nan),
            get("vy", nan),
            get("beta", nan),
            get("speed", nan),
            get("yaw_rate", nan),
            get("ay", nan),
        )
        return None if out is None else estimate_of(out)

    def restart(self) -> None:
        """The next record starts the filter afresh: another drive follows."""
        _reset(self._state)

    def steps(self, t: Array, values: Mapping[str, Array]) -> tuple[Array, Array, Array]:
        """``step`` over many records in one compiled loop: ``values`` role -> column (NaN where
        a record has none). Returns which records gave an estimate, the estimates' fields as rows
        (NaN where ``Estimate`` has None), and at which records the filter lost the car."""
        n = len(t)
        nan = np.full(n, math.nan)
        vx, vy, beta, speed, yaw_rate, ay = (
            np.ascontiguousarray(values.get(role, nan), np.float64) for role in _STEP_ROLES
        )
        out = np.empty((n, len(Estimate._fields)))
        valid, lost = np.zeros(n, np.bool_), np.zeros(n, np.bool_)
        t = np.ascontiguousarray(t, np.float64)
        _steps(self._state, self._params, t, vx, vy, beta, speed, yaw_rate, ay, out, valid, lost)
        return valid, out, lost

    @property
    def lost_now(self) -> bool:
        """The last step lost the car on a sensor (``FilterCounts``)."""
        return bool(self._state[_LOST_NOW] != 0.0)

    @property
    def counts(self) -> FilterCounts:
        return FilterCounts(*self._state[_COUNTS : _COUNTS + _N_COUNTS].astype(int).tolist())

    @property
    def health(self) -> float:
        return float(self._state[_HEALTH])

    def noise_sigma(self) -> dict[str, float]:
        """The measured noise of the optical channels (standard deviations, m/s)."""
        return {
            "vx_mps": math.sqrt(self._state[_NOISE_VX]),
            "lateral_mps": math.sqrt(self._state[_NOISE_LAT]),
        }

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Copies of x (6,) and P (6, 6)."""
        return self._state[_X:_P].copy(), self._state[_P : _P + 36].reshape(6, 6).copy()

    @property
    def last_transition(self) -> tuple[np.ndarray, np.ndarray]:
        """F and Q of the last step (identity and zero when it did not predict): the smoother's."""
        dt = float(self._state[_LAST_DT])
        return (np.eye(6), np.zeros((6, 6))) if math.isnan(dt) else transition(dt, *self.q)


def estimate_of(fields: "tuple[float, ...] | list[float]") -> Estimate:
    """The Estimate of a step's fields (NaN: None)."""
    u, u_dot, v, v_dot, r, r_dot, sideslip, sigma, ay, health, v_meas, sideslip_meas = fields
    return Estimate(
        u,
        u_dot,
        v,
        v_dot,
        None if r != r else r,  # NaN: unobserved
        None if r_dot != r_dot else r_dot,
        sideslip,
        sigma,
        None if ay != ay else ay,
        health,
        None if v_meas != v_meas else v_meas,
        None if sideslip_meas != sideslip_meas else sideslip_meas,
    )


def _prepare(scratch: Array, params: Array) -> None:
    """Compile the step (or load it from the cache: ~0.4 s) now, not at a drive's first frame,
    and for floats only: a signal that arrives as an int is converted, never compiled for
    mid-drive (the first compilation takes seconds)."""
    dispatcher: Any = _step
    if not hasattr(dispatcher, "signatures"):
        return  # NUMBA_DISABLE_JIT=1: the functions run as plain Python (to debug them)
    if not dispatcher.signatures:
        _step(scratch, params, 0.0, 1.0, 0.0, 0.0, 1.0, 0.0, 0.0)
        dispatcher.disable_compile()


# -- the compiled step: MotionFilter.step, its helpers in the same order ------------------------


@_compiled
def _step(
    s: Array, c: Array, t: float, vx: float, vy: float, beta: float, speed: float, yaw_rate: float, ay: float
) -> tuple[float, ...] | None:
    optical = vx == vx or vy == vy or beta == beta
    s[_LOST_NOW] = 0.0
    if s[_T] == s[_T]:
        dt = t - s[_T]
        if dt < -LATE_TOLERANCE_S:
            s[_COUNTS + 1] += 1.0
            s[_COUNTS] += 1.0
            _reset(s)
        elif optical and t - s[_T_OPTICAL] > c[_GAP]:
            s[_COUNTS] += 1.0
            _reset(s)
    if s[_T] != s[_T]:
        if not _initialise(s, c, t, vx, vy, beta, yaw_rate):
            return None
        s[_T_OPTICAL] = t
        if yaw_rate == yaw_rate:
            s[_T_YAW] = t
        return _estimate(s, t, math.nan, ay)
    dt = t - s[_T]
    s[_LAST_DT] = math.nan
    if dt < 0:
        s[_COUNTS + 2] += 1.0
    elif dt > 0:
        _predict(s, c, dt)
        s[_LAST_DT] = dt
        s[_T] = t
    v_meas = _update(s, c, t, vx, vy, beta, speed, yaw_rate, ay)
    if optical:
        s[_T_OPTICAL] = t
    return _estimate(s, t, v_meas, ay)


@_compiled
def _steps(
    s: Array,
    c: Array,
    t: Array,
    vx: Array,
    vy: Array,
    beta: Array,
    speed: Array,
    yaw_rate: Array,
    ay: Array,
    out: Array,
    valid: Array,
    lost: Array,
) -> None:
    for k in range(len(t)):
        result = _step(s, c, t[k], vx[k], vy[k], beta[k], speed[k], yaw_rate[k], ay[k])
        lost[k] = s[_LOST_NOW] != 0.0
        if result is not None:
            valid[k] = True
            for j, value in enumerate(result):
                out[k, j] = value


@_compiled
def _reset(s: Array) -> None:
    s[_T] = math.nan
    s[_T_OPTICAL] = -math.inf
    s[_T_YAW] = -math.inf


@_compiled
def _initialise(s: Array, c: Array, t: float, vx: float, vy: float, beta: float, yaw_rate: float) -> bool:
    if vx != vx:
        return False
    u = vx
    if vy == vy:
        v = vy
    elif beta == beta:
        v = u * math.tan(beta)
    else:
        v = 0.0
    r = yaw_rate if yaw_rate == yaw_rate else 0.0
    has_yaw = c[_HAS_YAW] != 0.0
    sigmas = (0.1, 1.0, 0.1, 0.5, 0.05 if has_yaw else 0.0, 0.1 if has_yaw else 0.0)
    x0 = (u + r * c[_YS], 0.0, v, 0.0, r, 0.0)
    for i in range(6):
        s[_X + i] = x0[i]
    for k in range(36):
        s[_P + k] = 0.0
    for i in range(6):
        s[_P + 7 * i] = sigmas[i] * sigmas[i]
    s[_T] = t
    s[_HEALTH] = 1.0
    return True


@_compiled
def _predict(s: Array, c: Array, dt: float) -> None:
    """x = F·x, P = F·P·Fᵀ + Q, per 2×2 block of the [value, rate] pairs: a value's row and
    column gain dt × its rate's; Q adds to the diagonal blocks (``app.estimate.motion_model.transition``)."""
    s[0] += dt * s[1]
    s[2] += dt * s[3]
    s[4] += dt * s[5]
    p = s[_P : _P + 36]
    cube, square = dt**3 / 3.0, dt * dt / 2.0
    for a in range(3):  # the diagonal blocks: value a, rate a + 1 (a = 0, 2, 4)
        i, q = 2 * a, c[_QU + a]
        n01 = p[6 * i + i + 1] + dt * p[6 * (i + 1) + i + 1]
        p[7 * i] = p[7 * i] + dt * p[6 * i + i + 1] + dt * n01 + q * cube
        p[6 * i + i + 1] = p[6 * (i + 1) + i] = n01 + q * square
        p[7 * (i + 1)] += q * dt
    for a in range(3):  # the off-diagonal blocks, upper triangle, mirrored
        for b in range(a + 1, 3):
            i, j = 2 * a, 2 * b
            n_ij1 = p[6 * i + j + 1] + dt * p[6 * (i + 1) + j + 1]  # value a, rate b
            n_ij = p[6 * i + j] + dt * p[6 * (i + 1) + j] + dt * n_ij1
            n_i1j = p[6 * (i + 1) + j] + dt * p[6 * (i + 1) + j + 1]  # rate a, value b
            p[6 * i + j] = p[6 * j + i] = n_ij
            p[6 * i + j + 1] = p[6 * (j + 1) + i] = n_ij1
            p[6 * (i + 1) + j] = p[6 * j + i + 1] = n_i1j


@_compiled
def _innovation(s: Array, z: float, hu: float, hv: float, hr: float) -> tuple[float, float]:
    """(z − H·x, H·P·Hᵀ) at the current state."""
    p = s[_P : _P + 36]
    hph = (
        hu * (p[0] * hu + p[2] * hv + p[4] * hr)
        + hv * (p[12] * hu + p[14] * hv + p[16] * hr)
        + hr * (p[24] * hu + p[26] * hv + p[28] * hr)
    )
    return z - (hu * s[0] + hv * s[2] + hr * s[4]), hph


@_compiled
def _scalar_update(s: Array, z: float, hu: float, hv: float, hr: float, r: float) -> None:
    """K = P·Hᵀ/S, x += K·y, P −= K·(P·Hᵀ)ᵀ on the upper triangle, mirrored."""
    p = s[_P : _P + 36]
    ph = np.empty(6)
    for i in range(6):
        ph[i] = p[6 * i] * hu + p[6 * i + 2] * hv + p[6 * i + 4] * hr
    total = hu * ph[0] + hv * ph[2] + hr * ph[4] + r
    y = z - (hu * s[0] + hv * s[2] + hr * s[4])
    k = ph / total
    for i in range(6):
        s[_X + i] += k[i] * y
    for i in range(6):
        for j in range(i, 6):
            value = p[6 * j + i] - k[i] * ph[j]
            p[6 * i + j] = value
            p[6 * j + i] = value


@_compiled
def _variance(s: Array, kind: int, resolution: float, speed: float) -> float:
    """Measured noise variance (velocity-equivalent), floored at one DBC bit's quantisation."""
    floor = (resolution * speed) ** 2 / 12.0
    return float(max(s[_NOISE_VX + kind], floor))


@_compiled
def _update(
    s: Array, c: Array, t: float, vx: float, vy: float, beta: float, speed: float, yaw_rate: float, ay: float
) -> float:
    """Update with every measurement of the frame; return the measured v (NaN: none)."""
    u, v, r = s[0], s[2], s[4]
    y_s = c[_YS]
    u_s = u - r * y_s
    rows = np.empty((5, 6))  # z, hu, hv, hr, R, kind
    n = 0
    if vx == vx:
        _put(rows, n, vx, 1.0, 0.0, -y_s, _variance(s, _VX, c[_RES_VX], 1.0), _VX)
        n += 1
    source = c[_SOURCE]
    lateral = 0  # 1: the angle, 2: vy
    if source != 2 and beta == beta and abs(u_s) > MIN_SPEED_FOR_ANGLE:
        lateral = 1
    elif source != 1 and vy == vy:
        lateral = 2
    s[_ANGLE] = 1.0 if lateral == 1 else 0.0
    v_meas = math.nan
    if lateral == 2:
        v_meas = vy
        _put(rows, n, vy, 0.0, 1.0, 0.0, _variance(s, _LAT, c[_RES_VY], 1.0), _LAT)
        n += 1
    elif lateral == 1:
        v_meas = u_s * math.tan(beta)
        n2 = u_s * u_s + v * v
        h = math.atan2(v, u_s)
        j0, j1, j2 = -v / n2, u_s / n2, v * y_s / n2
        if c[_SIGMA_BETA] == c[_SIGMA_BETA]:
            variance = math.radians(c[_SIGMA_BETA]) ** 2
        else:  # the angle's noise is the lateral velocity's over the speed
            variance = _variance(s, _LAT, c[_RES_BETA], abs(u_s)) / (u_s * u_s)
        # pseudo-measurement: y = z − h(x) as y = z' − H·x, z − h modulo 180° (angle_innovation)
        d = beta - h
        d -= math.pi * math.floor(d / math.pi + 0.5)
        _put(rows, n, d + j0 * u + j1 * v + j2 * r, j0, j1, j2, variance, _LAT)
        n += 1
    if speed == speed:
        hu = -1.0 if u < 0.0 and speed >= 0.0 else 1.0  # a wheel speed is |u|: reversing reads it so
        _put(rows, n, speed, hu, 0.0, 0.0, c[_SIGMA_SPEED] ** 2, _SPEED)
        n += 1
    if yaw_rate == yaw_rate:
        _put(rows, n, yaw_rate, 0.0, 0.0, 1.0, c[_SIGMA_YAW] ** 2, _YAW)
        n += 1
        s[_T_YAW] = t
    elif ay == ay and c[_AY_GIVES_YAW] != 0.0 and u > MIN_SPEED_FOR_ANGLE:
        _put(rows, n, ay / u, 0.0, 0.0, 1.0, (c[_SIGMA_AY] / u) ** 2, _YAW)
        n += 1
        s[_T_YAW] = t
    kept = _gate(s, c, rows, n)
    for i in range(n):
        if kept[i]:
            _scalar_update(s, rows[i, 0], rows[i, 1], rows[i, 2], rows[i, 3], rows[i, 4])
    return v_meas


@_compiled
def _put(rows: Array, n: int, z: float, hu: float, hv: float, hr: float, r: float, kind: int) -> None:
    rows[n, 0], rows[n, 1], rows[n, 2], rows[n, 3], rows[n, 4], rows[n, 5] = z, hu, hv, hr, r, kind


@_compiled
def _gate(s: Array, c: Array, rows: Array, n: int) -> Array:
    """Which rows to keep: MotionFilter._gate (outliers dropped unless a sensor insists; the
    optical rows' normalised innovation² is the health figure and teaches the noise)."""
    speed = abs(s[0] - s[4] * c[_YS])
    kept = np.zeros(n, dtype=np.bool_)
    nis_sum, nis_n = 0.0, 0
    for i in range(n):
        z, hu, hv, hr, r, kind = rows[i]
        k = int(kind)
        innovation, hph = _innovation(s, z, hu, hv, hr)
        nis = innovation * innovation / (hph + r)
        if nis > c[_GATE]:
            if s[_REJECTS + k] < MAX_CONSECUTIVE_REJECTS:
                s[_COUNTS + 3] += 1.0
                s[_REJECTS + k] += 1.0
                continue
            s[_COUNTS + 4 + k] += 1.0  # the sensor insists: believed, and the car was lost
            s[_LOST_NOW] = 1.0
        s[_REJECTS + k] = 0.0
        kept[i] = True
        if k in (_VX, _LAT):
            nis_sum += nis
            nis_n += 1
            angle = s[_ANGLE] != 0.0
            if c[_SIGMA_BETA] != c[_SIGMA_BETA] or k == _VX or not angle:
                _learn_noise(s, c, k, innovation * innovation, hph, speed, angle)
    if nis_n:
        s[_HEALTH] += HEALTH_ALPHA * (nis_sum / nis_n - s[_HEALTH])
    return kept


@_compiled
def _learn_noise(
    s: Array, c: Array, kind: int, innovation2: float, hph: float, speed: float, angle: bool
) -> None:
    """E[y²] = HPHᵀ + R: follow R from the innovations (velocity-equivalent units)."""
    sample = (innovation2 - hph) * (speed * speed if kind == _LAT and angle else 1.0)
    ceiling = (NOISE_CEILING * c[_SIGMA_V]) ** 2
    value = s[_NOISE_VX + kind] + NOISE_ALPHA * (sample - s[_NOISE_VX + kind])
    s[_NOISE_VX + kind] = min(max(value, 0.0), ceiling)


@_compiled
def _estimate(s: Array, t: float, v_meas: float, ay_meas: float) -> tuple[float, ...]:
    u, v = s[0], s[2]
    n2 = u * u + v * v
    variance = _innovation(s, 0.0, -v / n2, u / n2, 0.0)[1] if n2 > 0 else 0.0
    sigma = math.sqrt(max(variance, 0.0) * max(1.0, s[_HEALTH]))
    if ay_meas == ay_meas:
        s[_LAST_AY] = ay_meas
    yaw_observed = t - s[_T_YAW] <= YAW_TIMEOUT_S
    r = s[4] if yaw_observed else math.nan
    ay = u * r if yaw_observed else s[_LAST_AY]
    sideslip_meas = math.atan2(v_meas, u) if v_meas == v_meas else math.nan
    r_dot = s[5] if yaw_observed else math.nan
    return (u, s[1], v, s[3], r, r_dot, math.atan2(v, u), sigma, ay, s[_HEALTH], v_meas, sideslip_meas)
