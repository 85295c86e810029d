"""The marginal fit on a ``SampleRegression``'s statistics (the default estimator): its design — each
drive its own ψ0 and gyro's bias, the terms the physics allows — each term's prior scaled from
a_y's coefficient (``_priors``), the passes until that coefficient settles (``_posterior``), d's
two priors weighed by their evidence, and the result: C2n and d as the two posteriors' mixture,
the rest from the heavier one, the term holding C2n's interval open named. The model and its
maths are ``marginal.py``'s."""

import math
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from app.config import Priors
from app.results.fit_groups import (
    DResult,
    HeldOpen,
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
    combination_weights,
    per_log,
    slope_of,
    term_spread,
    tilt_of,
    turn_ci,
    turn_share,
    wald,
)
from app.results.marginal import (
    Blocks,
    Posterior,
    Term,
    data_alone,
    left_out,
    mixture,
    posterior,
    reciprocal_mixture,
    well_conditioned_inverse,
    wide_share,
)

D_EXACT_SD_M = 1e-4  # a tape stated exact (d_tolerance_mm 0): its prior 0.1 mm, finer than any tape reads


_SETTLED = 1e-4  # a_y's coefficient settled: a change under 0.01 % of C2n, far inside its interval


_PASSES = 5  # at most: a_y's coefficient settles in three, a slope's load transfer takes one more


def fit_marginal(model: Samples, priors: Priors, statistics: Statistics) -> RegressionFit | None:
    """One model, every nuisance with its prior (``marginal.py``); C2n's interval carries what
    the drive cannot tell apart, and names the term that holds it open most. d's prior: the
    tape's, and with ``d_gross_share`` a wide one (the tape wrong), each weighed by its evidence
    (``wide_share``); without a tape, a flat one."""
    made = _design(model, priors, statistics)
    if made is None:
        return None
    design, b_ay, covered = made
    blocks, logs = len(statistics.run), design.logs
    if model.d_tape_m is None:
        found = _posterior(model, priors, design, b_ay, math.inf)
        return None if found is None else _result(model, priors, [found], [1.0], blocks, logs, covered)
    tape_sd = max(model.d_tape_se_m, D_EXACT_SD_M)
    wide_sd = priors.d_gross_wheelbases * model.wheelbase_m
    tape = _posterior(model, priors, design, b_ay, tape_sd)
    # the wide prior's fit starts from the tape's a_y, noise, pull and passes' contraction
    wide = _posterior(model, priors, design, tape.post.value(Term.AY) if tape else b_ay, wide_sd, tape)
    if tape is None or wide is None:
        found = tape or wide
        return None if found is None else _result(model, priors, [found], [1.0], blocks, logs, covered)
    # the wide prior's weight by the evidence where the speeds are apart; at one speed d and C2n
    # move together, and what places d there is the other terms' priors (a_y³'s curvature), not
    # the drive: the weight stays the prior's (a flipped sideslip at one speed put it at 1.0,
    # d 0.76 m behind the axle)
    apart = model.speeds_apart
    share = (
        wide_share(wide.post, model.d_tape_m, tape_sd, wide_sd, priors.d_gross_share)
        if apart
        else priors.d_gross_share
    )
    fit = _result(model, priors, [tape, wide], [1.0 - share, share], blocks, logs, covered)
    return None if fit is None else _with_own_d(model, fit, wide.post, wide_sd, apart, priors.confidence)


def _design(
    model: Samples, priors: Priors, statistics: Statistics
) -> tuple["_Design", float, frozenset[Term]] | None:
    """The marginal fit's terms (each drive its own ψ0 and gyro's bias), a_y's coefficient to
    scale the priors from (a least-squares start), and the terms the drive's layout covers."""
    xtx, xty, yty, run, log = statistics
    n, logs = model.n_samples, len(np.unique(log))
    offsets: list[int] = [Term.PSI0]
    speeds: list[tuple[int, int]] = [(Term.U, Term.INV_U)]
    if logs > 1:
        xtx, xty, offsets, speeds = per_log(xtx, xty, log)
    blocks = Blocks(xtx, xty, yty, run, n)
    total, rhs = blocks.total, blocks.total_xty
    b_ay = _least_squares_ay(total, rhs, [*offsets, Term.D, Term.AY])
    if b_ay is None and model.d_tape_m is not None:  # one speed: d at the tape's to start
        b_ay = _least_squares_ay(total, rhs - model.d_tape_m * total[:, Term.D], [*offsets, Term.AY])
    if b_ay is None:
        return None
    # a pad's slope: a plane, whose pull turns with the heading, where the samples are taken on
    # one place (steady circles); a route's corners (quasi-steady samples) are each their own
    # place, whose cross-fall no heading gives; and the headings are each drive's own
    planar = logs == 1 and not model.transient
    slope_terms = [Term.SIN, Term.COS, Term.AY_SIN, Term.AY_COS] if planar else []
    turn = [Term.TURN] if priors.turn_force_pct > 0 else []
    fifth = [Term.AY5] if priors.softening_ratio or priors.softening_ratio_sd else []
    own = [Term.D, Term.AY, Term.AY3, *fifth, *slope_terms, Term.R_DOT, Term.AY_U_DOT, *turn, Term.K2_AY]
    design = _Design(blocks, offsets, speeds, [int(t) for t in own], logs)
    # a slope is reported (and its pull taken out of the crossings) where the headings cover it,
    # as the cascade tries one: one direction on one circle holds a 2 % "slope" at Wald's 95 %
    # that C2n's width carries but no crossing should be moved by; a turn force likewise where
    # the turns' directions and sizes cover it (CommonRoad's sweeps: the early fits, one turn
    # direction so far, handed the paired crossings a step that read them 39–55 % low)
    base = [*offsets, Term.D, Term.AY]
    covered = frozenset(
        term
        for term, layout, least in (
            (Term.SIN, [Term.SIN, Term.COS], SLOPE_SPREAD),
            (Term.TURN, [Term.TURN], TURN_SPREAD),
        )
        if term in own and term_spread(total, base, [int(t) for t in layout], n) >= least
    )
    return design, b_ay, covered


def _with_own_d(
    model: Samples,
    fit: RegressionFit,
    wide: Posterior,
    wide_sd: float,
    apart: bool,
    confidence: float,
) -> RegressionFit:
    """The fit with what the drive alone says of d (the wide prior's posterior less that prior):
    its information over the tape's, and — where the speeds are apart, as the cascade's — the
    top of its interval (a d behind the axle shows a role the wrong way round:
    ``Snapshot.sign_problem``). At one speed the a_y³ term's curvature lends d a little
    information that the prior's shape, not the drive, makes."""
    assert model.d_tape_m is not None
    alone = data_alone(wide, Term.D, model.d_tape_m, wide_sd)
    if alone is None:
        return replace(fit, d=replace(fit.d, information=0.0))
    tape_sd = max(model.d_tape_se_m, D_EXACT_SD_M)
    information = tape_sd**2 / alone[1] if alone[1] > 0 else math.inf
    if not apart:
        return replace(fit, d=replace(fit.d, information=information))
    from scipy.special import stdtrit

    q = float(stdtrit(max(fit.samples.blocks - len(wide.terms), 1), 0.5 + confidence / 2.0))
    free_m = alone[0] + q * math.sqrt(alone[1])
    return replace(fit, d=replace(fit.d, information=information, free_m=free_m))


class _Passes(NamedTuple):
    """A posterior whose priors' scale has settled: the yaw-rate bias's columns, a_y⁵'s reach
    (``_next_term``), and by how much a pass shrank a_y's coefficient's change (None where fewer
    than two passes followed the one before, or a pass did not shrink it)."""

    post: Posterior
    bias_terms: list[int]
    next_term: float
    contraction: float | None


def _posterior(
    model: Samples,
    priors: Priors,
    design: "_Design",
    b_ay: float,
    d_sd: float,
    start: _Passes | None = None,
) -> _Passes | None:
    """The posterior with d's prior N(tape, d_sd²) (flat without a tape); the priors' scale
    follows a_y's coefficient until it settles, each pass from the noise and the pull the one
    before found (the first from ``start``'s, a fit under the other prior on d).

    Settled: a pass moved a_y's coefficient by under ``_SETTLED`` of itself; or, given the
    passes' contraction ρ (``start``'s, measured on the same samples), the fixed point lies
    within that of this pass's result, which a change Δ bounds by Δ·ρ/(1 − ρ): the wide prior's
    fit, started from the tape's, then takes one pass instead of two."""
    post: Posterior | None = None if start is None else start.post
    contraction = None if start is None else start.contraction
    changes: list[float] = []  # a_y's coefficient's change in the passes that followed one before
    bias_terms: list[int] = []
    used: np.ndarray | None = None  # the last pass's weights
    pull = None if post is None else _Pull.of(post)
    softening = None if post is None else _softening2(post)
    own_terms = [*design.offsets, *design.own]
    own_weights = design.blocks.columns(own_terms)
    k = len(own_weights)
    for _ in range(_PASSES):  # the priors follow a_y's coefficient and the slope's pull
        prior = _priors(priors, model.g, b_ay, model.wheelbase_m, pull, softening)
        terms, weights = own_terms, own_weights
        if model.d_tape_m is not None:  # a yaw-rate bias b moves β by b·(k·u − d/u), k = −b_ay
            combos = [{u: -b_ay, inv_u: -model.d_tape_m} for u, inv_u in design.speeds]
            bias_terms = list(range(k, k + len(combos)))
            terms = [*own_terms, *bias_terms]
            weights = np.hstack([own_weights, combination_weights(k, combos)])
        mean, spread = np.array(
            [
                prior[Term.PSI0]
                if t in design.offsets
                else (0.0, math.radians(priors.gyro_bias_degps))
                if t in bias_terms
                else (model.d_tape_m or 0.0, d_sd)
                if t == Term.D
                else prior[t]
                for t in terms
            ]
        ).T
        sigma2 = None if post is None else post.sigma2
        post = posterior(design.blocks, weights, [int(t) for t in terms], mean, spread, sigma2)
        if post is None:
            return None
        used = weights
        # a pass follows the one before where the load transfer's prior was the pull a fit
        # found, and the next softening term's the softening's
        follows = (pull is not None or Term.SIN not in post.terms) and (
            softening is not None or Term.AY5 not in post.terms
        )
        change = abs(post.value(Term.AY) - b_ay) / abs(b_ay)
        reach = change if contraction is None else min(change, change * contraction / (1.0 - contraction))
        b_ay, pull, softening = post.value(Term.AY), _Pull.of(post), _softening2(post)
        if follows:
            changes.append(change)
            if reach <= _SETTLED:
                break
    assert post is not None and used is not None
    if len(changes) >= 2 and 0.0 < changes[-1] < changes[-2]:
        contraction = changes[-1] / changes[-2]
    return _Passes(post, bias_terms, _next_term(design, post, used), contraction)


def _next_term(design: "_Design", post: Posterior, weights: np.ndarray) -> float:
    """How far a_y's coefficient moves, as a share of itself, per unit of a_y⁵'s coefficient (as
    a share of a_y's) left out of the model: λ in Δb/b = λ·c5/b, from the statistics' a_y⁵
    column — 0 where the term is in the model (it carries itself) or cannot be told."""
    if Term.AY5 in post.terms:
        return 0.0
    moved = left_out(design.blocks, weights, post, Term.AY5)
    return 0.0 if moved is None else float(moved[post.index(Term.AY)])


def _result(
    model: Samples,
    priors: Priors,
    found: list[_Passes],
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
    kept = [(f, w) for f, w in zip(found, weights, strict=True) if f.post.value(Term.AY) != 0]
    if not kept:
        return None
    heaviest = max(kept, key=lambda fw: fw[1])[0]
    post, bias_terms, next_term = heaviest.post, heaviest.bias_terms, heaviest.next_term
    from scipy.special import stdtrit

    dof = max(blocks - len(post.terms), 1)
    q = float(stdtrit(dof, 0.5 + priors.confidence / 2.0))
    shares = [w for _, w in kept]
    c2ns = [-1.0 / (model.g * f.post.value(Term.AY)) for f, _ in kept]
    data_ses = [f.post.se(Term.AY) * model.g * c * c for (f, _), c in zip(kept, c2ns, strict=True)]
    c2n_ses = [math.hypot(se, model.scale_se * abs(c)) for se, c in zip(data_ses, c2ns, strict=True)]
    c2n, c2n_ci = reciprocal_mixture(c2ns, c2n_ses, shares, dof, priors.confidence)
    data_ci = c2n_ci
    if model.scale_se:  # the sensors' scales widen the interval; the value is the data's mixture's,
        # which a stated tolerance does not move (its median would: the widths weigh it)
        c2n, data_ci = reciprocal_mixture(c2ns, data_ses, shares, dof, priors.confidence)
    # the softening's next term, where the model leaves it out, reads C2n high by at least
    # next_pct (its series at r = 1): the interval reaches that much further down
    b_ay = post.value(Term.AY)
    next_pct = max(-100.0 * next_term * (post.value(Term.AY3) / b_ay) ** 2, 0.0)
    c2n_ci, data_ci = ((low - c2n * next_pct / 100.0, high) for low, high in (c2n_ci, data_ci))
    c2n_se = (c2n_ci[1] - c2n_ci[0]) / (2.0 * q)
    d_m, d_ci = mixture(
        [f.post.value(Term.D) for f, _ in kept],
        [f.post.se(Term.D) for f, _ in kept],
        shares,
        dof,
        priors.confidence,
    )
    fit = Solution(post.terms, post.coef, post.cov)

    def ci(term: int) -> tuple[float, float]:
        return (post.value(term) - q * post.se(term), post.value(term) + q * post.se(term))

    t3 = post.value(Term.AY3) / post.se(Term.AY3) if post.se(Term.AY3) > 0 else 0.0
    softens = abs(t3) > q and post.value(Term.AY3) * b_ay > 0  # reported where the data show it
    slope = slope_of(fit, c2n, q) if Term.SIN in post.terms else None
    slope_shown = slope is not None and Term.SIN in covered and wald(fit, [Term.SIN, Term.COS]) > SLOPE_WALD
    turn = Term.TURN in post.terms and Term.TURN in covered
    bias = bias_of(fit, bias_terms[0], q) if bias_terms else None
    held = post.held_open_by(Term.AY)
    return RegressionFit(
        c2n=c2n,
        c2n_se=c2n_se,
        c2n_ci95=c2n_ci,
        samples=model.fit_samples(blocks, logs, transient_terms=True),
        d=DResult(m=d_m, ci95_m=d_ci),
        psi0=Psi0Result(post.value(Term.PSI0), ci(Term.PSI0)),
        models=ModelChoice(
            chosen="softening" if softens else "linear",
            softening_t=t3,
            linear=ModelFit(c2n, c2n_ci, data_ci),
            softening=ModelFit(c2n, c2n_ci, data_ci),
        ),
        softening=SofteningResult(
            per_mps2_2=-post.value(Term.AY3) * model.g * c2n,
            se_per_mps2_2=post.se(Term.AY3) * model.g * abs(c2n),
            next_term_pct=next_pct,
        )
        if softens
        else None,
        slope=SlopeResult(slope[0], slope[1], slope[2], tilt_of(fit)) if slope and slope_shown else None,
        turn_force=TurnForceResult(
            pct=100.0 * turn_share(fit, model.g),
            ci95_pct=turn_ci(fit, model.g, q),
            step_rad=post.value(Term.TURN),
            step_se_rad=post.se(Term.TURN),
        )
        if turn
        else None,
        yaw_bias=YawBiasResult(bias[0], bias[1]) if bias else None,
        held_open=HeldOpen(TERM_NAMES.get(held[0], "psi0" if held[0] >= K else None), held[1])
        if held
        else None,
        scale_se=model.scale_se,
        c2n_data_ci95=data_ci,
        estimator="marginal",
    )


@dataclass(frozen=True)
class _Design:
    """The marginal fit's statistics and columns: ψ0's, the speed pairs, the drive's own terms;
    and how many drives the samples hold."""

    blocks: Blocks
    offsets: list[int]
    speeds: list[tuple[int, int]]
    own: list[int]
    logs: int


def _least_squares_ay(total: np.ndarray, rhs: np.ndarray, terms: list[int]) -> float | None:
    """a_y's coefficient of the least-squares fit on ``terms`` (the summed statistics), where the
    terms can be told apart: the marginal fit's start, whose priors it scales."""
    inverse = well_conditioned_inverse(total[np.ix_(terms, terms)])
    return None if inverse is None else float((inverse @ rhs[terms])[terms.index(Term.AY)])


def _softening2(post: Posterior) -> float:
    """The softening's s² as a fit found it, its variance counted (never 0 where the data are):
    s is a_y³'s coefficient over a_y's."""
    b_ay = post.value(Term.AY)
    if b_ay == 0.0:
        return 0.0
    return (post.value(Term.AY3) ** 2 + post.se(Term.AY3) ** 2) / b_ay**2


def _priors(
    priors: Priors,
    g: float,
    b_ay: float,
    wheelbase_m: float,
    pull: "_Pull | None",
    softening2: float | None = None,
) -> dict[int, tuple[float, float]]:
    """Each term's prior (mean, standard deviation) in its coefficient's units; ratios to a_y's
    coefficient scaled with ``b_ay`` (−1/(g·C2n)) from the fit before.

    The softening's next term, a_y⁵'s, is b_ay·r·s²: r under its prior, s² the fit before's
    (``softening2``; before a fit, the softening prior's own scale).

    A slope's load transfer follows its pull: the grade s falling towards D pulls β by
    −b·g·s·sin(D − ψ) (sin ψ's and cos ψ's coefficients c_s = b·g·s·cos D, c_c = −b·g·s·sin D)
    and, its gravity along the heading moving the rear's load by L·s·cos(D − ψ) of it, changes the
    a_y coefficient by b·L·s·cos(D − ψ): a_y·cos ψ's coefficient is (L/g)·c_s and a_y·sin ψ's
    −(L/g)·c_c. Given the pull found (``pull``), the pair's prior is that, with L's own spread
    (N(L, L²)) times the pull's size; before a pull is found, the grade's prior times L."""
    k = abs(b_ay)
    grade = priors.slope_pct / 100.0
    s2 = priors.softening_per_mps2_2**2 if softening2 is None else softening2
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
        Term.AY5: (b_ay * priors.softening_ratio * s2, k * priors.softening_ratio_sd * s2),
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
