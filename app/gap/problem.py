"""The gap's problem: the measured drive on the grid, the nominal car, each channel's noise and
unit (``Problem``), and the robust least-squares fit of the model's parameters to it (``fit``),
one by one or in forked processes (``fit_all``). Manoeuvres and the two folds they alternate
between are cut here too."""

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
from scipy.optimize import least_squares

from app.config import Config
from app.detect.quasi_steady import AY_MIN_MPS2, GRIP_MAX_MPS2, Cornering
from app.errors import NoResultError
from app.gap.candidates import Param
from app.gap.forked import map_forked
from app.gap.measured import Measured
from app.gap.nominal_model import Mods, Prepared, Simulated, prepare, run_model, simulate
from app.results.refusal import beyond_grip, reads_backwards, speed_min_problem
from app.sim.vehicle_model import BicycleParams

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
    beyond = np.count_nonzero(turning & (u >= speed_min) & (np.abs(u * np.nan_to_num(m.r)) > GRIP_MAX_MPS2))
    cornering = Cornering(turning_s=forwards, below_speed_s=below, beyond_grip_s=beyond * m.dt)
    return beyond_grip(cornering) or speed_min_problem(cornering, speed_min)


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
class FitJob:
    """A fit to make: its parameters, its rows, and where it may start (the best of ``starts``)."""

    params: tuple[Param, ...]
    rows: np.ndarray
    starts: tuple[tuple[float, ...], ...]


def fit_all(pb: Problem, jobs: Sequence[FitJob], workers: int) -> list[Fit]:
    """Each job's fit, in ``workers`` processes (the same fits ``fit`` makes one by one: only
    their numbers cross the process edge)."""

    def numbers(index: int) -> tuple[tuple[float, ...], float, np.ndarray | None, np.ndarray | None]:
        job = jobs[index]
        done = fit(pb, job.params, job.rows, start=best_start(pb, job.params, job.rows, list(job.starts)))
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
    return with_scales(pb, base)


def _diverged() -> NoResultError:
    """The bicycle model of the config's car diverges on this drive (e.g. a wheelbase so short
    that its yaw mode is faster than the 20-ms grid): there is nothing to fit."""
    return NoResultError(
        "the config's car cannot follow this drive: its model's response is not finite "
        "(check [vehicle] wheelbase_m, the axle loads and [tyres] in the config)"
    )


def with_scales(pb: Problem, sim: Simulated) -> Problem:
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


def best_start(
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
