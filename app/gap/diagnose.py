"""Where the measured drive departs from the nominal model, which effect explains it, how far the
gap shrinks once it is added — each effect fitted on some manoeuvres and scored on the others."""

import itertools
import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import least_squares

from app.config import Config
from app.gap.candidates import CANDIDATES, Candidate, separating_manoeuvre
from app.gap.measured import Measured
from app.gap.model import NOMINAL, Mods, Simulated, simulate
from app.gap.result import BeforeAfter, CandidateScore, GapC2n, GapNoise, GapResult, Located
from app.sim.vehicle_model import BicycleParams

NONE_THRESHOLD = 0.05  # a held-out improvement of the fit cost below this is noise: 'none'
YAW_WEIGHT = 0.3  # the yaw rate carries the driver's corrections the model cannot follow
GAP_BLOCK_S = 1.0  # the sideslip gap is measured on 1-s means
ROBUST_SCALE = 3.0  # residuals beyond this many noise σ count less (soft L1)
CONFOUNDED_SHARE = 0.8  # candidates reaching this share of the best improvement are confounded
DEFAULT_ROLL_AXIS_HEIGHT_M = 0.10  # at the sensor, where the config does not say: a saloon's roll centres
_STRAIGHT_RADPS, _TURNING_RADPS = 0.015, 0.03
_MIN_MANOEUVRE_S = 2.0


@dataclass(frozen=True)
class Scored:
    candidate: Candidate
    params: tuple[float, ...]  # fitted on every manoeuvre
    cost_before: float  # held-out normalised cost, nominal model
    cost_after: float  # held-out, with the effect fitted on the other manoeuvres
    rms_before_deg: float  # held-out sideslip residual
    rms_after_deg: float
    sim: Simulated  # the model with the effect (all-data fit)

    @property
    def improvement(self) -> float:
        return 1.0 - self.cost_after / self.cost_before if self.cost_before > 0 else 0.0


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
    """Fold 0 or 1 per grid step: manoeuvres of each kind (left, right, straight) alternate."""
    fold = np.zeros(len(ids), dtype=np.int8)
    seen: dict[int, int] = {}
    r = np.nan_to_num(m.r)
    for run in np.unique(ids):
        rows = ids == run
        kind = int(np.sign(np.median(r[rows]))) if np.abs(np.median(r[rows])) > _STRAIGHT_RADPS else 0
        fold[rows] = seen.get(kind, 0) % 2
        seen[kind] = seen.get(kind, 0) + 1
    return fold


def _usable(m: Measured) -> np.ndarray:
    usable = np.isfinite(m.beta) & np.isfinite(m.r) & np.isfinite(m.delta)
    return np.asarray(usable & (np.nan_to_num(m.u_optical) > 5.0))


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
    sigma_beta: float
    sigma_r: float

    def residual(self, sim: Simulated, rows: np.ndarray) -> np.ndarray:
        m = self.measured
        return np.concatenate(
            [
                (m.beta - sim.beta)[rows] / self.sigma_beta,
                YAW_WEIGHT * (sim.r_measured - sim.r)[rows] / self.sigma_r,
            ]
        )

    def cost(self, sim: Simulated, rows: np.ndarray) -> float:
        """Mean robust loss of the normalised residuals (soft L1, as the fit uses): transients the
        bicycle model cannot follow (tyre relaxation, roll) weigh less than the steady bulk."""
        z = self.residual(sim, rows) / ROBUST_SCALE
        return float(np.mean(2.0 * ROBUST_SCALE**2 * (np.sqrt(1.0 + z * z) - 1.0))) if len(z) else 0.0

    def rms_beta_deg(self, sim: Simulated, rows: np.ndarray) -> float:
        """The sideslip gap: the systematic part of the residual, which a model could explain.

        The residual is averaged over 1-s blocks and each block's mean counts by its samples (a
        block cut short by a fold boundary holds few samples and mostly noise); the white sensor
        noise left in a mean of n samples, σ²/n, is taken out of its square. The result is the
        RMS over samples of the residual's slow part, with the noise removed rather than averaged
        down.
        """
        m = self.measured
        if not rows.any():
            return 0.0
        block = (m.t[rows] // GAP_BLOCK_S).astype(np.int64)
        res = (m.beta - sim.beta)[rows]
        sums, counts = np.bincount(block, res), np.bincount(block)
        filled = counts > 0
        square = float(np.sum(sums[filled] ** 2 / counts[filled])) - filled.sum() * self.sigma_beta**2
        return math.degrees(math.sqrt(max(square, 0.0) / rows.sum()))

    def simulate(self, mods: Mods | None = None) -> Simulated:
        return simulate(
            self.params, self.measured, self.d_m, mods or NOMINAL, self.cg_height_m, self.roll_lever_m
        )

    def fit(self, candidate: Candidate, rows: np.ndarray) -> tuple[float, ...]:
        scales = np.array([p.scale for p in candidate.params])

        def residual(x: np.ndarray) -> np.ndarray:
            return self.residual(self.simulate(candidate.mods(tuple(x * scales))), rows)

        low = np.array([p.low / p.scale for p in candidate.params])
        starts = [np.array(x) / scales for x in itertools.product(*(p.starts for p in candidate.params))]
        if len(starts) > 1:
            costs = [self.cost(self.simulate(candidate.mods(tuple(x * scales))), rows) for x in starts]
            start = starts[int(np.argmin(costs))]
        else:
            start = starts[0]
        solution = least_squares(
            residual,
            np.clip(start, low, np.inf),
            bounds=(low, np.inf),
            loss="soft_l1",
            f_scale=ROBUST_SCALE,
            max_nfev=40,
        )
        return tuple(float(v) for v in solution.x * scales)


def problem(m: Measured, config: Config) -> Problem:
    params = BicycleParams.from_config(config)
    rows = _usable(m)
    cg_height, lever = config.vehicle.cg_height_m, roll_lever_m(config)
    base = simulate(params, m, config.d_m, cg_height_m=cg_height, roll_lever_m=lever)
    sigma_beta = _noise(m.beta - base.beta)
    sigma_r = _noise(base.r_measured - base.r)
    return Problem(params, m, config.d_m, cg_height, lever, rows, sigma_beta, sigma_r)


def roll_lever_m(config: Config) -> float:
    """The sensor's height above the roll axis; 0 (no roll term) without a sensor height."""
    vehicle = config.vehicle
    if not vehicle.sensor_height_m:
        return 0.0
    axis = vehicle.roll_axis_height_m
    return vehicle.sensor_height_m - (DEFAULT_ROLL_AXIS_HEIGHT_M if axis is None else axis)


def score(pb: Problem, fold: np.ndarray) -> list[Scored]:
    base = pb.simulate()
    held = [pb.rows & (fold == k) for k in (0, 1)]
    cost_before = sum(pb.cost(base, rows) * rows.sum() for rows in held) / pb.rows.sum()
    rms_before = _pooled_rms(pb, [(base, rows) for rows in held])
    out = []
    for candidate in CANDIDATES:
        sims = []
        for k in (0, 1):
            values = pb.fit(candidate, pb.rows & (fold != k))
            sims.append((pb.simulate(candidate.mods(values)), held[k]))
        cost_after = sum(pb.cost(sim, rows) * rows.sum() for sim, rows in sims) / pb.rows.sum()
        values = pb.fit(candidate, pb.rows)
        out.append(
            Scored(
                candidate,
                values,
                cost_before,
                cost_after,
                rms_before,
                _pooled_rms(pb, sims),
                pb.simulate(candidate.mods(values)),
            )
        )
    return sorted(out, key=lambda s: s.cost_after)


def _pooled_rms(pb: Problem, parts: list[tuple[Simulated, np.ndarray]]) -> float:
    total = sum(pb.rms_beta_deg(sim, rows) ** 2 * rows.sum() for sim, rows in parts)
    n = sum(int(rows.sum()) for _, rows in parts)
    return math.sqrt(total / n) if n else 0.0


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
    """The sideslip residual maps (deg) of the nominal model and of the model with the effect."""

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


def diagnose(m: Measured, config: Config) -> Diagnosis:
    pb = problem(m, config)
    ids = manoeuvres(m)
    fold = folds(m, ids)
    base = pb.simulate()
    scored = score(pb, fold)
    best = scored[0]
    confounded = [
        s.candidate.effect
        for s in scored[1:]
        if best.improvement > 0 and s.improvement >= CONFOUNDED_SHARE * best.improvement
    ]
    named = best.improvement >= NONE_THRESHOLD
    diagnosis = best.candidate.effect if named else "none"
    nominal = config.tyres.c2n_per_rad
    c2n_sim = method_c2n(pb, base.beta)
    c2n_measured = method_c2n(pb, m.beta)
    c2n_after = method_c2n(pb, best.sim.beta) if named else c2n_sim
    after = best.sim if named else base
    residuals = Residuals(
        t=m.t,
        ay=np.nan_to_num(m.u_optical * m.r),
        heading_deg=np.degrees(m.heading) % 360.0,
        before=np.degrees(m.beta - base.beta),
        after=np.degrees(m.beta - after.beta),
        rows=pb.rows,
    )
    result = GapResult(
        diagnosis=diagnosis,
        confounded_with=tuple(confounded) if named else (),
        separate_by={other: separating_manoeuvre(diagnosis, other) for other in confounded} if named else {},
        located=tuple(locate(pb, base, fold)),
        candidates=tuple(
            CandidateScore(
                effect=s.candidate.effect,
                params={p.name: round(v, 5) for p, v in zip(s.candidate.params, s.params, strict=True)},
                heldout_rms_before=round(s.rms_before_deg, 5),
                heldout_rms_after=round(s.rms_after_deg, 5),
                heldout_cost_before=round(float(s.cost_before), 4),
                heldout_cost_after=round(float(s.cost_after), 4),
                improvement=round(float(s.improvement), 4),
            )
            for s in scored
        ),
        c2n=GapC2n(
            nominal=nominal,
            sim=_r(c2n_sim),
            measured=_r(c2n_measured),
            after=_r(c2n_after),
            pipeline=m.summary.c2n,
        ),
        shrink_heldout=round(1.0 - best.rms_after_deg / best.rms_before_deg, 4)
        if named and best.rms_before_deg > 0
        else 0.0,
        heldout_rms_deg=BeforeAfter(
            before=round(best.rms_before_deg, 5),
            after=round(best.rms_after_deg if named else best.rms_before_deg, 5),
        ),
        noise=GapNoise(
            sideslip_deg=round(math.degrees(pb.sigma_beta), 5),
            yaw_rate_degps=round(math.degrees(pb.sigma_r), 5),
        ),
        manoeuvres=len(np.unique(ids)),
        speed_input=m.speed_source,
    )
    return Diagnosis(result, residuals)


def _r(x: float | None) -> float | None:
    return None if x is None else round(x, 4)
