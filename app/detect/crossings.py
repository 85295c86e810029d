"""Sideslip sign changes in steady cornering, fitted locally to give u0 and C2n (paper eq. 7).

The filtered sideslip flags a sign change once it clears a hysteresis band of a few of its own
(measured) standard deviations. The crossing speed itself comes from a local least-squares
fit of the *measured* samples against u² around the flag — not from the two samples either side
of it — using samples of one turning direction while the speed moves one way (a "run").

With a yaw rate, the fitted quantity is v/r, the lateral velocity at the sensor over the yaw
rate: in linear steady state v/r = d − u²/(g·C2n) for any radius (eq. 6 times R), so constant
steering, constant radius and step steers all give a straight line in u². Without a yaw rate it
is the sideslip itself (as v/u = tan β), a straight line in u² at constant radius (eq. 6).
"""

import math
from dataclasses import dataclass, field

import numpy as np

from app.config import DetectorSettings
from app.detect.line_fit import LineFit, Zero, fit_line
from app.records import (
    Crossing,
    CrossingRejected,
    Direction,
    Estimate,
    Event,
    SignChange,
    SlopeLever,
    SteadyState,
    Sweep,
)

_TRIM_EVERY = 2048  # samples between trims of a run's far-away history
_MAX_RUN_SAMPLES = 200_000  # hard cap on a run's memory (13 min at 250 Hz)


@dataclass
class _Pending:
    t: float
    u: float
    sweep: Sweep


@dataclass
class _Run:
    """Steady samples of one turning direction while the speed moves one way."""

    kind: str  # "v/r" or "beta"
    t: list[float] = field(default_factory=list)
    u: list[float] = field(default_factory=list)
    y: list[float] = field(default_factory=list)
    ay: list[float] = field(default_factory=list)
    ud: list[float] = field(default_factory=list)  # du/dt
    psi: list[float] = field(default_factory=list)  # heading (the integrated yaw rate)
    r: list[float] = field(default_factory=list)  # yaw rate (v/r only: what a slope's terms need)
    trend: int = 0  # +1 speed rising, −1 falling, 0 not yet known
    u_first: float = math.nan
    u_extreme: float = math.nan
    i_extreme: int = 0
    sign: int = 0  # last confident sign of the filtered sideslip
    u_at_sign: float = math.nan  # speed when that sign was last confirmed
    pending: _Pending | None = None
    crossed: bool = False  # a sweep one way crosses u0 once: later sign changes are noise
    appended: int = 0

    def track_speed(self, u: float, reversal: float) -> bool:
        """Follow the speed trend; True when the speed reverses by more than ``reversal``."""
        if self.trend == 0:
            if math.isnan(self.u_first):
                self.u_first = self.u_extreme = u
            if abs(u - self.u_first) >= reversal:
                self.trend = 1 if u > self.u_first else -1
                self.u_extreme, self.i_extreme = u, len(self.u)
            return False
        if (u - self.u_extreme) * self.trend > 0:
            self.u_extreme, self.i_extreme = u, len(self.u)
            return False
        return abs(u - self.u_extreme) > reversal

    def restart_at_extreme(self) -> None:
        """Keep only the samples since the speed's turning point; the trend flips."""
        for samples in (self.t, self.u, self.y, self.ay, self.ud, self.psi, self.r):
            del samples[: self.i_extreme]
        self.trend = -self.trend
        self.crossed = False
        self.u_extreme = self.u[-1] if self.u else math.nan
        self.i_extreme = len(self.u) - 1 if self.u else 0
        for i, value in enumerate(self.u):
            if (value - self.u_extreme) * self.trend > 0:
                self.u_extreme, self.i_extreme = value, i

    def take_pending(self) -> _Pending | None:
        pending, self.pending = self.pending, None
        return pending

    def append(
        self,
        t: float,
        u: float,
        y: float,
        ay: float,
        ud: float,
        keep_within: float,
        psi: float = 0.0,
        r: float = math.nan,
    ) -> None:
        self.t.append(t)
        self.u.append(u)
        self.y.append(y)
        self.ay.append(ay)
        self.ud.append(ud)
        self.psi.append(psi)
        self.r.append(r)
        self.appended += 1
        if self.appended % _TRIM_EVERY == 0 or len(self.t) > _MAX_RUN_SAMPLES:
            self._trim(u, keep_within)

    def _trim(self, u_now: float, keep_within: float) -> None:
        """Forget samples too far in speed to matter for any future fit (bounded memory)."""
        keep = [i for i, value in enumerate(self.u) if abs(value - u_now) <= keep_within]
        if len(keep) > _MAX_RUN_SAMPLES // 2:
            keep = keep[-_MAX_RUN_SAMPLES // 2 :]
        if len(keep) == len(self.u):
            return
        self.t = [self.t[i] for i in keep]
        self.u = [self.u[i] for i in keep]
        self.y = [self.y[i] for i in keep]
        self.ay = [self.ay[i] for i in keep]
        self.ud = [self.ud[i] for i in keep]
        self.psi = [self.psi[i] for i in keep]
        self.r = [self.r[i] for i in keep]
        self.u_extreme = self.u[0] if self.u else math.nan
        self.i_extreme = 0
        for i, value in enumerate(self.u):
            if self.trend and (value - self.u_extreme) * self.trend > 0:
                self.u_extreme, self.i_extreme = value, i


@dataclass(frozen=True)
class _Window:
    fit: LineFit
    zero: Zero
    selected: np.ndarray


class CrossingDetector:
    def __init__(self, settings: DetectorSettings, d_m: float, g: float) -> None:
        self.settings = settings
        self.d_m = d_m
        self.g = g
        self._runs: dict[Direction | None, _Run] = {}
        self._t_last: dict[Direction | None, float] = {}
        self._lasts: tuple[float, float] | None = None  # the runs' earliest and latest t_last
        # the pad's slope as the regression last found it (its RegressionFit.slope.tilt), taken out of
        # each crossing's samples before the fit: a crossing happens at one heading
        self.tilt: tuple[float, float, float, float] | None = None

    @property
    def pending(self) -> list[tuple[Direction | None, float, float]]:
        """Sign changes still being fitted: (direction, time, speed)."""
        return [(key, run.pending.t, run.pending.u) for key, run in self._runs.items() if run.pending]

    @property
    def running(self) -> bool:
        """Whether a steady run is open (a step that is not steady may end it)."""
        return bool(self._runs)

    def step(self, t: float, estimate: Estimate, steady: SteadyState, heading: float = 0.0) -> list[Event]:
        """One filtered frame; ``heading`` is the yaw rate integrated from the start (rad)."""
        events = self.end_quiet_runs(t)
        if not steady.steady or estimate.v_meas_mps is None or estimate.sideslip_meas_rad is None:
            return events
        key = steady.direction
        u = estimate.u_mps
        if estimate.r_radps is not None:
            kind, y = "v/r", estimate.v_meas_mps / estimate.r_radps
        else:
            kind, y = "beta", estimate.v_meas_mps / u  # tan β: eq. 6 is linear in it
        run = self._runs.get(key)
        if run is not None and run.kind != kind:
            events.extend(self._end_run(key, "the yaw rate came or went"))
            run = None
        if run is None:
            run = self._runs[key] = _Run(kind)
        self._t_last[key] = t
        self._lasts = None
        if run.track_speed(u, self.settings.reversal_mps):
            if (pending := run.take_pending()) is not None:
                events.append(self._fit(run, pending, key))
            run.restart_at_extreme()
        hw = self.settings.fit_half_width_mps
        ay = abs(estimate.ay_mps2) if estimate.ay_mps2 is not None else math.nan
        r = estimate.r_radps if estimate.r_radps is not None else math.nan
        run.append(t, u, y, ay, estimate.u_dot_mps2, 3 * hw, heading, r)
        events.extend(self._watch_sign(run, key, t, u, estimate))
        if run.pending is not None and abs(u - run.pending.u) >= hw:
            events.append(self._fit(run, run.take_pending(), key))
        return events

    def end_quiet_runs(self, t: float) -> list[Event]:
        """What ``step`` does with a frame that is not steady: end the runs that have had no
        steady frame for longer than the gap allowed (or whose time ran back)."""
        lasts = self._lasts
        if lasts is None and self._runs:
            times = [self._t_last[key] for key in self._runs]
            lasts = self._lasts = (min(times), max(times))
        if lasts is None or (t - lasts[0] <= self.settings.max_gap_s and t - lasts[1] >= -0.05):
            return []  # every run heard from within the gap (the loop below, for its extremes)
        events: list[Event] = []
        for key in list(self._runs):
            quiet = t - self._t_last[key]
            if quiet > self.settings.max_gap_s or quiet < -0.05:
                events.extend(self._end_run(key, "the steady run ended"))
        return events

    def finish(self) -> list[Event]:
        """End of input: fit whatever sign changes are still pending."""
        events: list[Event] = []
        for key in list(self._runs):
            events.extend(self._end_run(key, "the input ended"))
        return events

    # -- internals -------------------------------------------------------------------------
    def _watch_sign(self, run: _Run, key: Direction | None, t: float, u: float, e: Estimate) -> list[Event]:
        band = self.settings.hysteresis_sigmas * e.sideslip_sigma_rad
        sign = 1 if e.sideslip_rad > band else -1 if e.sideslip_rad < -band else 0
        if sign == 0:
            return []
        events: list[Event] = []
        if run.sign != 0 and sign != run.sign:
            if (pending := run.take_pending()) is not None:
                events.append(
                    CrossingRejected(
                        t,
                        key,
                        pending.sweep,
                        pending.u,
                        "the sideslip changed sign back within the fit window",
                    )
                )
            elif run.crossed:
                sweep_now: Sweep = "up" if run.trend > 0 else "down"
                events.append(CrossingRejected(t, key, sweep_now, u, "a second sign change in one sweep"))
            else:
                rising = run.trend > 0 if run.trend else u >= run.u_at_sign
                sweep: Sweep = "up" if rising else "down"
                run.pending = _Pending(t, u, sweep)
                events.append(SignChange(t, key, sweep, u))
        run.sign = sign
        run.u_at_sign = u
        return events

    def _end_run(self, key: Direction | None, why: str) -> list[Event]:
        run = self._runs.pop(key)
        self._t_last.pop(key, None)
        self._lasts = None
        pending = run.take_pending()
        return [self._fit(run, pending, key)] if pending is not None else []

    def _fit(self, run: _Run, pending: _Pending | None, key: Direction | None) -> Crossing | CrossingRejected:
        """Fit the measured samples around a sign change; a Crossing, or why not."""
        if pending is None:
            raise RuntimeError("no sign change to fit")
        run.crossed = True

        def reject(reason: str) -> CrossingRejected:
            return CrossingRejected(pending.t, key, pending.sweep, pending.u, reason)

        t, u, y, ay, ud = (np.asarray(a) for a in (run.t, run.u, run.y, run.ay, run.ud))
        corrected = self.tilt is not None and run.kind == "v/r"
        if corrected:
            y = y - self._slope_part(u, np.asarray(run.psi), np.asarray(run.r))
        hw = self.settings.fit_half_width_mps
        outcome: _Window | str = "no samples"
        for width in (hw, 1.5 * hw, 2.0 * hw, 3.0 * hw):  # sparse data (step steers) need a wider window
            outcome = self._fit_window(u, y, pending.u, width)
            if isinstance(outcome, _Window):
                break
        if isinstance(outcome, str):
            return reject(outcome)
        fit, zero, selected = outcome.fit, outcome.zero, outcome.selected
        u0, n = math.sqrt(zero.x0), int(np.count_nonzero(selected))
        direction: Direction | None = key
        if run.kind == "v/r" and fit.b >= 0:
            return reject("v/r rises with speed: check the signs of the yaw rate and lateral velocity")
        if run.kind == "beta":
            # eq. 6: dβ/d(u²) = −1/(R·g·C2n) is negative turning left (R > 0), positive turning right
            inferred: Direction = "left" if fit.b < 0 else "right"
            if direction is not None and direction != inferred:
                return reject(f"the sideslip trend does not fit a {direction} turn: check the signs")
            direction = inferred
        if direction is None:
            return reject("the turning direction is unknown")
        nearest = int(np.argmin(np.abs(u - u0) + np.where(selected, 0.0, np.inf)))
        per_step = slope_lever = None
        if run.kind == "v/r":
            psi, r = np.asarray(run.psi)[selected], np.asarray(run.r)[selected]
            # y = v/r gains δ·sign(κ)·u/r = δ·u/|r| (δ·R on a circle)
            per_step = float(np.mean(u[selected] / np.maximum(np.abs(r), 1e-9))) / fit.b
            # how any slope moves this fit: re-corrected with the last one found
            x = u[selected] ** 2
            lines = [fit_line(x, column) for column in self._slope_columns(u[selected], psi, r)]
            levers = tuple((line.a, line.b) for line in lines)
            slope_lever = SlopeLever(fit.x_mean, fit.a, fit.b, levers, self.tilt or (0.0, 0.0, 0.0, 0.0))
        ay0 = float(ay[nearest])
        radius = (u0 * u0 / ay0 if ay0 > 0 else math.inf) * (1 if direction == "left" else -1)
        scale = 1.0 / (self.g * self.d_m)
        lo, hi = zero.ci95
        return Crossing(
            t=float(t[nearest]),
            direction=direction,
            sweep=pending.sweep,
            u0_mps=u0,
            u0_ci95=(math.sqrt(max(lo, 0.0)), math.sqrt(max(hi, 0.0))),
            c2n=zero.x0 * scale,
            c2n_se=zero.se * scale,
            ci95=(lo * scale, hi * scale),
            ay_mps2=ay0,
            radius_m=radius,
            sweep_rate_mps2=float(np.mean(ud[selected])),
            n_samples=n,
            method="v/r" if run.kind == "v/r" else "beta",
            slope_corrected=corrected,
            u0sq_per_step=per_step,
            slope_lever=slope_lever,
        )

    def _slope_part(self, u: np.ndarray, psi: np.ndarray, r: np.ndarray) -> np.ndarray:
        """What the regression's slope (``tilt``: the sideslip a · (sin ψ, cos ψ, a_y·sin ψ,
        a_y·cos ψ), a_y = u·r) adds to y = v/r = β·u/r at each sample."""
        tilt = np.asarray(self.tilt or (0.0, 0.0, 0.0, 0.0))
        part: np.ndarray = tilt @ np.asarray(self._slope_columns(u, psi, r))
        return part

    @staticmethod
    def _slope_columns(u: np.ndarray, psi: np.ndarray, r: np.ndarray) -> list[np.ndarray]:
        """Each slope term's share of y = v/r: (sin ψ, cos ψ, a_y·sin ψ, a_y·cos ψ)·u/r."""
        sin, cos, lever = np.sin(psi), np.cos(psi), u / r
        return [sin * lever, cos * lever, u * r * sin * lever, u * r * cos * lever]

    def _fit_window(self, u: np.ndarray, y: np.ndarray, u_flag: float, width: float) -> "_Window | str":
        """Fit y against u² within ±width of the crossing: a first pass around the flag (which
        lags the true crossing), then again centred on the fitted u0. A _Window, or why not."""
        s = self.settings
        selected = np.abs(u - u_flag) <= 1.5 * width
        for _ in range(2):
            count = int(np.count_nonzero(selected))
            if count < s.min_fit_samples:
                return f"only {count} steady samples near the crossing"
            try:
                fit = fit_line(u[selected] ** 2, y[selected])
            except ValueError as error:
                return str(error)
            zero = fit.zero()
            near = u[selected]
            if not near.min() ** 2 <= zero.x0 <= near.max() ** 2:
                return "no crossing within the samples around the sign change"
            selected = np.abs(u - math.sqrt(zero.x0)) <= width
        count = int(np.count_nonzero(selected))
        if count < s.min_fit_samples:
            return f"only {count} steady samples within ±{width:g} m/s of u0"
        fit = fit_line(u[selected] ** 2, y[selected])
        zero = fit.zero()
        if not zero.x0 > 0:
            return "the local fit has no crossing at a positive speed"
        u0 = math.sqrt(zero.x0)
        used = u[selected]
        below, above = u0 - float(used.min()), float(used.max()) - u0
        if min(below, above) < s.min_side_fraction * width:
            return (
                f"samples cover u0 −{max(below, 0):.2f}/+{max(above, 0):.2f} m/s, "
                f"not ±{s.min_side_fraction * width:.2f}"
            )
        hole = float(used[used >= u0].min() - used[used <= u0].max())
        if hole > 0.5 * width:
            return f"no samples within {hole:.1f} m/s around u0 (sensor status, transients?)"
        if fit.slope_t < s.min_slope_t:
            return f"the sideslip hardly changes with speed here (slope t = {fit.slope_t:.1f})"
        return _Window(fit, zero, selected)
