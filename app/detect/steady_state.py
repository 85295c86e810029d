"""Is the car in steady cornering? The gate in front of the crossing detector.

The method holds for linear tyres in steady state (paper §2–3): lateral acceleration below
~4 m/s², slow speed changes, no steering transients, and the car must actually be turning
(driving straight, the sideslip is ~0 and its sign is noise). Each failed condition becomes a
Reason, with its words, that the dashboard turns into guidance for the driver.
"""

import math

import numpy as np

from app.config import DetectorSettings
from app.records import Direction, Estimate, Reason, SteadyState

STEER_MAX_RAD = 0.125  # wheelbase/radius, the steer a turn asks for: beyond it the bicycle model's small
# angles fail — at 2–3 m/s² the rear slip fell short of a_y/(g·C2n) by 1.4 % at 18 m, 7 % at 12 m and
# 42 % at 6 m on the two-track model (2.70 m: the limit 21.6 m; 0.1 % at 26 m), by 2–17 % under 18 m on
# CommonRoad's car
WHEELBASE_M = 2.7  # where the config gives none


def tightest_curvature(wheelbase_m: float | None) -> float:
    """1/radius of the tightest turn both gates take: eight wheelbases."""
    return STEER_MAX_RAD / (wheelbase_m or WHEELBASE_M)


# what a step decided, for a block of steps (``SteadyStateGate.steps``)
STEADY, HARD, SOFT, SETTLING = range(4)
DIRECTIONS: tuple[Direction | None, ...] = (None, "left", "right")


class SteadyStateGate:
    """Hard limits (speed, a_y, straight driving, sensor) end a steady spell at once; the rate
    limits (sweep, transients) read filtered derivatives that are noisy, so a brief excursion
    drops only its own samples and the spell goes on without settling again."""

    def __init__(self, settings: DetectorSettings, wheelbase_m: float | None = None) -> None:
        self.settings = settings
        self._since: float | None = None  # when every condition began to hold
        self._soft_since: float | None = None  # when a rate limit began to fail
        # the settings' part of the words, written once: the gate words every sample it drops
        s = settings
        self._min_curvature = 1.0 / s.radius_max_m
        self._straight = f"driving straight (radius over {s.radius_max_m:g} m)"
        self._max_curvature = tightest_curvature(wheelbase_m)
        self._tight = f"radius under {1.0 / self._max_curvature:.0f} m (eight wheelbases)"
        self._below = f" m/s below {s.speed_min_mps:g}"
        self._ay_over = f" m/s² > {s.ay_max_mps2:g}"
        self._sweep_over = f" m/s² > {s.sweep_max_mps2:g}"
        self._settle = f" of {s.settle_s:g} s)"

    def step(
        self, t: float, estimate: Estimate, steer_rad: float | None, sensor_problem: str | None
    ) -> SteadyState:
        direction = _direction(estimate, steer_rad)
        hard: list[tuple[Reason, str]]
        soft: list[tuple[Reason, str]]
        if sensor_problem is None and self._all_hold(estimate):
            hard = soft = []
        else:  # the reasons, worded for the driver
            hard = self._hard_reasons(estimate, sensor_problem)
            soft = self._soft_reasons(estimate)
        if self._since is not None and t < self._since:
            self._since = None  # time went backwards
        if hard:
            self._since = self._soft_since = None
            return _not_steady(direction, hard + soft)
        if soft:
            if self._soft_since is None or t < self._soft_since:
                self._soft_since = t
            if t - self._soft_since > self.settings.debounce_s:
                self._since = None
            return _not_steady(direction, soft)
        self._soft_since = None
        if self._since is None:
            self._since = t
        held = t - self._since
        if held < self.settings.settle_s:
            return self._settling(direction, held)
        return _STEADY[direction]

    def steps(
        self, t: np.ndarray, estimates: np.ndarray, steer_rad: np.ndarray, sensor_ok: np.ndarray
    ) -> tuple[list[int], list[int], list[float]]:
        """``step`` over many estimates at once (rows of ``Estimate``'s fields, NaN for None;
        ``steer_rad`` NaN where there is none): for each, what it decided (STEADY, HARD, SOFT,
        SETTLING), its direction (an index into DIRECTIONS) and, when settling, how long the
        conditions have held. ``verdict`` words one of them as ``step`` would."""
        s = self.settings
        u, u_dot, v_dot, r, r_dot, ay = (estimates[:, k] for k in (0, 1, 3, 4, 5, 8))
        with np.errstate(divide="ignore", invalid="ignore"):
            curvature = np.where(~np.isnan(r), np.abs(r) / u, np.abs(ay) / (u * u))
        straight = (u > 0) & (curvature < self._min_curvature)  # NaN: no curvature, no verdict
        tight = (u > 0) & (curvature > self._max_curvature)
        hard = ~sensor_ok | (u < s.speed_min_mps) | (np.abs(ay) > s.ay_max_mps2) | straight | tight
        soft = (
            (np.abs(u_dot) > s.sweep_max_mps2)
            | (np.abs(r_dot) > s.yaw_accel_max_radps2)
            | (np.abs(v_dot) > s.lateral_accel_rate_max_mps2)
        )
        direction = np.zeros(len(t), np.int64)
        for value in (steer_rad, ay, r):  # the last one given wins: yaw rate, then a_y, then steer
            given = np.isfinite(value) & (value != 0)
            direction = np.where(given, np.where(value > 0, 1, 2), direction)
        kinds, held = [], []
        since, soft_since = self._since, self._soft_since
        debounce, settle = s.debounce_s, s.settle_s
        for now, is_hard, is_soft in zip(t.tolist(), hard.tolist(), soft.tolist(), strict=True):
            if since is not None and now < since:
                since = None
            held.append(0.0)
            if is_hard:
                since = soft_since = None
                kinds.append(HARD)
            elif is_soft:
                if soft_since is None or now < soft_since:
                    soft_since = now
                if now - soft_since > debounce:
                    since = None
                kinds.append(SOFT)
            else:
                soft_since = None
                if since is None:
                    since = now
                held[-1] = now - since
                kinds.append(SETTLING if held[-1] < settle else STEADY)
        self._since, self._soft_since = since, soft_since
        return kinds, direction.tolist(), held

    def verdict(
        self,
        kind: int,
        direction: Direction | None,
        estimate: Estimate,
        sensor_problem: str | None,
        held: float,
    ) -> SteadyState:
        """The SteadyState ``step`` gives for a step that ``steps`` decided was ``kind``."""
        if kind == STEADY:
            return _STEADY[direction]
        if kind == SETTLING:
            return self._settling(direction, held)
        soft = self._soft_reasons(estimate)
        return _not_steady(
            direction, self._hard_reasons(estimate, sensor_problem) + soft if kind == HARD else soft
        )

    def _settling(self, direction: Direction | None, held: float) -> SteadyState:
        return SteadyState(False, direction, (f"settling ({held:.1f}{self._settle}",), _SETTLING)

    def _all_hold(self, e: Estimate) -> bool:
        """Every limit of ``_hard_reasons`` and ``_soft_reasons`` holds (the common case, which
        needs no words)."""
        s = self.settings
        if e.u_mps < s.speed_min_mps or abs(e.u_dot_mps2) > s.sweep_max_mps2:
            return False
        if abs(e.v_dot_mps2) > s.lateral_accel_rate_max_mps2:
            return False
        if e.ay_mps2 is not None and abs(e.ay_mps2) > s.ay_max_mps2:
            return False
        if e.r_dot_radps2 is not None and abs(e.r_dot_radps2) > s.yaw_accel_max_radps2:
            return False
        curvature = _curvature(e)
        return curvature is None or self._min_curvature <= curvature <= self._max_curvature

    def _hard_reasons(self, e: Estimate, sensor_problem: str | None) -> list[tuple[Reason, str]]:
        s = self.settings
        reasons = []
        if sensor_problem is not None:
            reasons.append((Reason.SENSOR, f"sensor: {sensor_problem}"))
        if e.u_mps < s.speed_min_mps:
            reasons.append((Reason.SPEED_LOW, f"speed {e.u_mps:.1f}{self._below}"))
        if e.ay_mps2 is not None and abs(e.ay_mps2) > s.ay_max_mps2:
            reasons.append(
                (Reason.AY_HIGH, f"lateral acceleration too high: {abs(e.ay_mps2):.1f}{self._ay_over}")
            )
        curvature = _curvature(e)
        if curvature is not None and curvature < self._min_curvature:
            reasons.append((Reason.STRAIGHT, self._straight))
        if curvature is not None and curvature > self._max_curvature:
            reasons.append((Reason.TIGHT, self._tight))
        return reasons

    def _soft_reasons(self, e: Estimate) -> list[tuple[Reason, str]]:
        s = self.settings
        reasons = []
        if abs(e.u_dot_mps2) > s.sweep_max_mps2:
            reasons.append((Reason.SWEEP_FAST, f"sweep too fast: {abs(e.u_dot_mps2):.2f}{self._sweep_over}"))
        yaw_transient = e.r_dot_radps2 is not None and abs(e.r_dot_radps2) > s.yaw_accel_max_radps2
        if yaw_transient or abs(e.v_dot_mps2) > s.lateral_accel_rate_max_mps2:
            reasons.append((Reason.TRANSIENT, "steering transient"))
        return reasons


_STEADY = {direction: SteadyState(True, direction) for direction in ("left", "right", None)}
_SETTLING = (Reason.SETTLING,)


def _not_steady(direction: Direction | None, why: list[tuple[Reason, str]]) -> SteadyState:
    """The verdict for the (cause, words) pairs: most often one, on the per-frame path."""
    if len(why) == 1:
        ((cause, words),) = why
        return SteadyState(False, direction, (words,), (cause,))
    return SteadyState(False, direction, tuple(w for _, w in why), tuple(c for c, _ in why))


def _curvature(e: Estimate) -> float | None:
    if e.u_mps <= 0:
        return None
    if e.r_radps is not None:
        return abs(e.r_radps) / e.u_mps
    if e.ay_mps2 is not None:
        return abs(e.ay_mps2) / (e.u_mps * e.u_mps)
    return None


def _direction(e: Estimate, steer_rad: float | None) -> Direction | None:
    """Turning direction (ISO 8855: positive yaw rate is a left turn)."""
    for value in (e.r_radps, e.ay_mps2, steer_rad):
        if value is not None and value != 0 and math.isfinite(value):
            return "left" if value > 0 else "right"
    return None
