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

``fit`` gives C2n two ways from the same statistics: by default one model with every term under
its prior (``marginal_fit.py``, whose maths is ``marginal.py``'s), or the cascade of tests this
account describes (``cascade.py``: ``[priors] estimator = "cascade"``), kept as the reference.
Both read their fits off the least squares in ``least_squares.py``; the result is a
``RegressionFit`` (``fit_groups.py``).
"""

import math

import numpy as np

from app.config import Priors
from app.results.cascade import fit_cascade
from app.results.fit_groups import FitSamples, RegressionFit
from app.results.least_squares import WIDE_SPEEDS, K, Statistics
from app.results.marginal_fit import fit_marginal
from app.units import Z95

__all__ = ["RegressionFit", "SampleRegression"]

_TERMS = (  # the columns each block keeps (``Term``'s names); a fit takes a subset
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
    "ay5",  # a_y⁵: the softening's next term
)
_GAP_S = 0.5  # a longer pause in steady samples starts a new run (no autocorrelation across it)
AY_SPAN_MPS2 = 0.5  # a fit needs its samples this far apart in |a_y|: C2n is their slope
MIN_SAMPLES = 200  # and this many of them, in ten blocks
D_TAPE_SE_M = 0.01 / Z95  # the tape's d to ±1 cm at 95 % (the config's default): in C2n's interval
TIGHT_WHEELBASES = 20.0  # most samples on radii under this many wheelbases: d is held at the tape's
# (the bicycle model's one-wheel axle misreads the two wheels of a tight turn by a share that d·κ
# takes: two-track radii of 25–36 m, d fitted 6–10 mm long, C2n 1–2.3 % low; held, within 1 %)


class SampleRegression:
    """The samples' statistics, block by block (``add``), and C2n fitted on them (``fit``)."""

    def __init__(
        self,
        g: float,
        block_s: float = 0.25,
        max_blocks: int = 32768,
        softening_t: float = 2.0,
        min_samples: int = MIN_SAMPLES,
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
        self._xtx = np.zeros((capacity, K, K))
        self._xty = np.zeros((capacity, K))
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
        columns += [r_dot, ay * u_dot, np.sign(kappa), u, 1.0 / u, kappa * kappa * ay, ay**5]
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
        self._xtx = np.resize(self._xtx, (size, K, K))
        self._xty = np.resize(self._xty, (size, K))
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

    def fit(self) -> RegressionFit | None:
        """The fit over every sample so far, or None while the data cannot support one: one model
        with every nuisance's prior (``priors``: ``marginal_fit.py``), else the cascade of tests
        (``cascade.py``)."""
        statistics = self._statistics()
        if statistics is None:
            return None
        if self.priors is not None:
            return fit_marginal(self, self.priors, statistics)
        return fit_cascade(self, statistics)

    def fit_samples(
        self, blocks: int, logs: int, transient_terms: bool, tight_terms: tuple[str, ...] = ()
    ) -> FitSamples:
        """What a fit rests on: the samples, their blocks and drives, their ranges."""
        return FitSamples(
            count=self.n_samples,
            blocks=blocks,
            ay_range_mps2=(self._ay_min, self._ay_max),
            curvature_range_per_m=(self._kappa_min, self._kappa_max),
            speed_range_mps=(self._u_min, self._u_max),
            duration_s=self._seconds,
            logs=logs,
            transient_terms=transient_terms,
            tight_terms=tight_terms,
        )

    @property
    def speeds_apart(self) -> bool:
        """The fastest sample ``WIDE_SPEEDS`` times the slowest: speeds apart, not one speed."""
        return self._u_max >= WIDE_SPEEDS * self._u_min

    @property
    def mostly_tight(self) -> bool:
        """Most samples on radii under ``TIGHT_WHEELBASES``: a small pad."""
        return 2 * self._tight_n > self.n_samples

    def _statistics(self) -> Statistics | None:
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
        if self.n_samples < self.min_samples or b < 10 or self._ay_max - self._ay_min < AY_SPAN_MPS2:
            return None
        return Statistics(self._xtx[:b], self._xty[:b], self._yty[:b], self._run[:b], self._log[:b])
