"""Every steady sample counts: C2n, d and the sideslip offset ψ0 fitted together.

In linear steady state the sideslip at the sensor is (eq. 6 with a misalignment ψ0)

    β = ψ0 + d·κ − a_y/(g·C2n)        κ = r/u, a_y = u·r

and a real tyre softens with slip, which adds a term k·a_y³ (the small-slip expansion of a
Magic-Formula curve). The fit is linear least squares on β = v/u (v measured, u and r filtered).
C2n comes from the a_y coefficient — the slope at zero lateral acceleration, as a tyre rig quotes
it — and does not depend on the tape-measured d, which the fit estimates as a check.

The softening term is kept only where the data show it — |t| > 2 and softening, not stiffening:
on near-linear tyres it would only add variance (measured: the worst error of 36 sessions rose
from 0.6 % to 1.4 %), while softening tyres read 3–4 % low without it. Sweeps at two radii let the
data tell the two apart far better than one (worst error 0.75 % instead of 1.65 % on a
Magic-Formula tyre at μ = 1).

A linear fit is only as good as the data's power to see softening. Where the steady samples span
a narrow band of a_y (one circle, all near the top of the linear range) a tyre could soften by
several per cent without the a_y³ term reaching |t| > 2; a linear interval there is confident and
wrong (Magic-Formula tyres at μ = 0.9, samples at 2.3–4 m/s²: −6 % with the truth outside). When
the softening that could hide in the data (twice the standard error of the difference between the
two models) exceeds ``UNRESOLVED_PCT`` of C2n — what real tyres soften by at the 4 m/s² gate, 3–4 %,
would then pass unseen — the interval spans both models' intervals and ``ModelChoice.resolved``
says so (one circle to 3.5 m/s² sampled at 50–100 Hz: 1.4–2.2 %).

A test pad is rarely level: a drainage slope of 1–2 % is common. Its gravity g·s·sin(D − ψ) pulls
the car sideways as the heading ψ turns, and the tyres make up the difference, so the sideslip
gains (g_y)/(g·C2n) — a term A·sin ψ + B·cos ψ. Where the steady samples cover the headings
(full circles) the two terms are tried beside the others, and the slope s = C2n·√(A² + B²) and
the direction D it falls to (atan2(B, −A) from the start heading, left positive) are reported;
on a 2 % slope, left out, they move C2n by several per cent. The slope's gravity along the heading,
g·s·cos(D − ψ), also moves load between the axles as braking does, which changes how much the rear
tyres give per m/s² of a_y: two terms a_y·sin ψ and a_y·cos ψ. All four are kept where the slope
is found (its two terms' Wald χ² beyond the 95 % point, and at least ``SLOPE_MIN_PCT``), and left
out where it is not: on a level pad they only add variance (one radius both ways, one drive in
four: the four spare terms let the a_y³ term pass for softening and C2n read 7 % high). The slope
found is also taken out of the crossings (``tilt``, for the detector). On 1–3 % slopes falling in
any direction
they took the worst C2n error of ten sessions from 2.3 % to 0.5 % and the intervals' coverage from
3 to 10 of 10 (tools/bench_accuracy.py, case e). The heading is the integrated yaw rate.

A force that follows the turn's direction but not its size (a tyre model's camber step, as in
CommonRoad's Pacejka formula; friction in the suspension) moves the sideslip by δ·sign(κ), the
same at every radius: left out, d·κ and the a_y³ term take it (CommonRoad's car: C2n 18 % high).
Where radii and speeds are apart it is tried beside the a_y³ term and kept on the BIC's evidence
(χ² > ln(blocks)) and at least ``SLOPE_MIN_PCT`` of the axle's weight (``TURN_MIN_HELD_PCT``
where d is held: a gyro's bias mimics a small one on track laps).

Quasi-steady samples (``transient``: corners of ordinary driving, where no sweep crossed zero) add
two terms: the rear's share of the yaw acceleration, k_r·ṙ, and braking's load transfer, k_x·a_y·u̇,
with a_y = u·r (u·r + v̇ with the sensor's filtered v̇, which carries the body's roll at the
sensor's height, read CommonRoad's track laps 2.9 % low, against 1.0 %: median of ten). Their
corners each hold one κ at about one speed, so d rests on how corners of different radii and speeds
differ, and unmodelled slow dynamics and a gyro's bias move it by centimetres (simulated track days:
d 1.12–1.16 m for 1.11, C2n 0.4–3.7 % low, the truth outside half the intervals). d is held there at
the tape's value, its centimetre counted (C2n 0.01–0.84 % off, every interval holding the truth).
A yaw rate that reads b high puts (r + b)/u and u·(r + b) into κ and a_y, which moves the
sideslip by b·(u/(g·C2n) − d/u): the same for left and right corners, so on a circuit that turns
mostly one way it leans on a_y (two-track track laps, 6 corners left and 2 right, a test day's
±0.02–0.08 °/s: C2n off by up to 0.7 %, in step with the bias). Where d is held and the speeds are
apart, that one term is fitted too (``YawBiasResult``), its C2n refitted until it settles: track
laps 0.50 % / 1.19 % → 0.11 % / 0.92 % (median / worst of 20), the bias found within 0.04 °/s.
It comes after the turn force's test, which it would otherwise take for its own on a circuit
turning mostly one way (CommonRoad's track laps: the turn force lost, C2n 16 % off), and a turn
force found is kept only if it passes again with the bias out (a gyro 1 °/s low passed for one).

On a small pad (most samples on radii under ``TIGHT_WHEELBASES``) every sample is far from zero
a_y, so C2n is an extrapolation, and two effects the bicycle model lacks lean on it: the axle's two
wheels, whose slip angles and loads differ by shares of κ (the sideslip gains a term κ²·a_y), and
the sweeps' own load transfer, k_x·a_y·u̇, which the short sweeps' up and down halves do not
cancel. Both are fitted there (``TIGHT_TERMS``, with d held) where the speeds are swept; at one
speed u̇ is noise and κ²·a_y nearly a_y's double, so circles at one speed keep their plain fit. On
the simulator's true states at the pipeline's steady samples each moves C2n by half a per cent
(a_y³ alone +0.15 %, with κ²·a_y −0.41 %, with a_y·u̇ +0.63 %, with both +0.11 %); with noise,
and without them, the a_y³ term did not pass (6 of 9 sessions, 1 % low) and a heading-borne
misfit passed for a slope. The two-track car's radii of 25–36 m: 0.85 % / 2.0 % → 0.16 % / 0.67 %
(median / worst of 20).

Samples at 50–250 Hz are autocorrelated, so the covariance is Newey–West (Bartlett) over short
time blocks. Only each block's sufficient statistics are kept (XᵀX, Xᵀy), so memory does not
grow with the samples; past ``max_blocks`` the oldest blocks are merged in pairs.
"""

import math
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np

from app.config import Priors
from app.results.fit_groups import (
    DResult,
    FitSamples,
    HeldOpen,
    ModelChoice,
    ModelFit,
    Psi0Result,
    SlopeResult,
    SofteningResult,
    TurnForceResult,
    YawBiasResult,
)
from app.results.marginal import (
    Blocks,
    Posterior,
    Term,
    data_alone,
    mixture,
    posterior,
    well_conditioned_inverse,
    wide_share,
)
from app.units import Z95

_TERMS = (  # the columns each block keeps; a fit takes a subset
    "psi0",  # 1: the head's yaw on the car
    "d",  # κ
    "ay",  # a_y = u·r: −1/(g·C2n)
    "ay3",  # a_y³: the tyres' softening
    "sin",  # sin ψ, cos ψ: a slope's pull at the heading ψ
    "cos",
    "ay_sin",  # a_y·sin ψ, a_y·cos ψ: its load transfer
    "ay_cos",
    "r_dot",  # ṙ: the yaw inertia's share of the rear force (quasi-steady)
    "ay_u_dot",  # a_y·u̇: braking's load transfer (quasi-steady)
    "turn",  # sign(κ): a force that follows the turn's direction
    "u",  # u and 1/u: a yaw-rate bias combines them (quasi-steady)
    "inv_u",
    "k2_ay",  # κ²·a_y: the axle's two wheels on a tight turn (small pad)
)
_K = len(_TERMS)
_GAP_S = 0.5  # a longer pause in steady samples starts a new run (no autocorrelation across it)
UNRESOLVED_PCT = 3.0  # softening that could hide in the data, % of C2n, beyond which both models count
_SLOPE_SPREAD = 0.3  # the headings' spread (of sin ψ, cos ψ beside the other terms; full circles 0.5)
# beyond which a slope's two terms are fitted
D_TAPE_SE_M = 0.01 / Z95  # the tape's d to ±1 cm at 95 % (the config's default): in C2n's interval
D_HELD_GAIN = 2.0  # d is held at the tape's value where fitting it would widen C2n's interval this much
_CM = 0.01  # metres: the tape step of DResult.per_tape_cm_pct, and of the decision below
D_HELD_REF_M = _CM  # ... beside the held interval with this much tape, whatever the config's tolerance
# (a result's value does not depend on a stated tolerance, only its interval does)
SLOPE_MIN_PCT = 0.25  # a slope under this moves C2n by less than the method's own error (a 2 %
# slope left out: 2.5 %), and is seen on level pads too (0.05–0.16 %: heading-borne misfit)
_SLOPE_WALD = -2.0 * math.log(0.05)  # χ²(2) at 95 %: a slope found, its load transfer fitted too
TURN_MIN_HELD_PCT = 1.0  # where d is held (ordinary driving) a gyro's bias, whose share of a_y and κ
# differs between left and right corners taken at different speeds, passes for a turn force: a
# test day's 0.06 °/s read 0.6 % on track laps (C2n −3.4 %); CommonRoad's camber step is 2–3 %
_WIDE_SPEEDS = 1.2  # the fastest sample this many times the slowest: speeds apart, not one speed
_BIAS_ITERATIONS = 5  # refits of a yaw-rate bias's term, its C2n from the fit before (3 settle it to 1e-6)
TIGHT_WHEELBASES = 20.0  # most samples on radii under this many wheelbases: d is held at the tape's
# (the bicycle model's one-wheel axle misreads the two wheels of a tight turn by a share that d·κ
# takes: two-track radii of 25–36 m, d fitted 6–10 mm long, C2n 1–2.3 % low; held, within 1 %)
TIGHT_TERMS = (
    Term.AY_U_DOT,
    Term.K2_AY,
)  # on a small pad: the sweeps' load transfer a_y·u̇ and the two wheels' κ²·a_y
_TERM_LEFT = 0.01  # a term tried only where the others leave this share of it (u̇ never passed: 0)
_TURN_SPREAD = 0.02  # of sign(κ) beside the other terms beyond which it is tried: one radius each way
# leaves 0; a small pad, every sample at a_y ≥ 1.2 m/s², 0.024 (at 0.05 it was not tried there, and
# CommonRoad's car read 8–21 % high, the truth outside every interval)


@dataclass(frozen=True)
class RegressionFit:
    """C2n with its interval, and the rest of the fit in groups (app/results/fit_groups.py): one
    per effect, None where the fit has no such effect to report."""

    c2n: float
    c2n_se: float
    c2n_ci95: tuple[float, float]
    samples: FitSamples
    d: DResult
    psi0: Psi0Result | None  # None when the data cannot tell ψ0 from d (one direction, one radius)
    models: ModelChoice
    softening: SofteningResult | None = None  # where the a_y³ term is kept
    slope: SlopeResult | None = None  # where the headings let it be fitted
    turn_force: TurnForceResult | None = None  # where one was found
    yaw_bias: YawBiasResult | None = None  # where it was fitted
    held_open: HeldOpen | None = None  # the marginal fit's
    scale_se: float = 0.0  # C2n's relative error from the sensors' scales, in its intervals
    c2n_data_ci95: tuple[float, float] | None = None  # without the sensors' scales (None: c2n_ci95)
    estimator: Literal["cascade", "marginal"] = "cascade"  # terms chosen by tests, or all with priors


class SampleRegression:
    def __init__(
        self,
        g: float,
        block_s: float = 0.25,
        max_blocks: int = 32768,
        softening_t: float = 2.0,
        min_samples: int = 200,
        d_tape_m: float | None = None,
        d_tape_se_m: float = D_TAPE_SE_M,
        transient: bool = False,
        scale_se: float = 0.0,
        wheelbase_m: float | None = None,
        priors: Priors | None = None,
    ) -> None:
        self.g = g
        self.priors = priors  # None: the cascade of tests; else one model, every term with its prior
        self.wheelbase_m = wheelbase_m or 2.7
        # where most samples turn tighter than TIGHT_WHEELBASES of these, d is held at the tape's
        self._tight_curvature = 1.0 / (TIGHT_WHEELBASES * wheelbase_m) if wheelbase_m else math.inf
        self._tight_n = 0
        self.scale_se = scale_se  # C2n's relative error from the sensors' scales (Calibration.fit_se)
        self.transient = transient  # quasi-steady samples: try the yaw inertia's and load transfer's terms
        self.d_tape_m = d_tape_m  # the sensor's d as measured with a tape: held where the data cannot fit it
        self.d_tape_se_m = d_tape_se_m  # ... and its standard error, counted in C2n's interval then
        self.block_s = block_s
        self.max_blocks = max_blocks
        self.softening_t = softening_t
        self.min_samples = min_samples
        capacity = 256
        self._xtx = np.zeros((capacity, _K, _K))
        self._xty = np.zeros((capacity, _K))
        self._yty = np.zeros(capacity)
        self._run = np.zeros(capacity, dtype=np.int64)
        self._log = np.zeros(capacity, dtype=np.int64)
        self._n = np.zeros(capacity, dtype=np.int64)
        self._blocks = 0
        self._open: list[tuple[float, ...]] = []  # (κ, a_y, β, ψ, ṙ, u̇, u) of the open block
        self._block_start = -math.inf
        self._t_last = -math.inf
        self._run_id = 0
        self._log_id = 0
        self._seconds = 0.0
        self._ay_min = math.inf
        self._ay_max = -math.inf
        self._kappa_min = math.inf
        self._kappa_max = -math.inf
        self._u_min = math.inf
        self._u_max = -math.inf

    @property
    def n_samples(self) -> int:
        return int(self._n[: self._blocks].sum()) + len(self._open)

    def new_log(self) -> None:
        """The samples from here on are from another drive of the same car: its own ψ0 (the head
        mounted again), its own headings, no autocorrelation with the drive before."""
        if self.n_samples:
            self._close_block()
            self._run_id += 1
            self._log_id += 1
        self._t_last = -math.inf

    def add(
        self,
        t: float,
        u: float,
        r: float,
        v_meas: float,
        heading: float = 0.0,
        r_dot: float = 0.0,
        u_dot: float = 0.0,
    ) -> None:
        """One steady sample: filtered speed and yaw rate, measured lateral velocity at the sensor,
        and the heading (the yaw rate integrated since the start). Quasi-steady samples give the
        filtered ṙ and u̇ too."""
        step = t - self._t_last
        if not 0.0 <= step <= _GAP_S:
            self._close_block()
            self._run_id += 1
        else:
            self._seconds += step
            if t - self._block_start >= self.block_s:
                self._close_block()
        if not self._open:
            self._block_start = t
        self._t_last = t
        ay = u * r
        kappa = r / u
        self._ay_min, self._ay_max = min(self._ay_min, abs(ay)), max(self._ay_max, abs(ay))
        self._kappa_min, self._kappa_max = min(self._kappa_min, abs(kappa)), max(self._kappa_max, abs(kappa))
        self._u_min, self._u_max = min(self._u_min, u), max(self._u_max, u)
        self._tight_n += abs(kappa) > self._tight_curvature
        self._open.append((kappa, ay, v_meas / u, heading, r_dot, u_dot, u))

    def _open_stats(self) -> tuple[np.ndarray, np.ndarray, float]:
        kappa, ay, beta, heading, r_dot, u_dot, u = np.array(self._open).T
        sin, cos = np.sin(heading), np.cos(heading)
        columns = [np.ones_like(ay), kappa, ay, ay**3, sin, cos, ay * sin, ay * cos]
        columns += [r_dot, ay * u_dot, np.sign(kappa), u, 1.0 / u, kappa * kappa * ay]
        x = np.column_stack(columns)
        return x.T @ x, x.T @ beta, float(beta @ beta)

    def _close_block(self) -> None:
        if not self._open:
            return
        xtx, xty, yty = self._open_stats()
        if self._blocks >= self.max_blocks:
            self._merge_pairs()
        if self._blocks == len(self._n):
            self._grow()
        i = self._blocks
        self._xtx[i] = xtx
        self._xty[i] = xty
        self._yty[i] = yty
        self._run[i] = self._run_id
        self._log[i] = self._log_id
        self._n[i] = len(self._open)
        self._blocks += 1
        self._open = []

    def _grow(self) -> None:
        size = 2 * len(self._n)
        self._xtx = np.resize(self._xtx, (size, _K, _K))
        self._xty = np.resize(self._xty, (size, _K))
        self._yty = np.resize(self._yty, size)
        self._run = np.resize(self._run, size)
        self._log = np.resize(self._log, size)
        self._n = np.resize(self._n, size)

    def _merge_pairs(self) -> None:
        """Halve the resolution of the history: block statistics add, so nothing is lost but
        the finest autocorrelation detail."""
        half = self._blocks // 2
        for array in (self._xtx, self._xty, self._yty, self._n):
            array[:half] = array[0 : 2 * half : 2] + array[1 : 2 * half : 2]
        self._run[:half] = self._run[0 : 2 * half : 2]
        self._log[:half] = self._log[0 : 2 * half : 2]
        if self._blocks % 2:
            for array in (self._xtx, self._xty, self._yty, self._n, self._run, self._log):
                array[half] = array[self._blocks - 1]
        self._blocks = half + self._blocks % 2

    def _held_se(
        self, held: "_Solution", xtx: np.ndarray, xty: np.ndarray, run: np.ndarray, n: int, tape_se_m: float
    ) -> float:
        """C2n's standard error with d held at the tape's value, the tape's own error counted."""
        return math.hypot(_c2n_se(held, self.g), self._tape_shift(held, xtx, xty, run, n, tape_se_m))

    def _tape_shift(
        self, held: "_Solution", xtx: np.ndarray, xty: np.ndarray, run: np.ndarray, n: int, step_m: float
    ) -> float:
        """How far C2n moves when the held d is ``step_m`` longer: the fit again."""
        if step_m == 0.0:
            return 0.0
        longer = _solve(xtx, xty - step_m * xtx[:, :, Term.D], run, held.terms, n)
        if longer is None:
            return 0.0
        i = held.terms.index(Term.AY)
        return abs(1.0 / (self.g * float(held.coef[i])) - 1.0 / (self.g * float(longer.coef[i])))

    def _turn_found(self, fit: "_Solution | None", blocks: int, held: bool) -> bool:
        """A turn force kept on the BIC's evidence, χ² > ln(blocks) (at 95 % one Magic-Formula drive
        in 20 to 7 m/s² took a 0.28 % force for one, C2n +1.5 %), and large enough to be one."""
        return (
            fit is not None
            and _wald(fit, [Term.TURN]) > math.log(blocks)
            and 100.0 * abs(_turn(fit, self.g)) >= (TURN_MIN_HELD_PCT if held else SLOPE_MIN_PCT)
        )

    def _fit_marginal(
        self,
        priors: Priors,
        xtx: np.ndarray,
        xty: np.ndarray,
        yty: np.ndarray,
        run: np.ndarray,
        log: np.ndarray,
    ) -> RegressionFit | None:
        """One model, every nuisance with its prior (``marginal.py``); C2n's interval carries what
        the drive cannot tell apart, and names the term that holds it open most. d's prior: the
        tape's, and with ``d_gross_share`` a wide one (the tape wrong), each weighed by its evidence
        (``wide_share``); without a tape, a flat one."""
        made = self._marginal_design(priors, xtx, xty, yty, run, log)
        if made is None:
            return None
        design, b_ay, covered = made
        blocks, logs = len(run), len(np.unique(log))
        if self.d_tape_m is None:
            found = self._marginal_posterior(priors, design, b_ay, math.inf)
            return (
                None
                if found is None
                else self._marginal_result(priors, [found], [1.0], blocks, logs, covered)
            )
        tape_sd = max(self.d_tape_se_m, D_EXACT_SD_M)
        wide_sd = priors.d_gross_wheelbases * self.wheelbase_m
        tape = self._marginal_posterior(priors, design, b_ay, tape_sd)
        wide = self._marginal_posterior(  # from the tape's a_y, noise and pull
            priors,
            design,
            b_ay if tape is None else tape[0].value(Term.AY),
            wide_sd,
            None if tape is None else tape[0],
        )
        if tape is None or wide is None:
            found = tape or wide
            return (
                None
                if found is None
                else self._marginal_result(priors, [found], [1.0], blocks, logs, covered)
            )
        # the wide prior's weight by the evidence where the speeds are apart; at one speed d and C2n
        # move together, and what places d there is the other terms' priors (a_y³'s curvature), not
        # the drive: the weight stays the prior's (a flipped sideslip at one speed put it at 1.0,
        # d 0.76 m behind the axle)
        apart = self._u_max >= _WIDE_SPEEDS * self._u_min
        share = (
            wide_share(wide[0], self.d_tape_m, tape_sd, wide_sd, priors.d_gross_share)
            if apart
            else priors.d_gross_share
        )
        fit = self._marginal_result(priors, [tape, wide], [1.0 - share, share], blocks, logs, covered)
        return None if fit is None else self._with_own_d(fit, wide[0], wide_sd, apart, priors.confidence)

    def _marginal_design(
        self,
        priors: Priors,
        xtx: np.ndarray,
        xty: np.ndarray,
        yty: np.ndarray,
        run: np.ndarray,
        log: np.ndarray,
    ) -> tuple["_Design", float, frozenset[Term]] | None:
        """The marginal fit's terms (each drive its own ψ0 and gyro's bias), a_y's coefficient to
        scale the priors from (a least-squares start), and the terms the drive's layout covers."""
        n, logs = self.n_samples, len(np.unique(log))
        offsets: list[int] = [Term.PSI0]
        speeds: list[tuple[int, int]] = [(Term.U, Term.INV_U)]
        if logs > 1:
            xtx, xty, offsets, speeds = _per_log(xtx, xty, log)
        total, rhs = xtx.sum(axis=0), xty.sum(axis=0)
        b_ay = _least_squares_ay(total, rhs, [*offsets, Term.D, Term.AY])
        if b_ay is None and self.d_tape_m is not None:  # one speed: d at the tape's to start
            b_ay = _least_squares_ay(total, rhs - self.d_tape_m * total[:, Term.D], [*offsets, Term.AY])
        if b_ay is None:
            return None
        # a pad's slope: a plane, whose pull turns with the heading, where the samples are taken on
        # one place (steady circles); a route's corners (quasi-steady samples) are each their own
        # place, whose cross-fall no heading gives; and the headings are each drive's own
        planar = logs == 1 and not self.transient
        slope_terms = [Term.SIN, Term.COS, Term.AY_SIN, Term.AY_COS] if planar else []
        turn = [Term.TURN] if priors.turn_force_pct > 0 else []
        own = [Term.D, Term.AY, Term.AY3, *slope_terms, Term.R_DOT, Term.AY_U_DOT, *turn, Term.K2_AY]
        design = _Design(Blocks(xtx, xty, yty, run, n), offsets, speeds, [int(t) for t in own])
        # a slope is reported (and its pull taken out of the crossings) where the headings cover it,
        # as the cascade tries one: one direction on one circle holds a 2 % "slope" at Wald's 95 %
        # that C2n's width carries but no crossing should be moved by; a turn force likewise where
        # the turns' directions and sizes cover it (CommonRoad's sweeps: the early fits, one turn
        # direction so far, handed the paired crossings a step that read them 39–55 % low)
        base = [*offsets, Term.D, Term.AY]
        covered = frozenset(
            term
            for term, layout, least in (
                (Term.SIN, [Term.SIN, Term.COS], _SLOPE_SPREAD),
                (Term.TURN, [Term.TURN], _TURN_SPREAD),
            )
            if term in own and _spread(design.blocks.total, base, [int(t) for t in layout], n) >= least
        )
        return design, b_ay, covered

    def _with_own_d(
        self, fit: RegressionFit, wide: Posterior, wide_sd: float, apart: bool, confidence: float
    ) -> RegressionFit:
        """The fit with what the drive alone says of d (the wide prior's posterior less that prior):
        its information over the tape's, and — where the speeds are apart, as the cascade's — the
        top of its interval (a d behind the axle shows a role the wrong way round:
        ``Snapshot.sign_problem``). At one speed the a_y³ term's curvature lends d a little
        information that the prior's shape, not the drive, makes."""
        assert self.d_tape_m is not None
        alone = data_alone(wide, Term.D, self.d_tape_m, wide_sd)
        if alone is None:
            return replace(fit, d=replace(fit.d, information=0.0))
        tape_sd = max(self.d_tape_se_m, D_EXACT_SD_M)
        information = tape_sd**2 / alone[1] if alone[1] > 0 else math.inf
        if not apart:
            return replace(fit, d=replace(fit.d, information=information))
        from scipy.special import stdtrit

        q = float(stdtrit(max(fit.samples.blocks - len(wide.terms), 1), 0.5 + confidence / 2.0))
        free_m = alone[0] + q * math.sqrt(alone[1])
        return replace(fit, d=replace(fit.d, information=information, free_m=free_m))

    def _marginal_posterior(
        self, priors: Priors, design: "_Design", b_ay: float, d_sd: float, start: Posterior | None = None
    ) -> tuple[Posterior, list[int]] | None:
        """The posterior with d's prior N(tape, d_sd²) (flat without a tape), and the yaw-rate
        bias's columns; the priors' scale follows a_y's coefficient until it settles, each pass
        from the noise and the pull the one before found (the first from ``start``'s, a fit under
        the other prior on d)."""
        post: Posterior | None = start
        bias_terms: list[int] = []
        pull = None if start is None else _Pull.of(start)
        own_terms = [*design.offsets, *design.own]
        own_weights = design.blocks.columns(own_terms)
        k = len(own_weights)
        for _ in range(_PASSES):  # the priors follow a_y's coefficient and the slope's pull
            prior = _priors(priors, self.g, b_ay, self.wheelbase_m, pull)
            terms, weights = own_terms, own_weights
            if self.d_tape_m is not None:  # a yaw-rate bias b moves β by b·(k·u − d/u), k = −b_ay
                combos = [{u: -b_ay, inv_u: -self.d_tape_m} for u, inv_u in design.speeds]
                bias_terms = list(range(k, k + len(combos)))
                terms = [*own_terms, *bias_terms]
                weights = np.hstack([own_weights, _combination_weights(k, combos)])
            mean, spread = np.array(
                [
                    prior[Term.PSI0]
                    if t in design.offsets
                    else (0.0, math.radians(priors.gyro_bias_degps))
                    if t in bias_terms
                    else (self.d_tape_m or 0.0, d_sd)
                    if t == Term.D
                    else prior[t]
                    for t in terms
                ]
            ).T
            sigma2 = None if post is None else post.sigma2
            post = posterior(design.blocks, weights, [int(t) for t in terms], mean, spread, sigma2)
            if post is None:
                return None
            # settled: the priors' scale was a_y's coefficient's own, and the load transfer's
            # prior the pull's this pass found
            settled = abs(post.value(Term.AY) - b_ay) <= _SETTLED * abs(b_ay)
            settled = settled and (pull is not None or Term.SIN not in post.terms)
            b_ay, pull = post.value(Term.AY), _Pull.of(post)
            if settled:
                break
        assert post is not None
        return post, bias_terms

    def _marginal_result(
        self,
        priors: Priors,
        found: list[tuple[Posterior, list[int]]],
        weights: list[float],
        blocks: int,
        logs: int,
        covered: frozenset[Term],
    ) -> RegressionFit | None:
        """The result of d's priors' mixture: C2n and d from both posteriors by their weights, the
        rest (terms reported, ``HeldOpen``) from the heavier one; a slope and a turn force
        reported only where the drive's layout covers them (``covered``: headings, turns' directions)."""
        # a_y's coefficient above zero is kept, C2n below zero: a role the wrong way round, which
        # Snapshot.sign_problem explains from d and the signs (the cascade's fits do the same)
        kept = [(f, w) for f, w in zip(found, weights, strict=True) if f[0].value(Term.AY) != 0]
        if not kept:
            return None
        post, bias_terms = max(kept, key=lambda fw: fw[1])[0]
        from scipy.special import stdtrit

        dof = max(blocks - len(post.terms), 1)
        q = float(stdtrit(dof, 0.5 + priors.confidence / 2.0))
        shares = [w for _, w in kept]
        c2ns = [-1.0 / (self.g * f[0].value(Term.AY)) for f, _ in kept]
        data_ses = [f[0].se(Term.AY) * self.g * c * c for (f, _), c in zip(kept, c2ns, strict=True)]
        c2n_ses = [math.hypot(se, self.scale_se * abs(c)) for se, c in zip(data_ses, c2ns, strict=True)]
        c2n, c2n_ci = mixture(c2ns, c2n_ses, shares, dof, priors.confidence)
        data_ci = c2n_ci
        if self.scale_se:  # the sensors' scales widen the interval; the value is the data's mixture's,
            # which a stated tolerance does not move (its median would: the widths weigh it)
            c2n, data_ci = mixture(c2ns, data_ses, shares, dof, priors.confidence)
        c2n_se = (c2n_ci[1] - c2n_ci[0]) / (2.0 * q)
        d_m, d_ci = mixture(
            [f[0].value(Term.D) for f, _ in kept],
            [f[0].se(Term.D) for f, _ in kept],
            shares,
            dof,
            priors.confidence,
        )
        b_ay = post.value(Term.AY)
        fit = _Solution(post.terms, post.coef, post.cov)

        def ci(term: int) -> tuple[float, float]:
            return (post.value(term) - q * post.se(term), post.value(term) + q * post.se(term))

        t3 = post.value(Term.AY3) / post.se(Term.AY3) if post.se(Term.AY3) > 0 else 0.0
        softens = abs(t3) > q and post.value(Term.AY3) * b_ay > 0  # reported where the data show it
        slope = _slope(fit, c2n, q) if Term.SIN in post.terms else None
        slope_shown = (
            slope is not None and Term.SIN in covered and _wald(fit, [Term.SIN, Term.COS]) > _SLOPE_WALD
        )
        turn = Term.TURN in post.terms and Term.TURN in covered
        bias = _bias(fit, bias_terms[0], q) if bias_terms else None
        held = post.held_open_by(Term.AY)
        return RegressionFit(
            c2n=c2n,
            c2n_se=c2n_se,
            c2n_ci95=c2n_ci,
            samples=FitSamples(
                count=self.n_samples,
                blocks=blocks,
                ay_range_mps2=(self._ay_min, self._ay_max),
                curvature_range_per_m=(self._kappa_min, self._kappa_max),
                speed_range_mps=(self._u_min, self._u_max),
                duration_s=self._seconds,
                logs=logs,
                transient_terms=True,
            ),
            d=DResult(m=d_m, ci95_m=d_ci),
            psi0=Psi0Result(post.value(Term.PSI0), ci(Term.PSI0)),
            models=ModelChoice(
                chosen="softening" if softens else "linear",
                softening_t=t3,
                linear=ModelFit(c2n, c2n_ci, data_ci),
                softening=ModelFit(c2n, c2n_ci, data_ci),
            ),
            softening=SofteningResult(
                per_mps2_2=-post.value(Term.AY3) * self.g * c2n,
                se_per_mps2_2=post.se(Term.AY3) * self.g * abs(c2n),
            )
            if softens
            else None,
            slope=SlopeResult(slope[0], slope[1], slope[2], _tilt(fit)) if slope and slope_shown else None,
            turn_force=TurnForceResult(
                pct=100.0 * _turn(fit, self.g),
                ci95_pct=_turn_ci(fit, self.g, q),
                step_rad=post.value(Term.TURN),
                step_se_rad=post.se(Term.TURN),
            )
            if turn
            else None,
            yaw_bias=YawBiasResult(bias[0], bias[1]) if bias else None,
            held_open=HeldOpen(_NAMES.get(held[0], "psi0" if held[0] >= _K else None), held[1])
            if held
            else None,
            scale_se=self.scale_se,
            c2n_data_ci95=data_ci,
            estimator="marginal",
        )

    def fit(self) -> RegressionFit | None:
        """The fit over every sample so far, or None while the data cannot support one: one model
        with every nuisance's prior (``priors``: ``_fit_marginal``), else the cascade of tests — the
        terms the drive shows (``_cascade``), d held where the tape places it better
        (``_hold_d``), a force that follows the turn (``_with_turn_force``), a yaw-rate bias
        (``_with_yaw_bias``), and the tyres' softening (``_cascade_result``)."""
        statistics = self._statistics()
        if statistics is None:
            return None
        if self.priors is not None:
            return self._fit_marginal(self.priors, *statistics)
        cascade = self._cascade(*statistics)
        self._hold_d(cascade)
        self._with_turn_force(cascade)
        self._with_yaw_bias(cascade)
        return self._cascade_result(cascade)

    def _statistics(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """The blocks' statistics (XᵀX, Xᵀy, yᵀy, run, drive), the open block's among them, in the
        slot closing it will fill (written again then); None while there are too few samples, blocks
        or a_y's range for a fit."""
        b = self._blocks
        if self._open:
            if b == len(self._n):
                self._grow()
            self._xtx[b], self._xty[b], self._yty[b] = self._open_stats()
            self._run[b], self._log[b] = self._run_id, self._log_id
            b += 1
        if self.n_samples < self.min_samples or b < 10 or self._ay_max - self._ay_min < 0.5:
            return None
        return self._xtx[:b], self._xty[:b], self._yty[:b], self._run[:b], self._log[:b]

    def _cascade(
        self, xtx: np.ndarray, xty: np.ndarray, _yty: np.ndarray, run: np.ndarray, log: np.ndarray
    ) -> "_Cascade":
        """The cascade's first terms: ψ0 where the curvature varies within the drives (else it is
        d·κ's double), d and a_y; a small pad's two terms where its sweeps show them; a slope's
        four where the headings and the Wald test find one; the quasi-steady samples' two."""
        n, b = self.n_samples, len(run)
        drives = np.unique(log)
        spread_k = sum(_within(xtx[log == k]) for k in drives) if len(drives) > 1 else _within(xtx)
        psi0_free = spread_k >= 0.04 * xtx[:, Term.D, Term.D].sum() > 0
        logs = len(drives)
        offsets: list[int] = [Term.PSI0]
        speeds: list[tuple[int, int]] = [(Term.U, Term.INV_U)]
        if logs > 1:  # each drive its own ψ0 (and speed columns: its own gyro's bias)
            xtx, xty, offsets, speeds = _per_log(xtx, xty, log)
        total = xtx.sum(axis=0)
        base: list[int] = [*offsets, Term.D, Term.AY] if psi0_free else [Term.D, Term.AY]
        tight = 2 * self._tight_n > n
        wide = self._u_max >= _WIDE_SPEEDS * self._u_min
        if tight and wide and self.d_tape_m is not None:  # a small pad's sweeps: d held (below) and
            pad = [t for t in TIGHT_TERMS if _left(total, base, t) >= _TERM_LEFT]  # these two fitted,
            if _solve(xtx, xty, run, [*base, *pad], n) is not None:  # where they leave a fit
                base += pad
        tilted = None  # the fit with a slope's pull, where the headings let one be fitted
        if logs == 1 and psi0_free and _spread(total, base, [Term.SIN, Term.COS], n) >= _SLOPE_SPREAD:
            tilted = _solve(xtx, xty, run, [*base, Term.SIN, Term.COS], n)
            if (
                tilted is not None
                and _wald(tilted, [Term.SIN, Term.COS]) > _SLOPE_WALD
                and _tilt_pct(tilted, self.g) >= SLOPE_MIN_PCT
            ):  # a slope found: its pull, and its gravity along the heading
                base += [Term.SIN, Term.COS, Term.AY_SIN, Term.AY_COS]
        # the yaw inertia's share of the rear force, and the speed's load transfer: in ordinary
        # driving always there (left out where they are not significant: C2n 1.4 % low on three
        # simulated track laps, the truth outside the interval)
        quasi_terms = [t for t in (Term.R_DOT, Term.AY_U_DOT) if t not in base]
        transient = self.transient and _solve(xtx, xty, run, [*base, *quasi_terms], n) is not None
        if transient:
            base += quasi_terms
        linear = _solve(xtx, xty, run, base, n)
        return _Cascade(
            xtx, xty, run, n, b, logs, speeds, psi0_free, tight, wide, total, base, linear, tilted, transient
        )

    def _hold_d(self, c: "_Cascade") -> None:
        """d at the tape's value (β − d·κ on the other terms) where the design is too narrow to
        place it beside C2n (one speed), on a small pad, and in ordinary driving."""
        if self.d_tape_m is None:
            return
        held_xty = c.xty - self.d_tape_m * c.xtx[:, :, Term.D]
        held_base = [t for t in c.base if t != Term.D]
        held = _solve(c.xtx, held_xty, c.run, held_base, c.n)
        if held is None:
            return
        c.narrow = c.linear is None or _c2n_se(c.linear, self.g) > D_HELD_GAIN * self._held_se(
            held, c.xtx, held_xty, c.run, c.n, D_HELD_REF_M
        )
        if c.narrow or c.tight or self.transient:  # transient: ordinary driving, where the tape's
            c.d_fixed, c.xty, c.base, c.linear = True, held_xty, held_base, held  # d is better

    def _with_turn_force(self, c: "_Cascade") -> None:
        """A force that follows the turn's direction, not its size. It needs radii and speeds
        apart: at one speed it takes a_y's slope and the a_y³ term's curvature (circles at one speed
        ±1 %: worst C2n 0.7 → 4.3 %). Tried beside the a_y³ term: a softening tyre's curvature,
        left to a straight line, leans on sign(κ) as well."""
        if (
            c.psi0_free
            and c.wide
            and not c.narrow
            and _spread(c.total, c.base, [Term.TURN], c.n) >= _TURN_SPREAD
            and self._turn_found(
                _solve(c.xtx, c.xty, c.run, [*c.base, Term.AY3, Term.TURN], c.n), c.blocks, c.d_fixed
            )
        ):
            c.base += [Term.TURN]
            c.linear = _solve(c.xtx, c.xty, c.run, c.base, c.n)

    def _with_yaw_bias(self, c: "_Cascade") -> None:
        """A yaw-rate bias's term, on quasi-steady samples with d held and the speeds apart; a turn
        force found is kept only if it passes again with the bias out."""
        c.plain = (c.xtx, c.free_xty, list(c.base))
        if not (
            c.transient
            and c.d_fixed
            and c.wide
            and c.psi0_free
            and c.linear is not None
            and self.d_tape_m is not None
        ):
            return
        yaw_bias = _yaw_bias(c.xtx, c.xty, c.run, c.base, c.n, self.d_tape_m, c.linear, c.speeds)
        if yaw_bias is not None and Term.TURN in c.base:  # the turn force still there with the bias out?
            turned = _solve(yaw_bias.xtx, yaw_bias.xty, c.run, [*c.base, *yaw_bias.terms, Term.AY3], c.n)
            if not self._turn_found(turned, c.blocks, c.d_fixed):  # a gyro's −1 °/s: 0.05 % [−0.09, 0.20]
                c.base = [t for t in c.base if t != Term.TURN]
                yaw_bias = _yaw_bias(c.xtx, c.xty, c.run, c.base, c.n, self.d_tape_m, c.linear, c.speeds)
        if yaw_bias is not None:
            c.xtx, c.xty, c.linear = yaw_bias.xtx, yaw_bias.xty, yaw_bias.fit
            c.base = [*c.base, *yaw_bias.terms]
        c.yaw_bias = yaw_bias

    def _cascade_result(self, c: "_Cascade") -> RegressionFit | None:
        """The cascade's last test, the tyres' softening: the a_y³ term kept where it softens at
        |t| > ``softening_t``; where the data could hide more softening than ``UNRESOLVED_PCT``,
        C2n's interval spans both models'. Then the result, with every term the cascade kept."""
        cubic = _solve(c.xtx, c.xty, c.run, [*c.base, Term.AY3], c.n)
        if cubic is None or c.linear is None:
            return None
        t3 = cubic.coef[-1] / math.sqrt(cubic.cov[-1, -1]) if cubic.cov[-1, -1] > 0 else 0.0
        # softening s = b3/b_ay must be positive: a tyre loses stiffness with slip, never gains it
        softens = cubic.coef[-1] * cubic.coef[cubic.terms.index(Term.AY)] > 0
        chosen = cubic if softens and abs(t3) > self.softening_t else c.linear
        terms = chosen.terms
        from scipy.special import stdtrit  # the t quantile; imported at the first fit, not at the start

        q = float(stdtrit(max(c.blocks - len(terms), 1), 0.975))

        def ci(value: float, se: float) -> tuple[float, float]:
            return (value - q * se, value + q * se)

        def model_se(model: _Solution, scales: bool = True) -> float:
            """C2n's error: the data's (with the tape's where d is held) and, with ``scales``, the
            sensors' scales', which no drive can show."""
            if c.d_fixed:
                data = self._held_se(model, c.xtx, c.xty, c.run, c.n, self.d_tape_se_m)
            else:
                data = _c2n_se(model, self.g)
            if not scales:
                return data
            scale = self.scale_se / (self.g * abs(float(model.coef[model.terms.index(Term.AY)])))
            return math.hypot(data, scale)

        def model_ci(model: _Solution, scales: bool = True) -> tuple[float, float] | None:
            slope = model.coef[model.terms.index(Term.AY)]
            if slope >= 0:  # no stiffness
                return None
            half = float(stdtrit(max(c.blocks - len(model.terms), 1), 0.975)) * model_se(model, scales)
            return (-1.0 / (self.g * slope) - half, -1.0 / (self.g * slope) + half)

        slope = chosen.coef[terms.index(Term.AY)]
        c2n = -1.0 / (self.g * slope)
        c2n_se = model_se(chosen)
        c2n_ci95 = ci(c2n, c2n_se)
        data_ci95 = ci(c2n, model_se(chosen, scales=False))
        c2n_linear = -1.0 / (self.g * c.linear.coef[c.linear.terms.index(Term.AY)])
        c2n_cubic = -1.0 / (self.g * cubic.coef[cubic.terms.index(Term.AY)])
        # the two models differ by the a_y³ term alone, so their difference has the term's t
        hidden = float(200.0 * abs((c2n_cubic - c2n_linear) / t3 / c2n)) if t3 else math.inf
        resolved = bool(chosen is cubic or hidden <= UNRESOLVED_PCT)
        if not resolved:
            i_cubic = cubic.terms.index(Term.AY)
            slope3 = cubic.coef[i_cubic]
            cubic_se = math.sqrt(cubic.cov[i_cubic, i_cubic]) / (self.g * slope3 * slope3)
            low, high = ci(c2n_cubic, cubic_se) if slope3 < 0 else (c2n_ci95[0], math.inf)
            c2n_ci95 = (min(c2n_ci95[0], low), max(c2n_ci95[1], high))
            data_ci95 = (min(data_ci95[0], low), max(data_ci95[1], high))
            c2n_se = max(c2n_se, cubic_se)
        if c.d_fixed and self.d_tape_m is not None:
            d, d_se = self.d_tape_m, 0.0
        else:
            i_d = terms.index(Term.D)
            d, d_se = chosen.coef[i_d], math.sqrt(chosen.cov[i_d, i_d])
        psi0 = psi0_se = None
        if c.psi0_free:
            i_psi0 = terms.index(Term.PSI0)
            psi0, psi0_se = chosen.coef[i_psi0], math.sqrt(chosen.cov[i_psi0, i_psi0])
        slope = _slope(chosen if Term.SIN in terms else c.tilted, c2n, q) if c.tilted is not None else None
        bias = _bias(chosen, c.yaw_bias.terms[0], q) if c.yaw_bias is not None else None
        softening = softening_se = None
        if chosen is cubic:
            softening = -cubic.coef[-1] * self.g * c2n  # α2 = a_y/(g·C2n)·(1 + s·a_y²)
            softening_se = _se(cubic, cubic.terms[-1]) * self.g * abs(c2n)
        return RegressionFit(
            c2n=c2n,
            c2n_se=c2n_se,
            c2n_ci95=c2n_ci95,
            samples=FitSamples(
                count=c.n,
                blocks=c.blocks,
                ay_range_mps2=(self._ay_min, self._ay_max),
                curvature_range_per_m=(self._kappa_min, self._kappa_max),
                speed_range_mps=(self._u_min, self._u_max),
                duration_s=self._seconds,
                logs=c.logs,
                transient_terms=c.transient,
                tight_terms=tuple(_TERMS[t] for t in TIGHT_TERMS if t in terms),
            ),
            d=DResult(
                m=d,
                ci95_m=ci(d, d_se),
                held=c.d_fixed,
                held_tight=c.d_fixed and c.tight and not c.narrow,
                per_tape_cm_pct=100.0 * self._tape_shift(chosen, c.xtx, c.xty, c.run, c.n, _CM) / c2n
                if c.d_fixed
                else None,
                free_m=_plain_d(*c.plain, c.run, c.n, q) if c.d_fixed and c.wide else None,
            ),
            psi0=Psi0Result(psi0, ci(psi0, psi0_se)) if psi0 is not None and psi0_se is not None else None,
            models=ModelChoice(
                chosen="softening" if chosen is cubic else "linear",
                softening_t=t3,
                linear=ModelFit(c2n_linear, model_ci(c.linear), model_ci(c.linear, scales=False)),
                softening=ModelFit(c2n_cubic, model_ci(cubic), model_ci(cubic, scales=False)),
                resolved=resolved,
                hidden_pct=hidden,
            ),
            softening=SofteningResult(softening, softening_se)
            if softening is not None and softening_se is not None
            else None,
            slope=SlopeResult(slope[0], slope[1], slope[2], _tilt(chosen)) if slope else None,
            turn_force=TurnForceResult(
                pct=100.0 * _turn(chosen, self.g),
                ci95_pct=_turn_ci(chosen, self.g, q),
                step_rad=float(chosen.coef[terms.index(Term.TURN)]),
                step_se_rad=_se(chosen, Term.TURN),
            )
            if Term.TURN in terms
            else None,
            yaw_bias=YawBiasResult(bias[0], bias[1]) if bias else None,
            scale_se=self.scale_se,
            c2n_data_ci95=data_ci95,
        )


@dataclass
class _Cascade:
    """The cascade's working state as its tests go (``SampleRegression.fit``): the statistics
    (with d held, the tape's d·κ taken out of y; with a yaw-rate bias, its columns added), the terms
    kept so far and the linear fit on them."""

    xtx: np.ndarray
    xty: np.ndarray
    run: np.ndarray
    n: int  # samples
    blocks: int
    logs: int  # drives pooled
    speeds: list[tuple[int, int]]  # each drive's u and 1/u columns (a yaw-rate bias combines them)
    psi0_free: bool
    tight: bool  # most samples on radii under TIGHT_WHEELBASES
    wide: bool  # the speeds apart (_WIDE_SPEEDS)
    total: np.ndarray  # XᵀX over every block
    base: list[int]  # the terms kept
    linear: "_Solution | None"  # the fit on them
    tilted: "_Solution | None"  # the fit with a slope's pull, where the headings let one be tried
    transient: bool  # the quasi-steady terms kept
    free_xty: np.ndarray = field(init=False)  # Xᵀy with d free
    d_fixed: bool = False
    narrow: bool = False  # the design cannot place d beside C2n (one speed)
    plain: "tuple[np.ndarray, np.ndarray, list[int]]" = field(init=False)  # d free, no yaw-rate
    # bias's columns, the terms kept before the bias: DResult.free_m's fit (``_with_yaw_bias`` takes it)
    yaw_bias: "_YawBias | None" = None

    def __post_init__(self) -> None:
        self.free_xty = self.xty


@dataclass(frozen=True)
class _Solution:
    terms: list[int]
    coef: np.ndarray
    cov: np.ndarray


def _plain_d(
    xtx: np.ndarray, xty: np.ndarray, base: list[int], run: np.ndarray, n: int, q: float
) -> float | None:
    """Where d is held: the top of d's 95 % interval as the samples alone place it, in the plain
    fit (ψ0, d, a_y: no term that a narrow design could make d's double)."""
    offsets = [t for t in base if t == 0 or t >= _K]
    fit = _solve(xtx, xty, run, [*offsets, Term.D, Term.AY], n)
    if fit is None:
        return None
    i = fit.terms.index(Term.D)
    return float(fit.coef[i]) + q * math.sqrt(max(float(fit.cov[i, i]), 0.0))


@dataclass(frozen=True)
class _YawBias:
    xtx: np.ndarray  # the blocks' statistics with its terms appended
    xty: np.ndarray
    terms: list[int]  # their indices there: one per drive (a gyro's bias changes when it is switched on)
    fit: _Solution  # the linear fit with them


def _yaw_bias(
    xtx: np.ndarray,
    xty: np.ndarray,
    run: np.ndarray,
    base: list[int],
    n: int,
    d: float,
    linear: _Solution,
    speeds: list[tuple[int, int]],
) -> _YawBias | None:
    """A yaw rate that reads b high puts (r + b)/u and u·(r + b) in κ and a_y, which moves the
    sideslip the fit sees by b·(u/(g·C2n) − d/u): one term per drive, k·u − d/u with k = 1/(g·C2n)
    from the fit, appended and refitted until k settles (``speeds``: each drive's columns u and
    1/u, which combine it)."""
    k = -float(linear.coef[linear.terms.index(Term.AY)])
    fit = linear
    for _ in range(_BIAS_ITERATIONS):
        wide_xtx, wide_xty, terms = _combined(xtx, xty, [{u: k, inv_u: -d} for u, inv_u in speeds])
        refit = _solve(wide_xtx, wide_xty, run, [*base, *terms], n)
        if refit is None:
            return None
        fit, settled = refit, k
        k = -float(fit.coef[fit.terms.index(Term.AY)])
        if abs(k - settled) <= 1e-6 * abs(k):
            break
    return _YawBias(wide_xtx, wide_xty, terms, fit)


def _combination_weights(k: int, combinations: list[dict[int, float]]) -> np.ndarray:
    """The weights (k × combinations) that make each combination (Σ weight·term) of k columns."""
    w = np.zeros((k, len(combinations)))
    for j, combination in enumerate(combinations):
        for term, weight in combination.items():
            w[term, j] = weight
    return w


def _combined(
    xtx: np.ndarray, xty: np.ndarray, combinations: list[dict[int, float]]
) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """The blocks' statistics with a term appended for each combination (Σ weight·term); returns
    their indices too."""
    k, extra = xtx.shape[1], len(combinations)
    w = _combination_weights(k, combinations)
    cross = xtx @ w  # (blocks, k, extra)
    wide_xtx = np.zeros((len(xtx), k + extra, k + extra))
    wide_xtx[:, :k, :k] = xtx
    wide_xtx[:, :k, k:] = cross
    wide_xtx[:, k:, :k] = cross.transpose(0, 2, 1)
    wide_xtx[:, k:, k:] = w.T @ cross
    return wide_xtx, np.concatenate([xty, xty @ w], axis=1), list(range(k, k + extra))


def _bias(fit: _Solution, term: int, q: float) -> tuple[float, tuple[float, float]]:
    """The yaw rate's bias in °/s with its 95 % interval: the term's coefficient is b itself."""
    i = fit.terms.index(term)
    value, se = float(fit.coef[i]), math.sqrt(max(float(fit.cov[i, i]), 0.0))
    return math.degrees(value), (math.degrees(value - q * se), math.degrees(value + q * se))


def _within(xtx: np.ndarray) -> float:
    """Σ(κ − κ̄)² of the blocks' samples: how much the curvature varies about its own mean."""
    n, sum_k, sum_k2 = xtx[:, 0, 0].sum(), xtx[:, 0, 1].sum(), xtx[:, 1, 1].sum()
    return float(sum_k2 - sum_k * sum_k / n) if n > 0 else 0.0


D_EXACT_SD_M = 1e-4  # a tape stated exact (d_tolerance_mm 0): its prior 0.1 mm, finer than any tape reads
_SETTLED = 1e-4  # a_y's coefficient settled: a change under 0.01 % of C2n, far inside its interval
_PASSES = 5  # at most: a_y's coefficient settles in three, a slope's load transfer takes one more


@dataclass(frozen=True)
class _Design:
    """The marginal fit's statistics and columns: ψ0's, the speed pairs, the drive's own terms."""

    blocks: Blocks
    offsets: list[int]
    speeds: list[tuple[int, int]]
    own: list[int]


def _per_log(
    xtx: np.ndarray, xty: np.ndarray, log: np.ndarray
) -> tuple[np.ndarray, np.ndarray, list[int], list[tuple[int, int]]]:
    """The blocks' statistics with the intercept and the speed columns u, 1/u split by drive: drive
    k ≥ 1 has them as terms ``_K + 3·(k − 1)`` on (the first drive's stay PSI0, U and INV_U).
    Returns them, the ψ0 terms and the speed columns' pairs."""
    logs = np.unique(log)
    split = (Term.PSI0, Term.U, Term.INV_U)
    size = _K + len(split) * (len(logs) - 1)
    wide_xtx = np.zeros((len(xtx), size, size))
    wide_xty = np.zeros((len(xty), size))
    offsets: list[int] = [Term.PSI0]
    speeds: list[tuple[int, int]] = [(Term.U, Term.INV_U)]
    for k, drive in enumerate(logs):
        columns = np.arange(_K)
        if k:
            first = _K + len(split) * (k - 1)
            columns[list(split)] = range(first, first + len(split))
            offsets.append(first)
            speeds.append((first + 1, first + 2))
        where = np.flatnonzero(log == drive)
        wide_xtx[np.ix_(where, columns, columns)] = xtx[where]
        wide_xty[np.ix_(where, columns)] = xty[where]
    return wide_xtx, wide_xty, offsets, speeds


def _spread(total: np.ndarray, base: list[int], extra: list[int], n: int) -> float:
    """How much of the ``extra`` terms the ``base`` terms leave: the smaller eigenvalue of their
    covariance beside the others, per sample (sin ψ and cos ψ over full circles: 0.5)."""
    b = total[np.ix_(base, base)]
    e = total[np.ix_(extra, extra)]
    c = total[np.ix_(extra, base)]
    try:
        schur = e - c @ np.linalg.solve(b, c.T)
    except np.linalg.LinAlgError:
        return 0.0
    return float(np.linalg.eigvalsh(schur)[0]) / n


def _left(total: np.ndarray, base: list[int], term: int) -> float:
    """The share of ``term`` the ``base`` terms leave (1: apart from them; 0: their double, or
    never measured)."""
    own = float(total[term, term])
    return _spread(total, base, [term], 1) / own if own > 0 else 0.0


def _tilt(fit: "_Solution") -> tuple[float, float, float, float] | None:
    """The slope's four coefficients (sin ψ, cos ψ, a_y·sin ψ, a_y·cos ψ), where they were fitted."""
    if 4 not in fit.terms:
        return None
    a, b, c, d = (float(fit.coef[fit.terms.index(k)]) for k in (Term.SIN, Term.COS, Term.AY_SIN, Term.AY_COS))
    return (a, b, c, d)


def _turn(fit: "_Solution", g: float) -> float:
    """The force that follows the turn, as a share of the rear axle's weight: the sideslip step
    δ·sign(κ) it makes is f/C2n, so f = δ·C2n (+ towards the turn's inside)."""
    c2n = -1.0 / (g * float(fit.coef[fit.terms.index(Term.AY)]))
    return float(fit.coef[fit.terms.index(Term.TURN)]) * c2n


def _turn_ci(fit: "_Solution", g: float, q: float) -> tuple[float, float]:
    """Its 95 % interval in %, from the step's own (C2n's share of the error is second order)."""
    c2n = -1.0 / (g * float(fit.coef[fit.terms.index(Term.AY)]))
    half = q * _se(fit, Term.TURN) * abs(c2n) * 100.0
    centre = 100.0 * _turn(fit, g)
    return (centre - half, centre + half)


def _tilt_pct(fit: "_Solution", g: float) -> float:
    """The slope in % the fit's sin ψ, cos ψ terms say: C2n·√(A² + B²)."""
    c2n = -1.0 / (g * float(fit.coef[fit.terms.index(Term.AY)]))
    return (
        100.0
        * abs(c2n)
        * math.hypot(fit.coef[fit.terms.index(Term.SIN)], fit.coef[fit.terms.index(Term.COS)])
    )


def _se(fit: "_Solution", term: int) -> float:
    """A coefficient's standard error."""
    i = fit.terms.index(term)
    return math.sqrt(max(float(fit.cov[i, i]), 0.0))


def _c2n_se(fit: "_Solution", g: float) -> float:
    """C2n's standard error: the delta method on C2n = −1/(g·b_ay)."""
    return _se(fit, Term.AY) / (g * float(fit.coef[fit.terms.index(Term.AY)]) ** 2)


def _wald(fit: "_Solution", terms: list[int]) -> float:
    """The Wald statistic of ``terms`` being zero together (χ² with len(terms) degrees)."""
    where = [fit.terms.index(t) for t in terms]
    coef = fit.coef[where]
    try:
        return float(coef @ np.linalg.solve(fit.cov[np.ix_(where, where)], coef))
    except np.linalg.LinAlgError:
        return 0.0


def _slope(fit: "_Solution", c2n: float, q: float) -> tuple[float, tuple[float, float], float]:
    """The slope in % with its 95 % interval (delta method on √(A² + B²); from zero where the
    interval reaches it), and the direction it falls to in degrees: A·sin ψ + B·cos ψ is
    g_y/(g·C2n) with g_y = g·s·sin(D − ψ), so A = −s·cos D/C2n and B = s·sin D/C2n."""
    i, j = fit.terms.index(Term.SIN), fit.terms.index(Term.COS)
    a, b = fit.coef[i], fit.coef[j]
    size = math.hypot(a, b)
    cov = fit.cov[np.ix_([i, j], [i, j])]
    grad = np.array([a, b]) / size if size > 0 else np.zeros(2)
    se = math.sqrt(max(float(grad @ cov @ grad), 0.0))
    pct = 100.0 * abs(c2n)
    interval = (max(pct * (size - q * se), 0.0), pct * (size + q * se))
    return pct * size, interval, math.degrees(math.atan2(b, -a))


_NAMES = {t.value: t.name.lower() for t in Term}  # the result file's names of the terms


def _least_squares_ay(total: np.ndarray, rhs: np.ndarray, terms: list[int]) -> float | None:
    """a_y's coefficient of the least-squares fit on ``terms`` (the summed statistics), where the
    terms can be told apart: the marginal fit's start, whose priors it scales."""
    inverse = well_conditioned_inverse(total[np.ix_(terms, terms)])
    return None if inverse is None else float((inverse @ rhs[terms])[terms.index(Term.AY)])


def _solve(xtx: np.ndarray, xty: np.ndarray, run: np.ndarray, terms: list[int], n: int) -> _Solution | None:
    """Least squares on a subset of the terms, with a Newey–West covariance over blocks
    (Bartlett weights 1 and ½: a block and its neighbour in the same run)."""
    sub_xtx = xtx[:, terms][:, :, terms]
    sub_xty = xty[:, terms]
    inverse = well_conditioned_inverse(sub_xtx.sum(axis=0))
    if inverse is None:
        return None
    coef = inverse @ sub_xty.sum(axis=0)
    scores = sub_xty - sub_xtx @ coef  # Σ x·e per block
    meat = scores.T @ scores
    same_run = run[1:] == run[:-1]
    cross = scores[1:][same_run].T @ scores[:-1][same_run]
    meat += 0.5 * (cross + cross.T)
    k = len(terms)
    cov = inverse @ meat @ inverse * n / max(n - k, 1)
    return _Solution(terms, coef, cov)


def _priors(
    priors: Priors, g: float, b_ay: float, wheelbase_m: float, pull: "_Pull | None"
) -> dict[int, tuple[float, float]]:
    """Each term's prior (mean, standard deviation) in its coefficient's units; ratios to a_y's
    coefficient scaled with ``b_ay`` (−1/(g·C2n)) from the fit before.

    A slope's load transfer follows its pull: the grade s falling towards D pulls β by
    −b·g·s·sin(D − ψ) (sin ψ's and cos ψ's coefficients c_s = b·g·s·cos D, c_c = −b·g·s·sin D)
    and, its gravity along the heading moving the rear's load by L·s·cos(D − ψ) of it, changes the
    a_y coefficient by b·L·s·cos(D − ψ): a_y·cos ψ's coefficient is (L/g)·c_s and a_y·sin ψ's
    −(L/g)·c_c. Given the pull found (``pull``), the pair's prior is that, with L's own spread
    (N(L, L²)) times the pull's size; before a pull is found, the grade's prior times L."""
    k = abs(b_ay)
    grade = priors.slope_pct / 100.0
    transfer = priors.load_transfer_per_g
    if pull is None:
        ay_sin = ay_cos = (0.0, grade * k * transfer)
    else:
        spread = transfer / g * pull.size
        ay_sin, ay_cos = (-transfer / g * pull.cos, spread), (transfer / g * pull.sin, spread)
    return {
        Term.PSI0: (0.0, math.radians(priors.head_yaw_deg)),
        Term.AY: (0.0, math.inf),
        Term.AY3: (0.0, k * priors.softening_per_mps2_2),
        Term.SIN: (0.0, grade * k * g),  # g_y/(g·C2n) = g·s·sin(D − ψ)·|b_ay|
        Term.COS: (0.0, grade * k * g),
        Term.AY_SIN: ay_sin,
        Term.AY_COS: ay_cos,
        Term.R_DOT: (0.0, k * priors.yaw_inertia_wheelbases * wheelbase_m),
        Term.AY_U_DOT: (0.0, k * transfer / g),
        Term.TURN: (0.0, priors.turn_force_pct / 100.0 * k * g),
        Term.K2_AY: (0.0, k * (priors.two_wheels_wheelbases2 * wheelbase_m) ** 2),
    }


@dataclass(frozen=True)
class _Pull:
    """A slope's pull as a fit found it: sin ψ's and cos ψ's coefficients, and its size with
    their variances counted (√(c_s² + c_c² + var c_s + var c_c): never 0 where the data are)."""

    sin: float
    cos: float
    size: float

    @classmethod
    def of(cls, post: Posterior) -> "_Pull | None":
        if Term.SIN not in post.terms:
            return None
        sin, cos = post.value(Term.SIN), post.value(Term.COS)
        size = math.sqrt(sin * sin + cos * cos + post.se(Term.SIN) ** 2 + post.se(Term.COS) ** 2)
        return cls(sin, cos, size)
