"""The motion filter written to be read: the model of ``app.estimate.motion_model`` on filterpy's
``KalmanFilter``, F, Q and H formed as matrices each step and updated jointly (Joseph form).

The pipeline runs ``app.estimate.compiled.CompiledMotionFilter``: the same steps compiled with
numba, tested equal to this one within 1e-9 on every estimate of whole drives.
"""

import math
from collections.abc import Mapping, Sequence

import numpy as np
from filterpy.kalman import KalmanFilter

from app.config import FilterSettings
from app.estimate.motion_model import (
    HEALTH_ALPHA,
    LATE_TOLERANCE_S,
    MAX_CONSECUTIVE_REJECTS,
    MIN_SPEED_FOR_ANGLE,
    NOISE_ALPHA,
    NOISE_CEILING,
    YAW_TIMEOUT_S,
    FilterCounts,
    H,
    Row,
    angle_innovation,
    full_row,
    transition,
)
from app.records import Estimate, Record


class FilterpyKalman:
    """The reference: filterpy's KalmanFilter, F, Q and H formed as matrices each step."""

    def __init__(self, q_u: float, q_v: float, q_r: float) -> None:
        self.q = (q_u, q_v, q_r)
        self.kf = KalmanFilter(dim_x=6, dim_z=1)

    def reset(self, x: Sequence[float], p_diagonal: Sequence[float]) -> None:
        self.kf.x = np.array(x, dtype=float).reshape(6, 1)
        self.kf.P = np.diag(np.asarray(p_diagonal, dtype=float))

    def predict(self, dt: float) -> None:
        f, q = transition(dt, *self.q)
        self.kf.predict(F=f, Q=q)

    def innovation(self, z: float, h: H) -> tuple[float, float]:
        row = full_row(h)
        return z - float(row @ self.kf.x[:, 0]), float(row @ self.kf.P @ row)

    def update(self, rows: Sequence[Row]) -> None:
        if rows:
            z = np.array([[row[0]] for row in rows])
            h = np.array([full_row(row[1]) for row in rows])
            self.kf.update(z, R=np.diag([row[2] for row in rows]), H=h)

    def value(self, i: int) -> float:
        return float(self.kf.x[i, 0])

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.kf.x[:, 0].copy(), self.kf.P.copy()


class MotionFilter:
    def __init__(
        self,
        settings: FilterSettings,
        sensor_lateral_m: float,
        roles: frozenset[str],
        resolutions: Mapping[str, float] | None = None,
    ) -> None:
        self.settings = settings
        self.roles = roles
        # Noise model: the measured noise of each optical channel (velocity-equivalent, m²/s²),
        # never below the quantisation of one DBC bit (res²/12).
        self.resolutions = resolutions or {}
        sigma2 = settings.sigma_velocity_mps**2
        self.noise_var = {"vx": sigma2, "lateral": sigma2}
        self.has_yaw = "yaw_rate" in roles or "ay" in roles
        # Without yaw information the lateral offset cannot be corrected (r is not observable).
        self.y_s = sensor_lateral_m if self.has_yaw else 0.0
        self._vx_row: H = (1.0, 0.0, -self.y_s)  # optical vx = u − r·y_s
        self.counts = FilterCounts()
        self.q = (settings.q_u, settings.q_v, settings.q_r if self.has_yaw else 0.0)
        self.kalman = FilterpyKalman(*self.q)
        self.health = 1.0
        self._t: float | None = None
        self._t_optical = -math.inf
        self._t_yaw = -math.inf
        self._last_ay: float | None = None
        self._rejects: dict[str, int] = {}  # consecutive gate rejections per sensor
        self._angle = False  # this frame's lateral measurement is the angle
        self.last_dt: float | None = None  # the time the last step predicted over (None: none)
        self.lost_now = False  # the last step lost the car on a sensor (FilterCounts)

    # -- time ------------------------------------------------------------------------------
    def _reset(self) -> None:
        self._t = None
        self._t_optical = -math.inf
        self._t_yaw = -math.inf

    def _initialise(self, record: Record) -> bool:
        s = record.signals
        if "vx" not in s:
            return False
        u = s["vx"]
        if "vy" in s:
            v = s["vy"]
        elif "beta" in s:
            v = u * math.tan(s["beta"])
        else:
            v = 0.0
        r = s.get("yaw_rate", 0.0)
        sigmas = (0.1, 1.0, 0.1, 0.5, 0.05 if self.has_yaw else 0.0, 0.1 if self.has_yaw else 0.0)
        self.kalman.reset((u + r * self.y_s, 0.0, v, 0.0, r, 0.0), [sigma * sigma for sigma in sigmas])
        self._t = record.t
        self.health = 1.0
        return True

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Copies of x (6,) and P (6, 6)."""
        return self.kalman.state()

    @property
    def last_transition(self) -> tuple[np.ndarray, np.ndarray]:
        """F and Q of the last step (identity and zero when it did not predict): the smoother's."""
        return _IDENTITY if self.last_dt is None else transition(self.last_dt, *self.q)

    # -- one frame -------------------------------------------------------------------------
    def step(self, record: Record) -> Estimate | None:
        """Predict to the record's time and update with its measurements."""
        s = record.signals
        optical = "vx" in s or "vy" in s or "beta" in s
        t = record.t
        self.lost_now = False
        if self._t is not None:
            dt = t - self._t
            if dt < -LATE_TOLERANCE_S:
                self.counts.time_jumps += 1
                self.counts.resets += 1
                self._reset()
            elif optical and t - self._t_optical > self.settings.gap_reset_s:
                self.counts.resets += 1
                self._reset()
        if self._t is None:
            if not self._initialise(record):
                return None
            self._t_optical = t
            if "yaw_rate" in s:
                self._t_yaw = t
            return self._estimate(t, None, s.get("ay"))
        dt = t - self._t
        self.last_dt = None  # no time passed, unless predicted below
        if dt < 0:
            self.counts.late_frames += 1
        elif dt > 0:
            self.kalman.predict(dt)
            self.last_dt = dt
            self._t = t
        v_meas = self._update(record)
        if optical:
            self._t_optical = t
        return self._estimate(t, v_meas, s.get("ay"))

    def _update(self, record: Record) -> float | None:
        """Update with every measurement in the record; return the measured v if there was one."""
        s = record.signals
        kalman = self.kalman
        u, v, r = kalman.value(0), kalman.value(2), kalman.value(4)
        u_s = u - r * self.y_s  # the head's own longitudinal velocity
        rows: list[tuple[float, H, float, str]] = []  # (z, H, R, kind)
        if "vx" in s:
            rows.append((s["vx"], self._vx_row, self._variance("vx", "vx", 1.0), "vx"))
        lateral = self._lateral_source(s, u_s)
        self._angle = lateral == "beta"
        v_meas = None
        if lateral == "vy":
            v_meas = s["vy"]
            rows.append((v_meas, _V_ROW, self._variance("lateral", "vy", 1.0), "lateral"))
        elif lateral == "beta":
            beta = s["beta"]
            v_meas = u_s * math.tan(beta)
            n2 = u_s * u_s + v * v
            h = math.atan2(v, u_s)
            jac = (-v / n2, u_s / n2, v * self.y_s / n2)
            if self.settings.sigma_beta_deg is not None:
                variance = math.radians(self.settings.sigma_beta_deg) ** 2
            else:  # the angle's noise is the lateral velocity's over the speed
                variance = self._variance("lateral", "beta", abs(u_s)) / (u_s * u_s)
            # pseudo-measurement: filterpy forms y = z − Hx, the EKF needs y = z − h(x)
            z = angle_innovation(beta, h) + jac[0] * u + jac[1] * v + jac[2] * r
            rows.append((z, jac, variance, "lateral"))
        if "speed" in s:  # a wheel speed is |u| (unsigned): reversing, it reads −u
            row = _MINUS_U_ROW if u < 0.0 and s["speed"] >= 0.0 else _U_ROW
            rows.append((s["speed"], row, self.settings.sigma_speed_mps**2, "speed"))
        if "yaw_rate" in s:
            rows.append((s["yaw_rate"], _R_ROW, self.settings.sigma_yaw_rate_radps**2, "yaw"))
            self._t_yaw = record.t
        elif "ay" in s and "yaw_rate" not in self.roles and u > MIN_SPEED_FOR_ANGLE:
            rows.append((s["ay"] / u, _R_ROW, (self.settings.sigma_ay_mps2 / u) ** 2, "yaw"))
            self._t_yaw = record.t
        self.kalman.update(self._gate(rows))
        return v_meas

    def _lateral_source(self, s: Mapping[str, float], u_s: float) -> str | None:
        source = self.settings.sideslip_source
        if source in ("auto", "beta") and "beta" in s and abs(u_s) > MIN_SPEED_FOR_ANGLE:
            return "beta"
        if source in ("auto", "vy") and "vy" in s:
            return "vy"
        return None

    def _variance(self, kind: str, role: str, speed: float) -> float:
        """Measured noise variance (velocity-equivalent), floored at one DBC bit's quantisation."""
        floor = (self.resolutions.get(role, 0.0) * speed) ** 2 / 12.0
        return max(self.noise_var[kind], floor)

    def _learn_noise(self, kind: str, innovation2: float, hph: float, speed: float) -> None:
        """E[y²] = HPHᵀ + R: follow R from the innovations (velocity-equivalent units)."""
        sample = (innovation2 - hph) * (speed * speed if kind == "lateral" and self._angle else 1.0)
        ceiling = (NOISE_CEILING * self.settings.sigma_velocity_mps) ** 2
        value = self.noise_var[kind] + NOISE_ALPHA * (sample - self.noise_var[kind])
        self.noise_var[kind] = min(max(value, 0.0), ceiling)

    def noise_sigma(self) -> dict[str, float]:
        """The measured noise of the optical channels (standard deviations, m/s)."""
        return {f"{kind}_mps": math.sqrt(value) for kind, value in self.noise_var.items()}

    def _gate(self, rows: list[tuple[float, H, float, str]]) -> list[Row]:
        """Drop measurements whose normalised innovation² exceeds the gate (outliers), unless the
        same sensor was dropped several times running: then the model has lost the car, and the
        sensor is believed. The optical rows' normalised innovation² is the health figure."""
        kalman = self.kalman
        speed = abs(kalman.value(0) - kalman.value(4) * self.y_s)
        kept: list[Row] = []
        optical_nis = []
        for row in rows:
            z, h, r, kind = row
            innovation, hph = kalman.innovation(z, h)
            nis = innovation * innovation / (hph + r)
            if nis > self.settings.innovation_gate:
                if self._rejects.get(kind, 0) < MAX_CONSECUTIVE_REJECTS:
                    self.counts.outliers += 1
                    self._rejects[kind] = self._rejects.get(kind, 0) + 1
                    continue
                lost = f"lost_{kind}"  # the sensor insists: believed, and the car was lost
                setattr(self.counts, lost, getattr(self.counts, lost) + 1)
                self.lost_now = True
            self._rejects[kind] = 0
            kept.append((z, h, r))
            if kind in ("vx", "lateral"):
                optical_nis.append(nis)
                if self.settings.sigma_beta_deg is None or kind == "vx" or not self._angle:
                    self._learn_noise(kind, innovation * innovation, hph, speed)
        if optical_nis:
            self.health += HEALTH_ALPHA * (sum(optical_nis) / len(optical_nis) - self.health)
        return kept

    def _estimate(self, t: float, v_meas: float | None, ay_meas: float | None) -> Estimate:
        kalman = self.kalman
        u, v = kalman.value(0), kalman.value(2)
        n2 = u * u + v * v
        variance = kalman.innovation(0.0, (-v / n2, u / n2, 0.0))[1] if n2 > 0 else 0.0
        sigma = math.sqrt(max(variance, 0.0) * max(1.0, self.health))
        if ay_meas is not None:
            self._last_ay = ay_meas
        yaw_observed = t - self._t_yaw <= YAW_TIMEOUT_S
        r = kalman.value(4) if yaw_observed else None
        ay = u * r if r is not None else self._last_ay
        sideslip_meas = math.atan2(v_meas, u) if v_meas is not None else None
        return Estimate(  # positional: a named tuple made with keywords costs twice as much
            u,
            kalman.value(1),
            v,
            kalman.value(3),
            r,
            kalman.value(5) if yaw_observed else None,
            math.atan2(v, u),
            sigma,
            ay,
            self.health,
            v_meas,
            sideslip_meas,
        )


_IDENTITY = (np.eye(6), np.zeros((6, 6)))


_U_ROW: H = (1.0, 0.0, 0.0)  # measurement rows (coefficients on u, v, r) that never change
_MINUS_U_ROW: H = (-1.0, 0.0, 0.0)
_V_ROW: H = (0.0, 1.0, 0.0)
_R_ROW: H = (0.0, 0.0, 1.0)
