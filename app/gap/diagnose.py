"""Where the measured drive departs from the model, which effect explains it, and how far the gap
shrinks once that effect is added — checked on manoeuvres the fit did not see.

1. **Calibrate.** Every real drive carries nuisances: a yaw-rate sensor's bias and scale, the
   steering wheel's centre offset and effective ratio, and nominal C1n and C2n that may be 20 %
   off the car's axles. They are fitted first, on every usable sample, and reported; they are not
   effects.
2. **Weigh the channels by their spread.** Each channel's residual (sideslip at the sensor, yaw
   rate) is scaled by its RMS on the calibrated model, white noise and systematic misfit alike,
   so neither channel outweighs the other by the accident of a quiet sensor.
3. **Score each effect held out.** Manoeuvres (left, right, straight) alternate between two
   folds; the nuisances, alone and with each effect, are fitted on one fold and the sideslip and
   yaw-rate gaps measured on the other (the gap: the residual's 1-s means with the white noise
   taken out of their squares).
4. **Judge each effect in the data's own units** (``app.gap.effects``): present when its held-out
   gain, manoeuvre by manoeuvre, stands beyond the drive's own spread; a finding when what it does
   to C2n or in its own unit exceeds the config's ``[gap]`` tolerances. The findings are fitted
   together; ``diagnosis`` names the one that matters most, ``none`` when none does and the
   calibrated model is within the sideslip tolerance of the drive, else ``unexplained``.
"""

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
from scipy.optimize import least_squares
from threadpoolctl import threadpool_limits

from app.config import Config
from app.detect.quasi_steady import AY_MIN_MPS2, Cornering
from app.errors import NoResultError
from app.gap.candidates import (
    CANDIDATES,
    HIDDEN_BY_CALIBRATION,
    HIDDEN_BY_RIVAL,
    NUISANCE_TWINS,
    RIVAL_NUISANCE,
    Candidate,
    Param,
    mods_of,
    nuisances,
    separating_manoeuvre,
)
from app.gap.effects import (
    MIN_CROSSING_S,
    Z_TEST,
    C2nShift,
    c2n_shift,
    channel,
    gain_z,
    importance,
    near_crossings,
    own_size,
    test_units,
    unit_gaps,
)
from app.gap.forked import map_forked
from app.gap.measured import Measured
from app.gap.method_effects import DIRECT, HELDOUT_FIT, method_effects, with_method_effects
from app.gap.nominal_model import Mods, Prepared, Simulated, prepare, run_model, simulate
from app.gap.result import (
    BeforeAfter,
    C2nEffect,
    Calibrated,
    CandidateScore,
    Effect,
    GapC2n,
    GapNoise,
    GapResult,
    Located,
    Secondary,
)
from app.results.refusal import reads_backwards, speed_min_problem
from app.sim.effects import EffectName
from app.sim.vehicle_model import BicycleParams
from app.units import Z95

GAP_BLOCK_S = 1.0  # the sideslip gap is measured on 1-s means
ROBUST_SCALE = 3.0  # residuals beyond this many channel scales count less (soft L1)
YAW_WEIGHT = 1.0  # the yaw rate carries the driver's corrections the model cannot follow
SPEED_WEIGHT = 0.5  # the vehicle speed signal: it tells the speed scale and the bus's lag
DEFAULT_ROLL_AXIS_HEIGHT_M = 0.10  # at the sensor, where the config does not say: a saloon's roll centres
LINEAR_AY_MPS2 = 4.5  # the bicycle model's tyres are linear: beyond this it is not compared
MAX_EVALUATIONS = 200  # model runs per fit (the Jacobian's are extra)
FIT_TOLERANCE = 1e-6  # a fit stops when its cost or its parameters (in their typical sizes) move
# by less than this share: a millionth of a typical size, far inside any interval it reports
_STRAIGHT_RADPS, _TURNING_RADPS = 0.015, 0.03
_MIN_MANOEUVRE_S = 2.0


def manoeuvres(m: Measured) -> np.ndarray:
    """A manoeuvre id per grid step: runs of turning left, right, or driving straight."""
    state = np.zeros(len(m.t), dtype=np.int8)
    current = 0
    r = np.nan_to_num(m.r)
    for k, value in enumerate(r.tolist()):
        if abs(value) > _TURNING_RADPS:
            current = 1 if value > 0 else -1
        elif abs(value) < _STRAIGHT_RADPS:
            current = 0
        state[k] = current
    ids = np.cumsum(np.r_[0, np.diff(state) != 0])
    # short runs (a wobble) join the run before them
    lengths = np.bincount(ids) * m.dt
    for run in np.flatnonzero(lengths < _MIN_MANOEUVRE_S):
        if run > 0:
            ids[ids == run] = ids[np.flatnonzero(ids == run)[0] - 1] if np.flatnonzero(ids == run)[0] else run
    return np.asarray(ids)


def folds(m: Measured, ids: np.ndarray) -> np.ndarray:
    """Fold 0 or 1 per grid step: manoeuvres of each kind (left, right, straight) alternate, the
    right turns one step out of phase with the left ones, so that where a session turns left and
    right on each radius in turn, each fold holds both directions on every radius (what tells an
    effect per curvature from one per turn direction)."""
    fold = np.zeros(len(ids), dtype=np.int8)
    seen: dict[int, int] = {}
    r = np.nan_to_num(m.r)
    for run in np.unique(ids):
        rows = ids == run
        kind = int(np.sign(np.median(r[rows]))) if np.abs(np.median(r[rows])) > _STRAIGHT_RADPS else 0
        fold[rows] = (seen.get(kind, 0) + (kind < 0)) % 2
        seen[kind] = seen.get(kind, 0) + 1
    return fold


def _usable(m: Measured) -> np.ndarray:
    """Grid steps the linear model is compared on: every signal there, moving, and the tyres in
    their linear range (|a_y| up to LINEAR_AY_MPS2, as the method itself assumes)."""
    usable = np.isfinite(m.beta) & np.isfinite(m.r) & np.isfinite(m.delta)
    linear = np.abs(np.nan_to_num(m.u_optical * m.r)) <= LINEAR_AY_MPS2
    return np.asarray(usable & linear & (np.nan_to_num(m.u_optical) > 5.0))


def _lacking(m: Measured, config: Config) -> str | None:
    """What the drive lacks that the model needs, named (it said "too short to diagnose: 0 s"):
    the steering that drives the model, the yaw rate it is compared on, a forward speed."""
    for values, what, role, why in (
        (m.delta, "steering angle", "steer", "driven by it"),
        (m.r, "yaw rate", "yaw_rate", "compared on it"),
    ):
        if np.isfinite(values).any():
            continue
        spec = config.roles.get(role)
        if spec is None:
            return f"no {what} in the drive: the model is {why} — give its signal as [roles] {role}"
        return (
            f"no {what} in the drive: the log has no frames of [roles] {role}'s {spec.message}.{spec.signal} "
            f"— the model is {why}: record it, or check the message's id and channel"
        )
    u, speed_min = np.nan_to_num(m.u_optical), config.detector.speed_min_mps
    turning = np.abs(u * np.nan_to_num(m.r)) >= AY_MIN_MPS2
    forwards = np.count_nonzero(turning & (u >= speed_min)) * m.dt
    scale = config.roles["vx"].scale if "vx" in config.roles else 1.0
    backwards = reads_backwards(np.count_nonzero(turning & (u <= -speed_min)) * m.dt, forwards, scale)
    if backwards:
        return backwards
    below = np.count_nonzero(turning & (u > 0) & (u < speed_min)) * m.dt
    return speed_min_problem(Cornering(turning_s=forwards, below_speed_s=below), speed_min)


def _noise(x: np.ndarray) -> float:
    """Robust standard deviation of the white part of a residual (from first differences)."""
    d = np.diff(x[np.isfinite(x)])
    if len(d) < 10:
        return 1.0
    return float(max(1.4826 * np.median(np.abs(d - np.median(d))) / math.sqrt(2.0), 1e-9))


@dataclass(frozen=True)
class Problem:
    params: BicycleParams
    measured: Measured
    d_m: float
    cg_height_m: float | None  # for the longitudinal load transfer
    roll_lever_m: float  # the sensor's height above the roll axis
    rows: np.ndarray  # usable grid steps
    sigma_beta: float  # white noise per grid step, rad
    sigma_r: float  # rad/s
    sigma_u: float  # the vehicle speed signal's, m/s
    has_speed: bool  # the drive has a vehicle speed signal besides the optical speed
    scale_beta: float = 1.0  # the channels' spread on the calibrated model: their residuals' units
    scale_r: float = 1.0
    scale_u: float = 1.0

    def residual(self, sim: Simulated, rows: np.ndarray) -> np.ndarray:
        m = self.measured
        channels = [
            (m.beta - sim.beta)[rows] / self.scale_beta,
            YAW_WEIGHT * (sim.r_measured - sim.r)[rows] / self.scale_r,
        ]
        if self.has_speed:
            channels.append(SPEED_WEIGHT * (m.u_vehicle - sim.speed_reading)[rows] / self.scale_u)
        return np.concatenate(channels)

    def rms_beta_deg(self, sim: Simulated, rows: np.ndarray) -> float:
        """The sideslip gap: the systematic part of the residual, which a model could explain.

        The residual is averaged over 1-s blocks and each block's mean counts by its samples (a
        block cut short by a fold boundary holds few samples and mostly noise); the white sensor
        noise left in a mean of n samples, σ²/n, is taken out of its square. The result is the
        RMS over samples of the residual's slow part, with the noise removed rather than averaged
        down.
        """
        return math.degrees(self._gap(self.measured.beta - sim.beta, rows, self.sigma_beta))

    def rms_yaw_degps(self, sim: Simulated, rows: np.ndarray) -> float:
        """The yaw-rate gap, measured as the sideslip gap is."""
        return math.degrees(self._gap(sim.r_measured - sim.r, rows, self.sigma_r))

    def rms_speed_mps(self, sim: Simulated, rows: np.ndarray) -> float:
        """The vehicle speed signal's gap (0 without one), measured as the sideslip gap is."""
        if not self.has_speed:
            return 0.0
        return self._gap(self.measured.u_vehicle - sim.speed_reading, rows, self.sigma_u)

    def _gap(self, residual: np.ndarray, rows: np.ndarray, sigma: float) -> float:
        if not rows.any():
            return 0.0
        block = (self.measured.t[rows] // GAP_BLOCK_S).astype(np.int64)
        sums, counts = np.bincount(block, residual[rows]), np.bincount(block)
        filled = counts > 0
        square = float(np.sum(sums[filled] ** 2 / counts[filled])) - filled.sum() * sigma**2
        return math.sqrt(max(square, 0.0) / rows.sum())

    def blocks(self, rows: np.ndarray) -> int:
        """How many GAP_BLOCK_S blocks ``rows`` touch."""
        return max(len(np.unique((self.measured.t[rows] // GAP_BLOCK_S).astype(np.int64))), 1)

    def gap_noise_deg(self, rows: np.ndarray) -> float:
        """The standard deviation of the sideslip gap's square estimate, as a gap: what white
        noise alone can make of a gap measured over ``rows`` (σ of a block mean, over the root of
        the number of blocks)."""
        blocks = self.blocks(rows)
        per_block = max(rows.sum() / blocks, 1.0)
        block_sigma = self.sigma_beta / math.sqrt(per_block)
        return math.degrees(block_sigma * (2.0 / blocks) ** 0.25)

    @cached_property
    def prepared(self) -> Prepared:
        return prepare(self.params, self.measured, self.cg_height_m, self.roll_lever_m)

    def simulate(self, mods: Mods | None = None) -> Simulated:
        return run_model(self.prepared, self.d_m, mods or Mods())


@dataclass(frozen=True)
class Fit:
    params: tuple[Param, ...]
    values: tuple[float, ...]
    cost: float  # the robust cost at the end
    jac: np.ndarray | None = None  # the residuals' Jacobian there (scaled parameters), and the
    fun: np.ndarray | None = None  # residuals: what a fit's intervals come from

    def fields(self) -> dict[str, float]:
        out: dict[str, float] = {}
        for param, value in zip(self.params, self.values, strict=True):
            out.update(param.to_mods(value))
        return out

    def at_bound(self) -> tuple[str, ...]:
        return tuple(p.name for p, v in zip(self.params, self.values, strict=True) if p.at_bound(v))


def fit(
    pb: Problem,
    params: Sequence[Param],
    rows: np.ndarray,
    start: Sequence[float] | None = None,
) -> Fit:
    """Least squares of both channels over ``rows`` (soft L1), every parameter inside its bounds.
    ``start``: where to begin (else each parameter's best start)."""
    params = tuple(params)
    free = np.array([p.free for p in params])
    held = np.array([p.nominal for p in params])  # a fixed parameter stays at its nominal value
    scales = np.array([p.scale for p in params])
    low = np.array([p.low for p in params]) / scales
    high = np.array([p.high for p in params]) / scales

    def full(x: np.ndarray) -> np.ndarray:
        out: np.ndarray = held / scales
        out[free] = x
        return out

    def mods(x: np.ndarray) -> Mods:
        fields: dict[str, float] = {}
        for param, value in zip(params, (full(x) * scales).tolist(), strict=True):
            fields.update(param.to_mods(value))
        return Mods(**fields)

    # A prior weighs as much as the data's independent samples make it: residuals on the 20-ms
    # grid hang together over about a block, so the data count as many samples as blocks.
    weight = math.sqrt(max(rows.sum() / pb.blocks(rows), 1.0))
    index = np.cumsum(free) - 1  # a free parameter's place in x
    priors = [
        (int(index[k]), p.nominal / p.scale, p.prior / p.scale / weight)
        for k, p in enumerate(params)
        if p.prior and p.free
    ]

    def residual(x: np.ndarray) -> np.ndarray:
        fitted = pb.residual(pb.simulate(mods(x)), rows)
        if not priors:
            return fitted
        return np.concatenate([fitted, [(x[k] - centre) / spread for k, centre, spread in priors]])

    def cost(x: np.ndarray) -> float:
        z = residual(x) / ROBUST_SCALE
        return float(np.sum(np.sqrt(1.0 + z * z)))

    low, high, scales_free = low[free], high[free], scales[free]
    if start is not None:
        x0 = np.asarray(start, dtype=float)[free] / scales_free
    else:
        starts = [np.array(x)[free] / scales_free for x in itertools.product(*(p.starts for p in params))]
        x0 = min(starts, key=cost) if len(starts) > 1 else starts[0]
    x0 = np.clip(x0, low + 1e-9 * (high - low), high - 1e-9 * (high - low))
    if not np.all(np.isfinite(residual(x0))):
        raise _diverged()
    result = least_squares(
        residual,
        x0,
        bounds=(low, high),
        loss="soft_l1",
        f_scale=ROBUST_SCALE,
        max_nfev=MAX_EVALUATIONS,
        ftol=FIT_TOLERANCE,
        xtol=FIT_TOLERANCE,
    )
    values = tuple(float(v) for v in full(result.x) * scales)
    return Fit(params, values, float(result.cost), result.jac, result.fun)


@dataclass(frozen=True)
class _Job:
    """A fit to make: its parameters, its rows, and where it may start (the best of ``starts``)."""

    params: tuple[Param, ...]
    rows: np.ndarray
    starts: tuple[tuple[float, ...], ...]


def _fit_all(pb: Problem, jobs: Sequence[_Job], workers: int) -> list[Fit]:
    """Each job's fit, in ``workers`` processes (the same fits ``fit`` makes one by one: only
    their numbers cross the process edge)."""

    def numbers(index: int) -> tuple[tuple[float, ...], float, np.ndarray | None, np.ndarray | None]:
        job = jobs[index]
        done = fit(pb, job.params, job.rows, start=_best_start(pb, job.params, job.rows, list(job.starts)))
        return done.values, done.cost, done.jac, done.fun

    done = map_forked(numbers, len(jobs), workers)
    return [Fit(job.params, *out) for job, out in zip(jobs, done, strict=True)]


MIN_USABLE_S = 60.0  # of driving the model is compared on: less cannot be split into folds


def problem(m: Measured, config: Config) -> Problem:
    """The drive, the nominal car, and the white noise of each channel on the nominal model."""
    params = BicycleParams.from_config(config)
    rows = _usable(m)
    lacking = _lacking(m, config)
    if lacking is not None:
        raise NoResultError(lacking)
    if rows.sum() * m.dt < MIN_USABLE_S:
        raise NoResultError(
            f"too short to diagnose: {rows.sum() * m.dt:.0f} s of usable driving (moving above 5 m/s, "
            f"|a_y| ≤ {LINEAR_AY_MPS2:g} m/s², every signal there), needs {MIN_USABLE_S:.0f} s — "
            "drive the standard session"
        )
    cg_height, lever = config.vehicle.cg_height_m, roll_lever_m(config)
    base = simulate(params, m, config.d_m, cg_height_m=cg_height, roll_lever_m=lever)
    sigma_beta = _noise(m.beta - base.beta)
    sigma_r = _noise(base.r_measured - base.r)
    has_speed = m.speed_source == "vehicle speed"
    sigma_u = _noise(m.u_vehicle - base.speed_reading) if has_speed else 1.0
    pb = Problem(params, m, config.d_m, cg_height, lever, rows, sigma_beta, sigma_r, sigma_u, has_speed)
    return _scaled(pb, base)


def _diverged() -> NoResultError:
    """The bicycle model of the config's car diverges on this drive (e.g. a wheelbase so short
    that its yaw mode is faster than the 20-ms grid): there is nothing to fit."""
    return NoResultError(
        "the config's car cannot follow this drive: its model's response is not finite "
        "(check [vehicle] wheelbase_m, the axle loads and [tyres] in the config)"
    )


def _scaled(pb: Problem, sim: Simulated) -> Problem:
    """The problem with each channel's unit set: the sideslip and the vehicle speed by their white
    noise (what the effects move, and what the user asks about), the yaw rate by its whole spread
    on ``sim`` (its systematic part included: the driver's corrections, the transients a bicycle
    model cannot follow), so a yaw-rate misfit no nuisance or effect can remove does not outweigh
    the sideslip and bend the calibration to it."""
    rows = pb.rows
    residual = (sim.r_measured - sim.r)[rows]
    with np.errstate(over="ignore", invalid="ignore"):
        spread = float(np.sqrt(np.mean(residual**2))) if rows.any() else 1.0
    if not math.isfinite(spread):
        raise _diverged()
    return replace(
        pb,
        scale_beta=max(pb.sigma_beta, 1e-6),
        scale_r=max(spread, pb.sigma_r, 1e-6),
        scale_u=max(pb.sigma_u, 1e-4),
    )


def roll_lever_m(config: Config) -> float:
    """The sensor's height above the roll axis; 0 (no roll term) without a sensor height."""
    vehicle = config.vehicle
    if not vehicle.sensor_height_m:
        return 0.0
    axis = vehicle.roll_axis_height_m
    return vehicle.sensor_height_m - (DEFAULT_ROLL_AXIS_HEIGHT_M if axis is None else axis)


@dataclass(frozen=True)
class NuisanceFit:
    """The drive's nuisances (a gyro's bias and scale, the steering's offset …) calibrated on it."""

    params: tuple[Param, ...]  # as calibrated: an optional nuisance the drive does not show, held
    fit: Fit
    ci95: tuple[tuple[float, float], ...]
    declared: tuple[Param, ...]  # as the candidates module declares them

    @property
    def values(self) -> tuple[float, ...]:
        return self.fit.values

    def mods(self, *effect: dict[str, float]) -> Mods:
        return mods_of(self.fit.fields(), *effect)

    def params_for(self, effect: EffectName, rival_free: bool = False) -> tuple[Param, ...]:
        """The nuisances fitted beside ``effect``; its rival (a nuisance that imitates it) held at
        its nominal value, or with ``rival_free`` fitted beside it even where the calibration
        alone did not show it (the effect may have hidden it)."""
        rival = RIVAL_NUISANCE.get(effect)
        if rival_free:
            return tuple(d if d.name == rival else p for p, d in zip(self.params, self.declared, strict=True))
        return tuple(p.fixed() if p.name == rival else p for p in self.params)

    def start_for(self, effect: EffectName) -> tuple[float, ...]:
        return tuple(
            v if p.free else p.nominal for p, v in zip(self.params_for(effect), self.values, strict=True)
        )


def calibrate(pb: Problem, params: tuple[Param, ...]) -> tuple[Problem, NuisanceFit]:
    """The nuisances fitted on every usable sample, twice: the channels' scales are set from the
    first fit's residuals, then the fit is repeated with them."""
    declared = params
    first = fit(pb, params, pb.rows)
    pb = _scaled(pb, pb.simulate(mods_of(first.fields())))
    final = fit(pb, params, pb.rows, start=first.values)
    ci95 = _intervals(pb, final)
    unseen = [
        k
        for k, (p, (low, high)) in enumerate(zip(params, ci95, strict=True))
        if p.optional and low <= p.nominal <= high
    ]
    if unseen:  # held at nominal; their intervals (which cover it) are what the drive says of them
        params = tuple(p.fixed() if k in unseen else p for k, p in enumerate(params))
        final = fit(pb, params, pb.rows, start=final.values)
        held = dict(zip(unseen, (ci95[k] for k in unseen), strict=True))
        ci95 = tuple(held.get(k, ci) for k, ci in enumerate(_intervals(pb, final)))
    return pb, NuisanceFit(params, final, ci95, declared)


def _intervals(pb: Problem, result: Fit) -> tuple[tuple[float, float], ...]:
    """95 % intervals from the fit's Jacobian (a fit over every usable sample), each channel's
    residual variance its own, inflated for residuals that hang together over about a block
    (GAP_BLOCK_S): the effective sample size is the blocks'. Per channel, so that a misfit in a
    channel a parameter does not act on (a vehicle speed signal off by its scale) does not widen
    that parameter's interval: cov = A⁻¹·(Σ s_c²·J_cᵀJ_c)·A⁻¹, A = JᵀJ."""
    jac, res = result.jac, result.fun
    if jac is None or res is None:
        raise ValueError("a fit without its Jacobian has no intervals")
    n = int(pb.rows.sum())
    k = jac.shape[1]
    inflate = max(n / pb.blocks(pb.rows), 1.0)
    channels = 3 if pb.has_speed else 2
    middle = np.zeros((k, k))
    for c in range(channels):
        block, r = jac[c * n : (c + 1) * n], res[c * n : (c + 1) * n]
        middle += float(np.sum(r**2)) / max(n - k, 1) * inflate * (block.T @ block)
    priors = jac[channels * n :]  # already in units of their spread
    middle += priors.T @ priors
    outer = np.linalg.pinv(jac.T @ jac)
    cov = outer @ middle @ outer
    free = np.array([p.free for p in result.params])
    scales = np.array([p.scale for p in result.params])
    half = np.zeros(len(free))  # a parameter held at its value has no interval of its own
    half[free] = Z95 * np.sqrt(np.clip(np.diag(cov), 0.0, None)) * scales[free]
    return tuple((v - w, v + w) for v, w in zip(result.values, half.tolist(), strict=True))


@dataclass(frozen=True)
class Scored:
    """A candidate's held-out scores and its fit on every sample (with the nuisances)."""

    candidate: Candidate
    fit: Fit  # nuisances + effect, every usable sample
    folds: tuple[Fit, ...]  # nuisances + effect, per training fold
    gap_before: float  # held-out sideslip gap of the calibrated model (its rival held), deg
    gap_after: float
    yaw_before: float  # deg/s
    yaw_after: float
    speed_before: float  # the vehicle speed signal's, m/s
    speed_after: float
    rival_gap: float | None = None  # the held-out sideslip gap with the rival nuisance calibrated

    @property
    def effect_values(self) -> tuple[float, ...]:
        return self.fit.values[-len(self.candidate.params) :]

    @property
    def at_bound(self) -> tuple[str, ...]:
        """Parameters whose fit ended on a physical bound: the effect's, or a nuisance's (bent to
        make room for the effect)."""
        return self.fit.at_bound()

    @property
    def shrink(self) -> float:
        return 1.0 - self.gap_after / self.gap_before if self.gap_before > 0 else 0.0

    def without_effect(self) -> Mods:
        """The fit's nuisances alone: the model beside the effect, with the effect taken out."""
        n = len(self.fit.params) - len(self.candidate.params)
        return mods_of(Fit(self.fit.params[:n], self.fit.values[:n], 0.0).fields())

    @property
    def speed_shrink(self) -> float:
        return 1.0 - self.speed_after / self.speed_before if self.speed_before > 0 else 0.0


@dataclass(frozen=True)
class Heldout:
    """The folds, and the calibrated model's held-out gaps: what every candidate is scored on."""

    fold: np.ndarray
    held: tuple[np.ndarray, ...]
    baseline: tuple[Fit, ...]
    gap: float
    yaw: float
    speed: float
    noise: float
    yaw_spread: float  # the yaw-rate channel's unit, deg/s


def heldout(pb: Problem, fold: np.ndarray, baseline: tuple[Fit, ...]) -> Heldout:
    """The calibrated model's held-out gaps, from its fits on each training fold (``baseline``,
    made by ``_baselines``)."""
    held = tuple(pb.rows & (fold == k) for k in (0, 1))
    sims = [pb.simulate(mods_of(f.fields())) for f in baseline]
    parts = list(zip(sims, held, strict=True))
    noise = math.sqrt(sum(pb.gap_noise_deg(rows) ** 2 for rows in held) / 2)
    return Heldout(
        fold,
        held,
        baseline,
        _pooled(pb.rms_beta_deg, parts),
        _pooled(pb.rms_yaw_degps, parts),
        _pooled(pb.rms_speed_mps, parts),
        noise,
        math.degrees(pb.scale_r),
    )


def _baseline_jobs(pb: Problem, calibration: NuisanceFit, fold: np.ndarray, effect: EffectName) -> list[_Job]:
    """The calibrated model's fits on each training fold (with the nuisances ``effect`` is
    fitted beside)."""
    params, start = calibration.params_for(effect), calibration.start_for(effect)
    return [_Job(params, pb.rows & (fold != k), (start,)) for k in (0, 1)]


def _baselines(
    pb: Problem, calibration: NuisanceFit, fold: np.ndarray, effects: Sequence[EffectName], workers: int
) -> list[Heldout]:
    """``heldout`` for each of ``effects``, their fits made together in ``workers`` processes."""
    jobs = [job for effect in effects for job in _baseline_jobs(pb, calibration, fold, effect)]
    fits = _fit_all(pb, jobs, workers)
    return [heldout(pb, fold, tuple(fits[2 * k : 2 * k + 2])) for k in range(len(effects))]


@dataclass(frozen=True)
class _Variant:
    """One way a candidate is scored: the nuisances fitted beside it, where they start, and the
    held-out gaps it is judged against (``held``: its rival nuisance held, those of the
    calibrated model without it)."""

    candidate: Candidate
    nuisance_params: tuple[Param, ...]
    calibrated: tuple[float, ...]
    ho: Heldout
    held: bool = False

    @property
    def params(self) -> tuple[Param, ...]:
        return (*self.nuisance_params, *self.candidate.params)


def _variants(
    calibration: NuisanceFit, ho: Heldout, candidate: Candidate, rival: Heldout | None
) -> list[_Variant]:
    """The candidate with the nuisances; one a nuisance imitates also with that nuisance held."""
    if rival is None:
        return [_Variant(candidate, calibration.params, calibration.values, ho)]
    effect = candidate.effect
    return [
        _Variant(candidate, calibration.params_for(effect, rival_free=True), calibration.values, ho),
        _Variant(candidate, calibration.params_for(effect), calibration.start_for(effect), rival, held=True),
    ]


def _everything(pb: Problem, variant: _Variant) -> Fit:
    """The candidate fitted with the nuisances on every sample. The nuisances start both from the
    calibration and from the config's values (a large effect the calibration could not see may
    have bent it): the better fit wins."""
    params = variant.params
    effect_starts = list(itertools.product(*(p.starts for p in variant.candidate.params)))

    def from_(base: tuple[float, ...]) -> Fit:
        return fit(
            pb, params, pb.rows, start=_best_start(pb, params, pb.rows, [(*base, *e) for e in effect_starts])
        )

    everything = from_(variant.calibrated)
    if everything.at_bound():  # a large effect may have bent the calibration: start again from the config
        nominal = tuple(p.nominal for p in variant.nuisance_params)
        everything = min((everything, from_(nominal)), key=lambda f: f.cost)
    return everything


def _scored(pb: Problem, variant: _Variant, everything: Fit, folds: tuple[Fit, ...]) -> Scored:
    """A variant's held-out gaps: each fold's samples from its fit on the other."""
    ho = variant.ho
    sims = [pb.simulate(mods_of(f.fields())) for f in folds]
    parts = list(zip(sims, ho.held, strict=True))
    return Scored(
        variant.candidate,
        everything,
        folds,
        ho.gap,
        _pooled(pb.rms_beta_deg, parts),
        ho.yaw,
        _pooled(pb.rms_yaw_degps, parts),
        ho.speed,
        _pooled(pb.rms_speed_mps, parts),
    )


def _best_start(
    pb: Problem, params: tuple[Param, ...], rows: np.ndarray, starts: list[tuple[float, ...]]
) -> tuple[float, ...]:
    if len(starts) == 1:
        return starts[0]

    def cost(values: tuple[float, ...]) -> float:
        fields: dict[str, float] = {}
        for param, value in zip(params, values, strict=True):
            fields.update(param.to_mods(value))
        z = pb.residual(pb.simulate(Mods(**fields)), rows) / ROBUST_SCALE
        return float(np.sum(np.sqrt(1.0 + z * z)))

    return min(starts, key=cost)


def _pooled(
    measure: Callable[[Simulated, np.ndarray], float], parts: list[tuple[Simulated, np.ndarray]]
) -> float:
    total = sum(measure(sim, rows) ** 2 * rows.sum() for sim, rows in parts)
    n = sum(int(rows.sum()) for _, rows in parts)
    return math.sqrt(total / n) if n else 0.0


@dataclass(frozen=True)
class Added:
    """A candidate added to a leading effect: the joint fits per training fold (what the held-out
    test compares) and on every sample (nuisances, the leading effect, this one)."""

    candidate: Candidate
    folds: tuple[Fit, ...]
    fit: Fit

    @property
    def own_values(self) -> tuple[float, ...]:
        return self.fit.values[-len(self.candidate.params) :]


def add_to(pb: Problem, ho: Heldout, best: Scored, other: Candidate, workers: int = 1) -> Added:
    """``other`` fitted beside the leading effect (and the nuisances) on each training fold and
    on every sample (the three fits in ``workers`` processes)."""
    params = (*best.fit.params, *other.params)
    starts = list(itertools.product(*(p.starts for p in other.params)))
    jobs = [
        _Job(params, pb.rows & (ho.fold != k), tuple((*best.folds[k].values, *s) for s in starts))
        for k in (0, 1)
    ]
    jobs.append(_Job(params, pb.rows, tuple((*best.fit.values, *s) for s in starts)))
    *folds, everything = _fit_all(pb, jobs, workers)
    return Added(other, tuple(folds), everything)


def _params(params: Sequence[Param], values: Sequence[float]) -> dict[str, float]:
    return {p.name: round(v, 5) for p, v in zip(params, values, strict=True)}


def method_c2n(pb: Problem, beta: np.ndarray) -> float | None:
    """C2n as the method reads it from a sideslip series: β = ψ0 + d·κ − a_y/(g·C2n) over the
    steady samples, with the measured speed and yaw rate (as the measurement has them)."""
    m = pb.measured
    u, r = m.u_optical, m.r
    rows = pb.rows & m.steady & (np.abs(np.nan_to_num(u * r)) > 0.5)
    if rows.sum() < 50:
        return None
    kappa, ay = (r / u)[rows], (u * r)[rows]
    design = np.column_stack([np.ones(rows.sum()), kappa, ay])
    coef, *_ = np.linalg.lstsq(design, beta[rows], rcond=None)
    g = pb.params.g
    return float(-1.0 / (g * coef[2])) if coef[2] < 0 else None


def locate(pb: Problem, base: Simulated, fold: np.ndarray) -> list[Located]:
    """Where the sideslip residual concentrates: its share of the squared residual per slice,
    against the slice's share of the samples."""
    m = pb.measured
    rows = pb.rows
    res = np.degrees(m.beta - base.beta)
    ay = np.nan_to_num(m.u_optical * m.r)
    u_dot = np.gradient(np.nan_to_num(m.u_optical), m.dt)
    heading = (np.degrees(m.heading) % 360.0 + 45.0) % 360.0 // 90.0
    duration = m.t[-1] if len(m.t) else 0.0
    slices: dict[str, np.ndarray] = {
        "left turns": ay > 0.3,
        "right turns": ay < -0.3,
        "straight": np.abs(ay) <= 0.3,
        "|a_y| < 1 m/s²": np.abs(ay) < 1.0,
        "|a_y| 1–2 m/s²": (np.abs(ay) >= 1.0) & (np.abs(ay) < 2.0),
        "|a_y| 2–3 m/s²": (np.abs(ay) >= 2.0) & (np.abs(ay) < 3.0),
        "|a_y| ≥ 3 m/s²": np.abs(ay) >= 3.0,
        "speed sweeping up": u_dot > 0.1,
        "speed sweeping down": u_dot < -0.1,
        "steady": m.steady,
        "transient": ~m.steady,
        **{f"heading {name}": heading == q for q, name in enumerate(("N", "E", "S", "W"))},
        **{
            f"time {k + 1}/3 of the drive": (m.t >= k * duration / 3) & (m.t < (k + 1) * duration / 3 + 1e-9)
            for k in range(3)
        },
    }
    total = float(np.sum(res[rows] ** 2)) or 1.0
    n = int(rows.sum()) or 1
    out = []
    for where, mask in slices.items():
        inside = rows & mask
        if inside.sum() < 50:
            continue
        share = float(np.sum(res[inside] ** 2)) / total
        samples = float(inside.sum()) / n
        out.append(
            Located(
                where=where,
                share=round(share, 3),
                samples_share=round(samples, 3),
                concentration=round(share / samples, 2),
                mean_deg=round(float(np.mean(res[inside])), 4),
                rms_deg=round(float(np.sqrt(np.mean(res[inside] ** 2))), 4),
            )
        )
    return sorted(out, key=lambda row: -row.concentration)


@dataclass(frozen=True)
class Residuals:
    """The sideslip residual maps (deg) of the calibrated model and of the model with the effect."""

    t: np.ndarray
    ay: np.ndarray
    heading_deg: np.ndarray
    before: np.ndarray
    after: np.ndarray
    rows: np.ndarray


@dataclass(frozen=True)
class Diagnosis:
    result: GapResult  # what c2n gap --json writes
    residuals: Residuals


def _scores(
    pb: Problem, calibration: NuisanceFit, ho: Heldout, rivals: dict[EffectName, Heldout], workers: int
) -> list[tuple[Scored, tuple[tuple[float, float], ...]]]:
    """Every candidate scored, with its effect's 95 % intervals: fitted with the nuisances on every
    sample, then on each training fold starting from there, and its held-out gaps.

    A candidate a nuisance imitates is fitted twice: beside every nuisance (a drive may carry
    both), and with that nuisance held (``rivals``: the calibrated model's gaps without it), where
    it must explain the drive better than the nuisance does. The lower held-out gap counts.

    The fits on every sample, then the folds', are made in ``workers`` processes, two rounds of
    independent fits; only numbers cross the process edge (the candidates hold functions)."""
    variants = [v for c in CANDIDATES for v in _variants(calibration, ho, c, rivals.get(c.effect))]

    def whole(index: int) -> tuple[tuple[float, ...], float, tuple[tuple[float, float], ...]]:
        variant = variants[index]
        done = _everything(pb, variant)
        return done.values, done.cost, _intervals(pb, done)[-len(variant.candidate.params) :]

    firsts = map_forked(whole, len(variants), workers)
    everything = [Fit(v.params, values, cost) for v, (values, cost, _) in zip(variants, firsts, strict=True)]

    def fold(index: int) -> tuple[tuple[float, ...], float]:
        variant, k = variants[index // 2], index % 2
        done = fit(pb, variant.params, pb.rows & (variant.ho.fold != k), start=everything[index // 2].values)
        return done.values, done.cost

    seconds = map_forked(fold, 2 * len(variants), workers)
    best: dict[str, tuple[Scored, tuple[tuple[float, float], ...]]] = {}
    for k, variant in enumerate(variants):
        folds = tuple(Fit(variant.params, *seconds[2 * k + j]) for j in (0, 1))
        scored = _scored(pb, variant, everything[k], folds)
        if variant.held:
            scored = replace(scored, rival_gap=ho.gap)
        effect = variant.candidate.effect
        if effect not in best or scored.gap_after < best[effect][0].gap_after:
            best[effect] = (scored, firsts[k][2])
    return [best[c.effect] for c in CANDIDATES]


def diagnose(m: Measured, config: Config, workers: int = 1) -> Diagnosis:
    """The diagnosis of a measured drive against the config's car; ``workers``: processes that
    score the candidates. BLAS runs on one thread: the fits' linear algebra is hundreds of small
    SVDs, for which a thread pool costs more than it gives (a session: 13 s against 6 s)."""
    with threadpool_limits(limits=1, user_api="blas"):
        return _diagnose(m, config, workers)


_CHANNELS = ("sideslip", "yaw", "speed")


def _heldout_residuals(pb: Problem, fold: np.ndarray, fits: Sequence[Fit]) -> dict[str, np.ndarray]:
    """Each channel's residual where it is held out: fold k's samples from the fit on the other."""
    m = pb.measured
    sims = [pb.simulate(mods_of(f.fields())) for f in fits]
    channels = {
        "sideslip": [m.beta - s.beta for s in sims],
        "yaw": [s.r_measured - s.r for s in sims],
        "speed": [m.u_vehicle - s.speed_reading for s in sims],
    }
    return {name: np.where(fold == 0, a, b) for name, (a, b) in channels.items()}


@dataclass(eq=False)  # one candidate's judgement: compared by identity
class _Judged:
    """A candidate as the held-out test and the tolerances judge it."""

    scored: Scored
    ci95: tuple[tuple[float, float], ...]
    after: dict[str, np.ndarray]  # held-out residuals with it
    gain: float  # in its own channel, over its standard error
    present: bool
    reason: str | None  # why it is not present, or not a finding
    shift: C2nShift
    size: tuple[float, float] | None
    importance: float
    confounded: list[EffectName]

    @property
    def effect(self) -> EffectName:
        return self.scored.candidate.effect

    @property
    def matters(self) -> bool:
        return self.present and self.importance >= 1.0 and self.reason is None


def _units(pb: Problem, ids: np.ndarray, res: dict[str, np.ndarray], name: str | None = None) -> np.ndarray:
    """Each manoeuvre's held-out gap in one channel (the sideslip on its steady samples), or in
    all of them on every sample, weighed as the fit weighs them (each channel in its own unit)."""
    m, rows = pb.measured, pb.rows
    if name == "sideslip" and (rows & m.steady).sum() * m.dt >= MIN_USABLE_S:
        return unit_gaps(m.t, res[name], rows & m.steady, ids)
    if name is not None:
        return unit_gaps(m.t, res[name], rows, ids)
    scales = {"sideslip": pb.scale_beta, "yaw": pb.scale_r / YAW_WEIGHT, "speed": pb.scale_u / SPEED_WEIGHT}
    used = [c for c in _CHANNELS if c != "speed" or pb.has_speed]
    return np.asarray(np.sum([unit_gaps(m.t, res[c], rows, ids) / scales[c] ** 2 for c in used], axis=0))


def _judge(
    pb: Problem,
    config: Config,
    calibration: NuisanceFit,
    ids: np.ndarray,
    bases: dict[str, dict[str, np.ndarray]],
    scored: Scored,
    ci95: tuple[tuple[float, float], ...],
    before: dict[str, np.ndarray] | None = None,
) -> _Judged:
    """One candidate: present (its held-out gain beyond the drive's spread, no channel worse),
    and what it does to C2n and in its own unit."""
    m, rows, fold = pb.measured, pb.rows, bases["fold"]["fold"]
    effect = scored.candidate.effect
    if before is None:
        before = bases["rival" if scored.rival_gap is not None else "none"]
    after = _heldout_residuals(pb, fold, scored.folds)
    own = channel(effect)

    gain = (
        gain_z(_units(pb, ids, before, own), _units(pb, ids, after, own))
        if own == "sideslip" or pb.has_speed
        else 0.0
    )
    worse = (
        gain_z(_units(pb, ids, before), _units(pb, ids, after)) < -Z_TEST
    )  # the fit's own measure, held out
    reason = None
    if scored.at_bound:
        reason = f"its fit ended on a physical bound ({', '.join(scored.at_bound)})"
    elif gain <= Z_TEST:
        reason = f"its held-out gain in the {own} is z = {gain:.1f}: within the drive's own spread"
    elif worse:
        reason = "it makes the held-out gap of the channels together worse"
    c2n = calibration.values[[p.name for p in calibration.params].index("c2n_per_rad")]
    delta = pb.simulate(mods_of(scored.fit.fields())).beta - pb.simulate(scored.without_effect()).beta
    shift = c2n_shift(m, rows, delta, pb.d_m, c2n, pb.params.g)
    size = own_size(effect, _params(scored.candidate.params, scored.effect_values), config)
    return _Judged(
        scored, ci95, after, gain, reason is None, reason, shift, size, importance(shift, size, config), []
    )


def _together(
    pb: Problem,
    config: Config,
    calibration: NuisanceFit,
    ho: Heldout,
    ids: np.ndarray,
    bases: dict[str, dict[str, np.ndarray]],
    judged: list[_Judged],
    workers: int = 1,
) -> tuple[list[_Judged], dict[str, Added]]:
    """The findings, fitted together: the one that matters most leads; each other one that
    matters is added to the finding of its channel and kept where it shrinks, held out, what that
    one left — else it is confounded with it."""
    findings: list[_Judged] = []
    joint: dict[str, Added] = {}
    order = {c.effect: k for k, c in enumerate(CANDIDATES)}
    for j in sorted((j for j in judged if j.matters), key=lambda j: -j.importance):
        lead = next((f for f in findings if channel(f.effect) == channel(j.effect)), None)
        if lead is None:
            findings.append(j)
            continue
        added = add_to(pb, ho, lead.scored, j.scored.candidate, workers)
        both = _heldout_residuals(pb, ho.fold, added.folds)
        own = channel(j.effect)
        gain = gain_z(_units(pb, ids, lead.after, own), _units(pb, ids, both, own))
        if gain > Z_TEST and not added.fit.at_bound():
            findings.append(j)
            joint[j.effect] = added
        else:
            if order[j.effect] < order[lead.effect]:  # the drive cannot tell them apart: the
                findings[findings.index(lead)] = j  # vocabulary's order names one (Effect's order)
                j.confounded.extend([lead.effect, *lead.confounded])
                lead.confounded.clear()
                lead, j = j, lead
            else:
                lead.confounded.append(j.effect)
            j.confounded = [lead.effect]
            j.reason = (
                f"the drive cannot tell it from {lead.effect} (added to it, a held-out gain of "
                f"z = {gain:.1f})"
            )
    if findings:
        findings += _beside(pb, config, calibration, ho, ids, bases, judged, findings, joint, workers)
    return findings, joint


def _beside(
    pb: Problem,
    config: Config,
    calibration: NuisanceFit,
    ho: Heldout,
    ids: np.ndarray,
    bases: dict[str, dict[str, np.ndarray]],
    judged: list[_Judged],
    findings: list[_Judged],
    joint: dict[str, Added],
    workers: int = 1,
) -> list[_Judged]:
    """A candidate whose fit alone bent a nuisance to its bound (making room for an effect it
    does not have: the finding's) is fitted again beside the finding of its channel, or the first
    one, and judged on what that finding left."""
    more = []
    for k, j in enumerate(judged):
        bent = set(j.scored.at_bound) - {p.name for p in j.scored.candidate.params}
        if j in findings or j.confounded or not bent:
            continue
        lead = next((f for f in findings if channel(f.effect) == channel(j.effect)), findings[0])
        added = add_to(pb, ho, lead.scored, j.scored.candidate, workers)
        sims = [pb.simulate(mods_of(f.fields())) for f in added.folds]
        parts = list(zip(sims, ho.held, strict=True))
        s = lead.scored
        scored = Scored(
            j.scored.candidate,
            added.fit,
            added.folds,
            s.gap_after,
            _pooled(pb.rms_beta_deg, parts),
            s.yaw_after,
            _pooled(pb.rms_yaw_degps, parts),
            s.speed_after,
            _pooled(pb.rms_speed_mps, parts),
        )
        ci95 = _intervals(pb, added.fit)[-len(j.scored.candidate.params) :]
        again = _judge(pb, config, calibration, ids, bases, scored, ci95, before=lead.after)
        judged[k] = again
        if again.matters:
            more.append(again)
            joint[again.effect] = added
    return more


def _judged_text(j: _Judged, config: Config) -> str:
    """Why an effect matters, or what it is within."""
    parts = []
    if j.shift.crossing is not None:
        parts.append(
            f"C2n {j.shift.crossing:+.2f} % on a single crossing, {j.shift.headline:+.2f} % on the headline"
        )
    if j.size is not None:
        parts.append(f"size {j.size[0]:.4g} against a tolerance of {j.size[1]:.4g}")
    what = "; ".join(parts) or "no effect on C2n"
    if not j.present:
        return f"not present: {j.reason}"
    if j.reason is not None:
        return j.reason
    if j.matters:
        return f"matters: {what} (tolerance ±{config.gap.c2n_pct:g} % of C2n)"
    return f"within tolerance: {what} (tolerance ±{config.gap.c2n_pct:g} % of C2n)"


def _effect(j: _Judged, config: Config) -> Effect:
    s, own = j.scored, channel(j.effect)
    before, after = (s.gap_before, s.gap_after) if own == "sideslip" else (s.speed_before, s.speed_after)
    names = [p.name for p in s.candidate.params]
    action = s.candidate.action(s.effect_values)
    if j.shift.crossing is not None and own == "sideslip":
        action += (
            f" (single crossings move {j.shift.crossing:+.1f} %, the headline {j.shift.headline:+.1f} %)"
        )
    if not j.matters:
        action = f"within tolerance: nothing to do ({_judged_text(j, config)})"
    return Effect(
        effect=j.effect,
        channel=own,
        params=_params(s.candidate.params, s.effect_values),
        ci95={n: (round(lo, 5), round(hi, 5)) for n, (lo, hi) in zip(names, j.ci95, strict=True)},
        shrink_heldout=round(1.0 - after / before if before > 0 else 0.0, 4),
        heldout_before=round(before, 5),
        heldout_after=round(after, 5),
        gain_sigmas=round(j.gain, 2),
        c2n_effect_pct=C2nEffect(j.shift.crossing, j.shift.headline),
        matters=j.matters,
        judged=_judged_text(j, config),
        confounded_with=tuple(j.confounded),
        action=action,
    )


def _diagnose(m: Measured, config: Config, workers: int) -> Diagnosis:
    pb = problem(m, config)
    pb, calibration = calibrate(pb, nuisances(config))
    _refuse_without_crossings(pb, calibration)
    calibrated = pb.simulate(calibration.mods())
    ids = manoeuvres(m)
    fold = folds(m, ids)
    names = {p.name for p in calibration.params}
    imitated = {rival: effect for effect, rival in RIVAL_NUISANCE.items() if rival in names}
    ho, *rival_ho = _baselines(pb, calibration, fold, ["none", *imitated.values()], workers)
    held = dict(zip(imitated, rival_ho, strict=True))
    rivals = {effect: held[rival] for effect, rival in RIVAL_NUISANCE.items() if rival in held}
    bases = {"none": _heldout_residuals(pb, fold, ho.baseline), "fold": {"fold": fold}}
    for rival in held.values():  # one rival nuisance at most
        bases["rival"] = _heldout_residuals(pb, fold, rival.baseline)
    pairs = sorted(_scores(pb, calibration, ho, rivals, workers), key=lambda p: -p[0].shrink)
    units = test_units(ids)
    judged = [_judge(pb, config, calibration, units, bases, s, ci) for s, ci in pairs]
    findings, joint = _together(pb, config, calibration, ho, units, bases, judged, workers)
    measured_effects = method_effects(m, config)
    # where the method measures an effect's own parameter, its measurement decides, not the fit's
    direct = DIRECT & {e.effect for e in measured_effects}
    fitted_beside = findings  # the nuisances are reported as fitted beside every effect the fit named
    findings = [f for f in findings if f.effect not in direct]
    lead = findings[0] if findings else None
    best = lead.scored if lead is not None else None
    after_sim = calibrated
    beside = calibration.fit  # the nuisances as reported: calibrated beside the effects named
    confounded: list[str] = []
    diagnosis: str  # an effect of the vocabulary, or "unexplained"
    if lead is not None and best is not None:
        diagnosis = lead.effect
        confounded = list(lead.confounded)
        last = joint.get(findings[-1].effect)
        after_sim = pb.simulate(mods_of((last.fit if last else best.fit).fields()))
        joint_fit = last.fit if last else best.fit
        beside = fit(pb, joint_fit.params, pb.rows, start=joint_fit.values)
    else:
        diagnosis = "none" if ho.gap <= config.gap.sideslip_deg else "unexplained"
        if diagnosis == "none":
            confounded = [*HIDDEN_BY_CALIBRATION, *hidden_by_rivals(calibration)]
    if len(fitted_beside) > len(findings):  # a d the regression measures: the fit's, beside it
        last_fit = joint.get(fitted_beside[-1].effect)
        beside_fit = last_fit.fit if last_fit else fitted_beside[0].scored.fit
        beside = fit(pb, beside_fit.params, pb.rows, start=beside_fit.values)
    effects = [_effect(j, config) for j in findings] + [
        _effect(j, config)
        for j in sorted((j for j in judged if j.present and j not in findings), key=lambda j: -j.importance)
    ]
    own_shrink = effects[0].shrink_heldout if lead is not None else 0.0
    lead_importance = lead.importance if lead else 0.0
    effects = with_method_effects(effects, measured_effects, lead_importance, config)
    first = effects[0] if effects else None
    measured_lead = first if first and first.measured_by != HELDOUT_FIT and first.matters else None
    if measured_lead is not None:  # what the held-out fit led with is now a secondary finding
        diagnosis, confounded = measured_lead.effect, [] if lead is not None else confounded
    # an effect the method measured, present or not, is not hidden in a calibrated nuisance: its
    # entry gives its size and interval
    measured = {e.effect for e in effects if e.measured_by != HELDOUT_FIT}
    confounded = [c for c in confounded if c not in measured]
    without = pb.simulate(best.without_effect()) if best is not None else calibrated
    effect_delta = pb.simulate(mods_of(best.fit.fields())).beta - without.beta if best is not None else 0.0
    residuals = Residuals(
        t=m.t,
        ay=np.nan_to_num(m.u_optical * m.r),
        heading_deg=np.degrees(m.heading) % 360.0,
        before=np.degrees(m.beta - calibrated.beta),
        after=np.degrees(m.beta - after_sim.beta),
        rows=pb.rows,
    )
    sideslip_joint = [
        joint[f.effect] for f in findings if f.effect in joint and channel(f.effect) == "sideslip"
    ]
    total = _shrink_with(pb, ho, sideslip_joint[-1]) if sideslip_joint and best is not None else None
    c2n_index = [p.name for p in calibration.params].index("c2n_per_rad")
    result = GapResult(
        diagnosis=diagnosis,
        confounded_with=tuple(confounded),
        secondary=tuple(
            Secondary(e.effect, e.params, e.shrink_heldout, e.action) for e in effects[1:] if e.matters
        ),
        calibration=_calibrated(pb, calibration, beside),
        located=tuple(locate(pb, calibrated, fold)),
        candidates=tuple(_candidate_score(j, findings) for j in judged),
        c2n=GapC2n(
            nominal=config.tyres.c2n_per_rad,
            calibrated=round(beside.values[c2n_index], 4),
            sim=_r(method_c2n(pb, pb.simulate(Mods()).beta)),
            measured=_r(method_c2n(pb, m.beta)),
            after=_r(method_c2n(pb, after_sim.beta)),
            corrected=_r(method_c2n(pb, m.beta - effect_delta)) if best is not None else None,
            pipeline=m.summary.c2n,
        ),
        shrink_heldout=round(max(own_shrink, 0.0), 4),
        shrink_heldout_with_secondary=round(max(own_shrink, total if total is not None else 0.0), 4),
        heldout_rms_deg=BeforeAfter(
            round(best.gap_before if best else ho.gap, 5), round(best.gap_after if best else ho.gap, 5)
        ),
        heldout_yaw_rms_degps=BeforeAfter(
            round(best.yaw_before if best else ho.yaw, 5), round(best.yaw_after if best else ho.yaw, 5)
        ),
        verdict=_verdict(
            diagnosis, effects[0] if lead is not None or measured_lead else None, ho, confounded, config
        ),
        action=effects[0].action if lead is not None or measured_lead else None,
        separate_by={
            other: {**HIDDEN_BY_CALIBRATION, **HIDDEN_BY_RIVAL}[other]
            if best is None
            else separating_manoeuvre(diagnosis, other)
            for other in confounded
        },
        noise=GapNoise(
            sideslip_deg=round(math.degrees(pb.sigma_beta), 5),
            yaw_rate_degps=round(math.degrees(pb.sigma_r), 5),
            sideslip_gap_deg=round(ho.noise, 5),
        ),
        manoeuvres=len(np.unique(ids)),
        speed_input=m.speed_source,
        effects=tuple(effects),
        tolerances={
            "c2n_pct": config.gap.c2n_pct,
            "sideslip_deg": config.gap.sideslip_deg,
            "speed_pct": config.gap.speed_pct,
            "latency_s": config.gap.latency_s,
            "d_mm": config.calibration.d_tolerance_mm,
        },
    )
    return Diagnosis(result, residuals)


def _refuse_without_crossings(pb: Problem, calibration: NuisanceFit) -> None:
    """The report says what each effect does to C2n read from zero crossings: a drive without
    steady turning near the crossing's speed, either way, cannot say it — refused, naming the
    manoeuvre."""
    m = pb.measured
    c2n = calibration.values[[p.name for p in calibration.params].index("c2n_per_rad")]
    near = near_crossings(m, pb.rows, pb.d_m, c2n, pb.params.g)
    r = np.nan_to_num(m.r)
    seconds = [float((near & (np.sign(r) == side)).sum() * m.dt) for side in (1.0, -1.0)]
    if max(seconds) < MIN_CROSSING_S:
        u0 = math.sqrt(pb.params.g * pb.d_m * c2n)
        raise NoResultError(
            f"no steady cornering near the sideslip's sign change ({seconds[0]:.0f} s left, "
            f"{seconds[1]:.0f} s right within ±50 % of u0² = g·d·C2n, u0 ≈ {u0:.1f} m/s, "
            f"|a_y| ≤ {LINEAR_AY_MPS2:g} m/s²): what an effect does to C2n cannot be judged — drive "
            "constant-radius sweeps through u0, left and right"
        )


def _shrink_with(pb: Problem, ho: Heldout, added: Added) -> float:
    """The held-out sideslip gap's shrink with the findings fitted together."""
    sims = [pb.simulate(mods_of(f.fields())) for f in added.folds]
    gap = _pooled(pb.rms_beta_deg, list(zip(sims, ho.held, strict=True)))
    return 1.0 - gap / ho.gap if ho.gap > 0 else 0.0


def _calibrated(pb: Problem, calibration: NuisanceFit, beside: Fit) -> dict[str, Calibrated]:
    """Each nuisance as fitted beside the effects named, with its 95 % interval there; one the
    drive did not show keeps the calibration's interval (which covers its nominal value), one held
    beside the effect it imitates has none."""
    intervals = _intervals(pb, beside) if beside is not calibration.fit else calibration.ci95
    out = {}
    for k, p in enumerate(calibration.params):
        value, held = beside.values[k], None
        if beside.params[k].free:
            low, high = intervals[k]
        elif not p.free:
            low, high = calibration.ci95[k]
            held = "not seen in this drive (its interval covers the nominal value)"
        else:
            low = high = p.nominal
            held = "the effect named explains the drive better"
        out[p.name] = Calibrated(
            round(p.nominal, 5),
            round(value, 5),
            (round(low, 5), round(high, 5)),
            beside.params[k].at_bound(value),
            held,
        )
    return out


def _candidate_score(j: _Judged, findings: list[_Judged]) -> CandidateScore:
    s = j.scored
    return CandidateScore(
        effect=s.candidate.effect,
        params=_params(s.candidate.params, s.effect_values),
        at_bound=s.at_bound,
        heldout_rms_before=round(s.gap_before, 5),
        heldout_rms_after=round(s.gap_after, 5),
        heldout_yaw_rms_before=round(s.yaw_before, 5),
        heldout_yaw_rms_after=round(s.yaw_after, 5),
        shrink_heldout=round(s.shrink, 4),
        named=j in findings,
        why_not=None if j in findings else j.reason or "within tolerance",
    )


def hidden_by_rivals(calibration: NuisanceFit) -> list[str]:
    """The effects whose rival nuisance the drive showed (calibrated free, not held at nominal):
    such an effect could be inside it."""
    free = {p.name for p in calibration.params if p.free}
    return [effect for effect, rival in RIVAL_NUISANCE.items() if rival in free and effect in HIDDEN_BY_RIVAL]


def _verdict(diagnosis: str, lead: Effect | None, ho: Heldout, confounded: list[str], config: Config) -> str:
    """The diagnosis in a sentence: what was found, and what the held-out test showed."""
    twins: dict[str, str] = {**NUISANCE_TWINS, **dict(RIVAL_NUISANCE.items())}
    inside: dict[str, list[str]] = {}
    for effect in confounded:
        if effect in twins:
            inside.setdefault(twins[effect], []).append(f"a {effect.replace('_', ' ')}")
    hidden = "; ".join(f"{' or '.join(e)} would be inside the calibrated {n}" for n, e in inside.items())
    if lead is None and diagnosis == "none":
        return (
            f"none: the calibrated model is within {ho.gap:.4f}° of the drive's sideslip (held out; "
            f"tolerance {config.gap.sideslip_deg:g}°); no effect found matters"
            + (f" ({hidden})" if hidden else "")
        )
    if lead is None:
        return (
            f"unexplained: the calibrated model leaves a held-out sideslip gap of {ho.gap:.4f}°, beyond "
            f"the sensor's {config.gap.sideslip_deg:g}°, that no candidate effect found matters for "
            "(see where it lies)"
        )
    if lead.heldout_before is None or lead.heldout_after is None:
        return f"{diagnosis}, measured by {lead.measured_by}: {lead.judged.removeprefix('matters: ')}" + (
            f"; {hidden}" if hidden else ""
        )
    unit = "°" if lead.channel == "sideslip" else " m/s"
    where = "sideslip" if lead.channel == "sideslip" else "vehicle speed signal"
    text = (
        f"{diagnosis}: held-out {where} gap {lead.heldout_before:.4f}{unit} → "
        f"{lead.heldout_after:.4f}{unit} (shrink {max(lead.shrink_heldout, 0.0):.0%}, "
        f"gain z = {lead.gain_sigmas:.1f})"
    )
    twin = NUISANCE_TWINS.get(diagnosis)
    if twin:
        text += f"; in steady state it is indistinguishable from a calibrated {twin}"
    return text


def _r(x: float | None) -> float | None:
    return None if x is None else round(x, 4)
