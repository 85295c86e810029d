"""Quasi-steady cornering: the samples that carry C2n where no sweep crossed the sign change.

The sideslip at the sensor is β = ψ0 + d·κ − α2 whenever the rear tyres make the force the turn
asks of them, α2 = F_y2/(C2n·m2·g). In steady state F_y2 = m2·a_y. In ordinary driving — track
laps, road corners — speed and yaw rate change slowly, and the rear axle's force is still
m2·a_y less the rear's share of the yaw acceleration, m2·a_y − I_z·ṙ/(m·a): the regression that
takes these samples fits a term in ṙ and one in a_y·u̇ (braking moves load off the rear axle,
whose tyres then give more slip per newton).

So the gate here keeps the steady gate's hard limits (speed, the linear range of a_y, a turn, a
sensor reporting well) and lets the rates through up to where a transient is no longer slow
compared with the tyres and the filter: turn-ins and hard braking are dropped, a corner taken
with the throttle half open is kept. A sample counts once the conditions have held for
``SETTLE_S`` (the filter's rates catch up with a turn-in in about that).

It also keeps the tally a refusal needs: how long the car cornered, and why those seconds were
not usable (``Cornering``).
"""

import math
from dataclasses import dataclass

import numpy as np

from app.config import DetectorSettings
from app.detect.steady_state import tightest_curvature
from app.records import Estimate
from app.units import G0

SWEEP_MAX_MPS2 = 2.0  # |u̇|: a corner under part throttle or light braking, not a stop
YAW_ACCEL_MAX_RADPS2 = 0.25  # |ṙ|: a corner's radius tightening, not a turn-in or a slalom
LATERAL_RATE_MAX_MPS2 = 0.5  # |v̇| at the sensor: the body settling, not a step steer
SETTLE_S = 0.5  # the conditions must hold this long before samples count
AY_MIN_MPS2 = 0.5  # a turn that asks this much of the tyres: below it, a straight's drift at low speed
# (a second log's near-straight stretches at 6 m/s moved CommonRoad's pooled C2n by up to 1 %)
_MAX_STEP_S = 0.5  # a longer pause between samples counts as no driving
# |a_y| no car holds on a test pad: 3 g. A racing slick's peak friction is about 1.7–2 and road
# tyres' about 1.0–1.2; more takes aerodynamic downforce, which at the method's 10–25 m/s is a
# few per cent of the weight. Beyond it the reading is a unit's (a yaw rate in deg/s read as
# rad/s: 57.3×), not the car's
GRIP_MAX_MPS2 = 3.0 * G0


@dataclass(frozen=True)
class Cornering:
    """Seconds of driving, by what the quasi-steady gate made of them."""

    turning_s: float = 0.0  # above the speed limit, in a turn (|a_y| ≥ 0.5 m/s²), the sensor reporting well
    ay_high_s: float = 0.0  # of which |a_y| beyond the tyres' linear range
    transient_s: float = 0.0  # of which speed or steering changing too fast, or settling
    usable_s: float = 0.0  # of which quasi-steady
    tight_s: float = 0.0  # of which on a radius under eight wheelbases (``tightest_curvature``)
    usable_ay_mps2: tuple[float, float] | None = None  # the quasi-steady samples' |a_y|: least, most
    usable_samples: int = 0  # the quasi-steady samples
    backwards_s: float = 0.0  # cornering as above but the optical speed at or below −speed_min: vx flipped
    below_speed_s: float = 0.0  # in a turn as above but under the speed limit ([detector] speed_min_mps)
    beyond_grip_s: float = 0.0  # of turning_s, |a_y| beyond any tyre's grip (``GRIP_MAX_MPS2``): a unit's


NO_CORNERING = Cornering()


class QuasiSteadyGate:
    def __init__(self, settings: DetectorSettings, wheelbase_m: float | None = None) -> None:
        self.settings = settings
        self._min_curvature = 1.0 / settings.radius_max_m
        self._max_curvature = tightest_curvature(wheelbase_m)
        self._since: float | None = None  # when every condition began to hold
        self._t: float | None = None  # the last sample's time
        self._seconds = [0.0] * 8  # Cornering's seconds: five, backwards_s, below_speed_s, beyond_grip_s
        self._usable_ay = [math.inf, 0.0]  # the quasi-steady samples' least and most |a_y|
        self._usable_n = 0

    @property
    def cornering(self) -> Cornering:
        low, high = self._usable_ay
        turning, ay_high, transient, usable, tight, backwards, below, beyond = self._seconds
        spread = (low, high) if low <= high else None
        return Cornering(
            turning, ay_high, transient, usable, tight, spread, self._usable_n, backwards, below, beyond
        )

    def new_log(self) -> None:
        """Another drive follows: nothing of this one carries over but the tally."""
        self._since = self._t = None

    def step(self, t: float, e: Estimate, sensor_ok: bool) -> bool:
        """Is this estimate a quasi-steady sample? ``steps`` for one, without arrays: this runs
        for every filtered frame of a live drive."""
        s, u, r, ay, r_dot = self.settings, e.u_mps, e.r_radps, e.ay_mps2, e.r_dot_radps2
        curvature = abs(r) / abs(u) if r is not None and abs(u) >= s.speed_min_mps and u != 0 else -1.0
        turning = sensor_ok and curvature >= self._min_curvature and ay is not None and abs(ay) >= AY_MIN_MPS2
        backwards = turning and u < 0  # cornering by the optical speed driven backwards: vx's sign
        turning = turning and u > 0
        ay_ok = ay is not None and abs(ay) <= s.ay_max_mps2
        wide = curvature <= self._max_curvature  # not too tight a turn
        slow = (
            abs(e.u_dot_mps2) <= SWEEP_MAX_MPS2
            and r_dot is not None
            and abs(r_dot) <= YAW_ACCEL_MAX_RADPS2
            and abs(e.v_dot_mps2) <= LATERAL_RATE_MAX_MPS2
        )
        quasi = False
        if turning and ay_ok and wide and slow:
            if self._since is None:
                self._since = t
            quasi = t - self._since >= SETTLE_S
        else:
            self._since = None
        dt = min(max(t - (t if self._t is None else self._t), 0.0), _MAX_STEP_S)
        self._t = t
        if turning:
            tally = self._seconds
            tally[0] += dt
            tally[1 if not ay_ok else 4 if not wide else 3 if quasi else 2] += dt
            if ay is not None and abs(ay) > GRIP_MAX_MPS2:
                tally[7] += dt
        elif backwards:
            self._seconds[5] += dt
        elif (  # a turn, too slow
            sensor_ok
            and r is not None
            and ay is not None
            and 0.0 < u < s.speed_min_mps
            and abs(ay) >= AY_MIN_MPS2
            and abs(r) / u >= self._min_curvature
        ):
            self._seconds[6] += dt
        if quasi:
            assert ay is not None  # a quasi-steady sample is turning: it has an a_y
            spread = self._usable_ay
            spread[0], spread[1] = min(spread[0], abs(ay)), max(spread[1], abs(ay))
            self._usable_n += 1
        return quasi

    def steps(self, t: np.ndarray, estimates: np.ndarray, sensor_ok: np.ndarray) -> np.ndarray:
        """``step`` over rows of ``Estimate``'s fields (NaN for None) at times t: which are
        quasi-steady."""
        s, n = self.settings, len(t)
        if not n:
            return np.zeros(0, bool)
        u, u_dot, v_dot, r, r_dot, ay = (estimates[:, k] for k in (0, 1, 3, 4, 5, 8))
        with np.errstate(divide="ignore", invalid="ignore"):
            curvature = np.abs(r) / np.abs(u)
            cornering = sensor_ok & (np.abs(u) >= s.speed_min_mps) & (curvature >= self._min_curvature)
            cornering &= np.abs(ay) >= AY_MIN_MPS2
            turning, backwards = cornering & (u > 0), cornering & (u < 0)
            below = sensor_ok & (u > 0) & (u < s.speed_min_mps) & (curvature >= self._min_curvature)
            below &= np.abs(ay) >= AY_MIN_MPS2
            wide = curvature <= self._max_curvature
        ay_ok = np.abs(ay) <= s.ay_max_mps2
        slow = (
            (np.abs(u_dot) <= SWEEP_MAX_MPS2)
            & (np.abs(r_dot) <= YAW_ACCEL_MAX_RADPS2)
            & (np.abs(v_dot) <= LATERAL_RATE_MAX_MPS2)
        )
        holds = turning & ay_ok & wide & slow
        # when each sample's spell of holding began: after the last sample that broke it
        last_broken = np.maximum.accumulate(np.where(holds, -1, np.arange(n)))
        first = float(t[0]) if self._since is None else self._since
        began = np.where(last_broken >= 0, t[np.minimum(last_broken + 1, n - 1)], first)
        quasi = holds & (t - began >= SETTLE_S)
        self._since = float(began[-1]) if holds[-1] else None
        # the tally: each sample stands for the time since the one before
        before = np.concatenate([[t[0] if self._t is None else self._t], t[:-1]])
        dt = np.clip(t - before, 0.0, _MAX_STEP_S)
        self._t = float(t[-1])
        tally = self._seconds
        tally[0] += float(dt[turning].sum())
        tally[1] += float(dt[turning & ~ay_ok].sum())
        tally[2] += float(dt[turning & ay_ok & wide & ~quasi].sum())
        tally[3] += float(dt[quasi].sum())
        tally[4] += float(dt[turning & ay_ok & ~wide].sum())
        tally[5] += float(dt[backwards].sum())
        tally[6] += float(dt[below].sum())
        tally[7] += float(dt[turning & (np.abs(ay) > GRIP_MAX_MPS2)].sum())
        if quasi.any():
            usable = np.abs(ay[quasi])
            spread = self._usable_ay
            spread[0], spread[1] = min(spread[0], float(usable.min())), max(spread[1], float(usable.max()))
            self._usable_n += len(usable)
        return np.asarray(quasi, bool)
