"""The cascade of tests: the regression's terms (``regression.py``) each kept where its test passes,
the estimator before 2026-11-27 (``[priors] estimator = "cascade"``), kept as the reference the
marginal fit is measured against (tools/bench_coverage.py).

In order (``fit_cascade``): ψ0, d and a_y, a small pad's two terms, a slope's four where the
headings cover it and its Wald test and size pass, the quasi-steady terms (``_first_terms``); d
held at the tape's value where the design cannot place it (``_hold_d``); a force that follows the
turn on the BIC's evidence (``_with_turn_force``); a yaw rate's bias on quasi-steady samples
(``_with_yaw_bias``); and the tyres' softening at |t| > ``softening_t``, both models' intervals
spanned where the data could hide more softening than ``UNRESOLVED_PCT`` (``_result``). The
reasons for each test and its threshold are in ``regression.py``'s account of the terms.
"""

import math
from dataclasses import dataclass, field

import numpy as np

from app.results.fit_groups import (
    DResult,
    ModelChoice,
    ModelFit,
    Psi0Result,
    RegressionFit,
    SlopeResult,
    SofteningResult,
    TurnForceResult,
    YawBiasResult,
)
from app.results.least_squares import (
    SLOPE_SPREAD,
    SLOPE_WALD,
    TERM_NAMES,
    TURN_SPREAD,
    K,
    Samples,
    Solution,
    Statistics,
    bias_of,
    c2n_se_of,
    combined,
    per_log,
    slope_of,
    solve,
    term_se,
    term_spread,
    tilt_of,
    turn_ci,
    turn_share,
    wald,
)
from app.results.marginal import Term

UNRESOLVED_PCT = 3.0  # softening that could hide in the data, % of C2n, beyond which both models count
D_HELD_GAIN = 2.0  # d is held at the tape's value where fitting it would widen C2n's interval this much
_CM = 0.01  # metres: the tape step of DResult.per_tape_cm_pct, and of the decision below
D_HELD_REF_M = _CM  # ... beside the held interval with this much tape, whatever the config's tolerance
# (a result's value does not depend on a stated tolerance, only its interval does)
SLOPE_MIN_PCT = 0.25  # a slope under this moves C2n by less than the method's own error (a 2 %
# slope left out: 2.5 %), and is seen on level pads too (0.05–0.16 %: heading-borne misfit)
TURN_MIN_HELD_PCT = 1.0  # where d is held (ordinary driving) a gyro's bias, whose share of a_y and κ
# differs between left and right corners taken at different speeds, passes for a turn force: a
# test day's 0.06 °/s read 0.6 % on track laps (C2n −3.4 %); CommonRoad's camber step is 2–3 %
_BIAS_ITERATIONS = 5  # refits of a yaw-rate bias's term, its C2n from the fit before (3 settle it to 1e-6)
TIGHT_TERMS = (
    Term.AY_U_DOT,
    Term.K2_AY,
)  # on a small pad: the sweeps' load transfer a_y·u̇ and the two wheels' κ²·a_y
_TERM_LEFT = 0.01  # a term tried only where the others leave this share of it (u̇ never passed: 0)


def fit_cascade(model: Samples, statistics: Statistics) -> RegressionFit | None:
    """The cascade on ``model``'s statistics (``SampleRegression._statistics``)."""
    cascade = _first_terms(model, statistics)
    _hold_d(model, cascade)
    _with_turn_force(model, cascade)
    _with_yaw_bias(model, cascade)
    return _result(model, cascade)


def _first_terms(model: Samples, statistics: Statistics) -> "_Cascade":
    """The cascade's first terms: ψ0 where the curvature varies within the drives (else it is
    d·κ's double), d and a_y; a small pad's two terms where its sweeps show them; a slope's
    four where the headings and the Wald test find one; the quasi-steady samples' two."""
    xtx, xty, _, run, log = statistics
    n, b = model.n_samples, len(run)
    drives = np.unique(log)
    spread_k = sum(_within(xtx[log == k]) for k in drives) if len(drives) > 1 else _within(xtx)
    psi0_free = spread_k >= 0.04 * xtx[:, Term.D, Term.D].sum() > 0
    logs = len(drives)
    offsets: list[int] = [Term.PSI0]
    speeds: list[tuple[int, int]] = [(Term.U, Term.INV_U)]
    if logs > 1:  # each drive its own ψ0 (and speed columns: its own gyro's bias)
        xtx, xty, offsets, speeds = per_log(xtx, xty, log)
    total = xtx.sum(axis=0)
    base: list[int] = [*offsets, Term.D, Term.AY] if psi0_free else [Term.D, Term.AY]
    tight = model.mostly_tight
    wide = model.speeds_apart
    if tight and wide and model.d_tape_m is not None:  # a small pad's sweeps: d held (below) and
        pad = [t for t in TIGHT_TERMS if _left(total, base, t) >= _TERM_LEFT]  # these two fitted,
        if solve(xtx, xty, run, [*base, *pad], n) is not None:  # where they leave a fit
            base += pad
    tilted = None  # the fit with a slope's pull, where the headings let one be fitted
    if logs == 1 and psi0_free and term_spread(total, base, [Term.SIN, Term.COS], n) >= SLOPE_SPREAD:
        tilted = solve(xtx, xty, run, [*base, Term.SIN, Term.COS], n)
        if (
            tilted is not None
            and wald(tilted, [Term.SIN, Term.COS]) > SLOPE_WALD
            and _tilt_pct(tilted, model.g) >= SLOPE_MIN_PCT
        ):  # a slope found: its pull, and its gravity along the heading
            base += [Term.SIN, Term.COS, Term.AY_SIN, Term.AY_COS]
    # the yaw inertia's share of the rear force, and the speed's load transfer: in ordinary
    # driving always there (left out where they are not significant: C2n 1.4 % low on three
    # simulated track laps, the truth outside the interval)
    quasi_terms = [t for t in (Term.R_DOT, Term.AY_U_DOT) if t not in base]
    transient = model.transient and solve(xtx, xty, run, [*base, *quasi_terms], n) is not None
    if transient:
        base += quasi_terms
    linear = solve(xtx, xty, run, base, n)
    return _Cascade(
        xtx, xty, run, n, b, logs, speeds, psi0_free, tight, wide, total, base, linear, tilted, transient
    )


def _hold_d(model: Samples, c: "_Cascade") -> None:
    """d at the tape's value (β − d·κ on the other terms) where the design is too narrow to
    place it beside C2n (one speed), on a small pad, and in ordinary driving."""
    if model.d_tape_m is None:
        return
    held_xty = c.xty - model.d_tape_m * c.xtx[:, :, Term.D]
    held_base = [t for t in c.base if t != Term.D]
    held = solve(c.xtx, held_xty, c.run, held_base, c.n)
    if held is None:
        return
    c.narrow = c.linear is None or c2n_se_of(c.linear, model.g) > D_HELD_GAIN * _held_se(
        model, held, c.xtx, held_xty, c.run, c.n, D_HELD_REF_M
    )
    if c.narrow or c.tight or model.transient:  # transient: ordinary driving, where the tape's
        c.d_fixed, c.xty, c.base, c.linear = True, held_xty, held_base, held  # d is better


def _with_turn_force(model: Samples, c: "_Cascade") -> None:
    """A force that follows the turn's direction, not its size. It needs radii and speeds
    apart: at one speed it takes a_y's slope and the a_y³ term's curvature (circles at one speed
    ±1 %: worst C2n 0.7 → 4.3 %). Tried beside the a_y³ term: a softening tyre's curvature,
    left to a straight line, leans on sign(κ) as well."""
    if (
        c.psi0_free
        and c.wide
        and not c.narrow
        and term_spread(c.total, c.base, [Term.TURN], c.n) >= TURN_SPREAD
        and _turn_found(
            model, solve(c.xtx, c.xty, c.run, [*c.base, Term.AY3, Term.TURN], c.n), c.blocks, c.d_fixed
        )
    ):
        c.base += [Term.TURN]
        c.linear = solve(c.xtx, c.xty, c.run, c.base, c.n)


def _with_yaw_bias(model: Samples, c: "_Cascade") -> None:
    """A yaw-rate bias's term, on quasi-steady samples with d held and the speeds apart; a turn
    force found is kept only if it passes again with the bias out."""
    c.plain = (c.xtx, c.free_xty, list(c.base))
    if not (
        c.transient
        and c.d_fixed
        and c.wide
        and c.psi0_free
        and c.linear is not None
        and model.d_tape_m is not None
    ):
        return
    yaw_bias = _yaw_bias(c.xtx, c.xty, c.run, c.base, c.n, model.d_tape_m, c.linear, c.speeds)
    if yaw_bias is not None and Term.TURN in c.base:  # the turn force still there with the bias out?
        turned = solve(yaw_bias.xtx, yaw_bias.xty, c.run, [*c.base, *yaw_bias.terms, Term.AY3], c.n)
        if not _turn_found(model, turned, c.blocks, c.d_fixed):  # a gyro's −1 °/s: 0.05 % [−0.09, 0.20]
            c.base = [t for t in c.base if t != Term.TURN]
            yaw_bias = _yaw_bias(c.xtx, c.xty, c.run, c.base, c.n, model.d_tape_m, c.linear, c.speeds)
    if yaw_bias is not None:
        c.xtx, c.xty, c.linear = yaw_bias.xtx, yaw_bias.xty, yaw_bias.fit
        c.base = [*c.base, *yaw_bias.terms]
    c.yaw_bias = yaw_bias


def _result(model: Samples, c: "_Cascade") -> RegressionFit | None:
    """The cascade's last test, the tyres' softening: the a_y³ term kept where it softens at
    |t| > ``softening_t``; where the data could hide more softening than ``UNRESOLVED_PCT``,
    C2n's interval spans both models'. Then the result, with every term the cascade kept."""
    cubic = solve(c.xtx, c.xty, c.run, [*c.base, Term.AY3], c.n)
    if cubic is None or c.linear is None:
        return None
    t3 = cubic.coef[-1] / math.sqrt(cubic.cov[-1, -1]) if cubic.cov[-1, -1] > 0 else 0.0
    # softening s = b3/b_ay must be positive: a tyre loses stiffness with slip, never gains it
    softens = cubic.coef[-1] * cubic.coef[cubic.terms.index(Term.AY)] > 0
    chosen = cubic if softens and abs(t3) > model.softening_t else c.linear
    terms = chosen.terms
    from scipy.special import stdtrit  # the t quantile; imported at the first fit, not at the start

    q = float(stdtrit(max(c.blocks - len(terms), 1), 0.975))

    def ci(value: float, se: float) -> tuple[float, float]:
        return (value - q * se, value + q * se)

    def model_se(fit: Solution, scales: bool = True) -> float:
        """C2n's error: the data's (with the tape's where d is held) and, with ``scales``, the
        sensors' scales', which no drive can show."""
        if c.d_fixed:
            data = _held_se(model, fit, c.xtx, c.xty, c.run, c.n, model.d_tape_se_m)
        else:
            data = c2n_se_of(fit, model.g)
        if not scales:
            return data
        scale = model.scale_se / (model.g * abs(float(fit.coef[fit.terms.index(Term.AY)])))
        return math.hypot(data, scale)

    def model_ci(fit: Solution, scales: bool = True) -> tuple[float, float] | None:
        slope = fit.coef[fit.terms.index(Term.AY)]
        if slope >= 0:  # no stiffness
            return None
        half = float(stdtrit(max(c.blocks - len(fit.terms), 1), 0.975)) * model_se(fit, scales)
        return (-1.0 / (model.g * slope) - half, -1.0 / (model.g * slope) + half)

    slope = chosen.coef[terms.index(Term.AY)]
    c2n = -1.0 / (model.g * slope)
    c2n_se = model_se(chosen)
    c2n_ci95 = ci(c2n, c2n_se)
    data_ci95 = ci(c2n, model_se(chosen, scales=False))
    c2n_linear = -1.0 / (model.g * c.linear.coef[c.linear.terms.index(Term.AY)])
    c2n_cubic = -1.0 / (model.g * cubic.coef[cubic.terms.index(Term.AY)])
    # the two models differ by the a_y³ term alone, so their difference has the term's t
    hidden = float(200.0 * abs((c2n_cubic - c2n_linear) / t3 / c2n)) if t3 else math.inf
    resolved = bool(chosen is cubic or hidden <= UNRESOLVED_PCT)
    if not resolved:
        i_cubic = cubic.terms.index(Term.AY)
        slope3 = cubic.coef[i_cubic]
        cubic_se = math.sqrt(cubic.cov[i_cubic, i_cubic]) / (model.g * slope3 * slope3)
        low, high = ci(c2n_cubic, cubic_se) if slope3 < 0 else (c2n_ci95[0], math.inf)
        c2n_ci95 = (min(c2n_ci95[0], low), max(c2n_ci95[1], high))
        data_ci95 = (min(data_ci95[0], low), max(data_ci95[1], high))
        c2n_se = max(c2n_se, cubic_se)
    if c.d_fixed and model.d_tape_m is not None:
        d, d_se = model.d_tape_m, 0.0
    else:
        i_d = terms.index(Term.D)
        d, d_se = chosen.coef[i_d], math.sqrt(chosen.cov[i_d, i_d])
    psi0 = psi0_se = None
    if c.psi0_free:
        i_psi0 = terms.index(Term.PSI0)
        psi0, psi0_se = chosen.coef[i_psi0], math.sqrt(chosen.cov[i_psi0, i_psi0])
    slope = slope_of(chosen if Term.SIN in terms else c.tilted, c2n, q) if c.tilted is not None else None
    bias = bias_of(chosen, c.yaw_bias.terms[0], q) if c.yaw_bias is not None else None
    softening = softening_se = None
    if chosen is cubic:
        softening = -cubic.coef[-1] * model.g * c2n  # α2 = a_y/(g·C2n)·(1 + s·a_y²)
        softening_se = term_se(cubic, cubic.terms[-1]) * model.g * abs(c2n)
    return RegressionFit(
        c2n=c2n,
        c2n_se=c2n_se,
        c2n_ci95=c2n_ci95,
        samples=model.fit_samples(
            c.blocks, c.logs, c.transient, tuple(TERM_NAMES[t] for t in TIGHT_TERMS if t in terms)
        ),
        d=DResult(
            m=d,
            ci95_m=ci(d, d_se),
            held=c.d_fixed,
            held_tight=c.d_fixed and c.tight and not c.narrow,
            per_tape_cm_pct=100.0 * _tape_shift(model, chosen, c.xtx, c.xty, c.run, c.n, _CM) / c2n
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
        slope=SlopeResult(slope[0], slope[1], slope[2], tilt_of(chosen)) if slope else None,
        turn_force=TurnForceResult(
            pct=100.0 * turn_share(chosen, model.g),
            ci95_pct=turn_ci(chosen, model.g, q),
            step_rad=float(chosen.coef[terms.index(Term.TURN)]),
            step_se_rad=term_se(chosen, Term.TURN),
        )
        if Term.TURN in terms
        else None,
        yaw_bias=YawBiasResult(bias[0], bias[1]) if bias else None,
        scale_se=model.scale_se,
        c2n_data_ci95=data_ci95,
    )


def _held_se(
    model: Samples,
    held: "Solution",
    xtx: np.ndarray,
    xty: np.ndarray,
    run: np.ndarray,
    n: int,
    tape_se_m: float,
) -> float:
    """C2n's standard error with d held at the tape's value, the tape's own error counted."""
    return math.hypot(c2n_se_of(held, model.g), _tape_shift(model, held, xtx, xty, run, n, tape_se_m))


def _tape_shift(
    model: Samples,
    held: "Solution",
    xtx: np.ndarray,
    xty: np.ndarray,
    run: np.ndarray,
    n: int,
    step_m: float,
) -> float:
    """How far C2n moves when the held d is ``step_m`` longer: the fit again."""
    if step_m == 0.0:
        return 0.0
    longer = solve(xtx, xty - step_m * xtx[:, :, Term.D], run, held.terms, n)
    if longer is None:
        return 0.0
    i = held.terms.index(Term.AY)
    return abs(1.0 / (model.g * float(held.coef[i])) - 1.0 / (model.g * float(longer.coef[i])))


def _turn_found(model: Samples, fit: Solution | None, blocks: int, held: bool) -> bool:
    """A turn force kept on the BIC's evidence, χ² > ln(blocks) (at 95 % one Magic-Formula drive
    in 20 to 7 m/s² took a 0.28 % force for one, C2n +1.5 %), and large enough to be one."""
    return (
        fit is not None
        and wald(fit, [Term.TURN]) > math.log(blocks)
        and 100.0 * abs(turn_share(fit, model.g)) >= (TURN_MIN_HELD_PCT if held else SLOPE_MIN_PCT)
    )


@dataclass
class _Cascade:
    """The cascade's working state as its tests go (``fit_cascade``): the statistics
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
    wide: bool  # the speeds apart (WIDE_SPEEDS)
    total: np.ndarray  # XᵀX over every block
    base: list[int]  # the terms kept
    linear: Solution | None  # the fit on them
    tilted: Solution | None  # the fit with a slope's pull, where the headings let one be tried
    transient: bool  # the quasi-steady terms kept
    free_xty: np.ndarray = field(init=False)  # Xᵀy with d free
    d_fixed: bool = False
    narrow: bool = False  # the design cannot place d beside C2n (one speed)
    plain: "tuple[np.ndarray, np.ndarray, list[int]]" = field(init=False)  # d free, no yaw-rate
    # bias's columns, the terms kept before the bias: DResult.free_m's fit (``_with_yaw_bias`` takes it)
    yaw_bias: "_YawBias | None" = None

    def __post_init__(self) -> None:
        self.free_xty = self.xty


def _plain_d(
    xtx: np.ndarray, xty: np.ndarray, base: list[int], run: np.ndarray, n: int, q: float
) -> float | None:
    """Where d is held: the top of d's 95 % interval as the samples alone place it, in the plain
    fit (ψ0, d, a_y: no term that a narrow design could make d's double)."""
    offsets = [t for t in base if t == 0 or t >= K]
    fit = solve(xtx, xty, run, [*offsets, Term.D, Term.AY], n)
    if fit is None:
        return None
    i = fit.terms.index(Term.D)
    return float(fit.coef[i]) + q * math.sqrt(max(float(fit.cov[i, i]), 0.0))


@dataclass(frozen=True)
class _YawBias:
    xtx: np.ndarray  # the blocks' statistics with its terms appended
    xty: np.ndarray
    terms: list[int]  # their indices there: one per drive (a gyro's bias changes when it is switched on)
    fit: Solution  # the linear fit with them


def _yaw_bias(
    xtx: np.ndarray,
    xty: np.ndarray,
    run: np.ndarray,
    base: list[int],
    n: int,
    d: float,
    linear: Solution,
    speeds: list[tuple[int, int]],
) -> _YawBias | None:
    """A yaw rate that reads b high puts (r + b)/u and u·(r + b) in κ and a_y, which moves the
    sideslip the fit sees by b·(u/(g·C2n) − d/u): one term per drive, k·u − d/u with k = 1/(g·C2n)
    from the fit, appended and refitted until k settles (``speeds``: each drive's columns u and
    1/u, which combine it)."""
    k = -float(linear.coef[linear.terms.index(Term.AY)])
    fit = linear
    for _ in range(_BIAS_ITERATIONS):
        wide_xtx, wide_xty, terms = combined(xtx, xty, [{u: k, inv_u: -d} for u, inv_u in speeds])
        refit = solve(wide_xtx, wide_xty, run, [*base, *terms], n)
        if refit is None:
            return None
        fit, settled = refit, k
        k = -float(fit.coef[fit.terms.index(Term.AY)])
        if abs(k - settled) <= 1e-6 * abs(k):
            break
    return _YawBias(wide_xtx, wide_xty, terms, fit)


def _within(xtx: np.ndarray) -> float:
    """Σ(κ − κ̄)² of the blocks' samples: how much the curvature varies about its own mean."""
    n, sum_k, sum_k2 = xtx[:, 0, 0].sum(), xtx[:, 0, 1].sum(), xtx[:, 1, 1].sum()
    return float(sum_k2 - sum_k * sum_k / n) if n > 0 else 0.0


def _left(total: np.ndarray, base: list[int], term: int) -> float:
    """The share of ``term`` the ``base`` terms leave (1: apart from them; 0: their double, or
    never measured)."""
    own = float(total[term, term])
    return term_spread(total, base, [term], 1) / own if own > 0 else 0.0


def _tilt_pct(fit: Solution, g: float) -> float:
    """The slope in % the fit's sin ψ, cos ψ terms say: C2n·√(A² + B²)."""
    c2n = -1.0 / (g * float(fit.coef[fit.terms.index(Term.AY)]))
    return (
        100.0
        * abs(c2n)
        * math.hypot(fit.coef[fit.terms.index(Term.SIN)], fit.coef[fit.terms.index(Term.COS)])
    )
