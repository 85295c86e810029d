"""One model for every steady sample: each nuisance term enters with a Gaussian prior, none is chosen.

The cascade (``cascade.py``) tries a term, keeps it where a test passes and then reports the
chosen model's interval as if it had been fixed in advance. Here every term the physics allows is
in the model at once, each with a prior from physics or a data sheet (``Priors``); the posterior is
closed-form (a ridge regression whose penalties are the priors' precisions), so a term the drive
cannot separate from C2n widens C2n's interval by as much as its prior allows, and
``held_open_by`` names the term that contributes most to that width.

The noise: the samples' variance σ² is estimated from the residuals with the fit's effective
degrees of freedom (n − tr(XᵀX·A⁻¹)), and inflated by the samples' autocorrelation (the Newey–West
long-run variance of the block scores against σ²·XᵀX). The covariance is the sandwich
A⁻¹(M + σ⁴Λ)A⁻¹ — the prior counted as pseudo-observations of the coefficients, the data's scores
M as in the least-squares fit — so it is the textbook posterior σ²A⁻¹ where the noise is white.

d's prior is two: the tape's, and a wide one for a tape that is wrong (``wide_share``). The fit is
made under each and the two weighed by Bayes' rule on their evidence, which for one coefficient's
prior is the density of the data's own estimate of it under each prior (the other terms' priors
are the same in both, so the rest of the evidence cancels); C2n and d are then the two posteriors'
mixture (``mixture``): its median, and its central interval.

Several priors are on a ratio to a_y's coefficient (the slope's pull is g_y/(g·C2n), the softening
s·a_y² multiplies it): they are scaled with a_y's coefficient from the fit before, and the fit is
repeated until it settles (three passes take it to 1e-6 on the benches' drives; the wide d
prior's fit, started from the tape's, mostly one). A slope's load transfer is its pull turned by
90° and scaled by L/g (one slope makes both): its prior follows the pull the pass before found, so
a level pad leaves it no room to take a heading-borne misfit (CommonRoad's sweeps read +0.45 %
median through it before, −0.18 % after).
"""

import math
from dataclasses import dataclass, field
from enum import IntEnum

import numpy as np


def well_conditioned_inverse(a: np.ndarray, equilibrated: bool = False) -> np.ndarray | None:
    """``a``'s inverse, or None where ``a`` is singular or too ill-conditioned for its inverse to
    carry digits (condition number over 1e14: fewer than two of a double's sixteen left). The
    condition number in the 1-norm, ‖a‖₁·‖a⁻¹‖₁, from the inverse at hand (the 2-norm's, an SVD,
    cost a third of the marginal fit; the two differ by at most the matrix's size).
    ``equilibrated`` (a symmetric ``a`` with a positive diagonal): inverted and judged with its
    rows and columns scaled to a unit diagonal, so that a column's units (a_y⁵ reaches 10³ where
    κ is 10⁻²) set no condition a rescaling would remove — the marginal posterior's, whose priors
    keep every column's scale in hand; the cascade's least squares keep the raw test, which also
    turns away a broken signal's column of 10⁹."""
    outer = None
    scaled = a
    if equilibrated:
        diagonal = a.diagonal()
        if not (diagonal.min() > 0.0 and diagonal.max() < math.inf):  # NaN fails both
            return None
        scale = 1.0 / np.sqrt(diagonal)
        outer = scale[:, None] * scale
        scaled = a * outer
    try:
        inverse = np.linalg.inv(scaled)
    except np.linalg.LinAlgError:
        return None
    # a NaN or an infinity in either matrix makes the product NaN or infinite, which fails too
    if not np.abs(scaled).sum(axis=0).max() * np.abs(inverse).sum(axis=0).max() <= 1e14:
        return None
    return inverse if outer is None else inverse * outer


class Term(IntEnum):
    """The regression's columns by name (their order in ``SampleRegression``'s block statistics)."""

    PSI0 = 0  # 1: the head's yaw on the car
    D = 1  # κ
    AY = 2  # a_y = u·r: −1/(g·C2n)
    AY3 = 3  # a_y³: the tyres' softening
    SIN = 4  # sin ψ, cos ψ: a slope's pull at the heading ψ
    COS = 5
    AY_SIN = 6  # a_y·sin ψ, a_y·cos ψ: the slope's load transfer
    AY_COS = 7
    R_DOT = 8  # ṙ: the yaw inertia's share of the rear force
    AY_U_DOT = 9  # a_y·u̇: braking's load transfer
    TURN = 10  # sign(κ): a force that follows the turn's direction (a camber step)
    U = 11  # u and 1/u: a yaw-rate bias combines them
    INV_U = 12
    K2_AY = 13  # κ²·a_y: the axle's two wheels on a tight turn
    AY5 = 14  # a_y⁵: the softening's next term (its size follows a_y³'s)


@dataclass(frozen=True)
class Posterior:
    """The coefficients' posterior mean and covariance over ``terms`` (indices into the statistics'
    columns), the noise variance, the degrees of freedom left, and the matrix that made the mean
    (XᵀX + σ²·Λ)⁻¹, which a term left out is taken through (``left_out``)."""

    terms: list[int]
    coef: np.ndarray
    cov: np.ndarray
    sigma2: float
    dof: float
    inverse: np.ndarray | None = field(default=None, repr=False)

    def index(self, term: int) -> int:
        return self.terms.index(term)

    def value(self, term: int) -> float:
        return float(self.coef[self.terms.index(term)])

    def se(self, term: int) -> float:
        i = self.terms.index(term)
        return math.sqrt(max(float(self.cov[i, i]), 0.0))

    def held_open_by(self, term: int) -> tuple[int, float] | None:
        """The term whose uncertainty contributes most to ``term``'s variance: how much of it would
        go were that term known exactly (cov²/var), and that share of the variance."""
        i = self.terms.index(term)
        total = float(self.cov[i, i])
        best: tuple[int, float] | None = None
        for j, other in enumerate(self.terms):
            if j == i or self.cov[j, j] <= 0 or total <= 0:
                continue
            share = float(self.cov[i, j]) ** 2 / float(self.cov[j, j]) / total
            if best is None or share > best[1]:
                best = (other, share)
        return best


@dataclass(frozen=True)
class Blocks:
    """The samples' statistics by block — XᵀX (blocks × k × k), Xᵀy (blocks × k), yᵀy (blocks),
    each block's run — the samples' count, and XᵀX summed over the blocks."""

    xtx: np.ndarray
    xty: np.ndarray
    yty: np.ndarray
    run: np.ndarray
    n: int
    total: np.ndarray = field(init=False, repr=False)
    total_xty: np.ndarray = field(init=False, repr=False)
    total_yty: float = field(init=False, repr=False)
    neighbours: np.ndarray = field(init=False, repr=False)  # 1 where a block follows one in its run

    def __post_init__(self) -> None:
        object.__setattr__(self, "total", self.xtx.sum(axis=0))
        object.__setattr__(self, "total_xty", self.xty.sum(axis=0))
        object.__setattr__(self, "total_yty", float(self.yty.sum()))
        object.__setattr__(self, "neighbours", (self.run[1:] == self.run[:-1]).astype(float)[:, None])

    def times(self, coef: np.ndarray) -> np.ndarray:
        """Each block's XᵀX times ``coef`` (blocks × k): one product over the stacked blocks."""
        blocks, k, _ = self.xtx.shape
        return np.asarray((self.xtx.reshape(blocks * k, k) @ coef).reshape(blocks, k))

    def newey_west(self, scores: np.ndarray) -> np.ndarray:
        """Σ sᵀs over blocks with Bartlett weights 1 and ½: a block and its neighbour in the same run."""
        cross = (scores[1:] * self.neighbours).T @ scores[:-1]
        return np.asarray(scores.T @ scores + 0.5 * (cross + cross.T))

    def columns(self, terms: list[int]) -> np.ndarray:
        """The weights (k × terms) that take ``terms`` of the statistics' columns as they are."""
        weights = np.zeros((self.xtx.shape[1], len(terms)))
        weights[terms, range(len(terms))] = 1.0
        return weights


def posterior(
    blocks: Blocks,
    weights: np.ndarray,
    terms: list[int],
    prior_mean: np.ndarray,
    prior_sd: np.ndarray,
    sigma2: float | None = None,
) -> Posterior | None:
    """The Gaussian-prior regression on the terms ``weights`` makes of the statistics' columns (k ×
    terms: a column each, or a combination of them), named ``terms``; ``prior_sd`` inf for a flat
    prior. The noise variance from ``sigma2`` (a fit before's; without, y's mean square, an upper
    bound), stepped until it settles. None where the posterior is improper."""
    n = blocks.n
    data, block_xty = weights.T @ blocks.total @ weights, blocks.xty @ weights
    rhs, yy = blocks.total_xty @ weights, blocks.total_yty
    precision = _precision(prior_sd)
    sigma2 = max(yy / n, 1e-30) if sigma2 is None else sigma2
    for _ in range(3):  # σ² from the residuals, then its autocorrelation, then once more
        found = well_conditioned_inverse(data + sigma2 * np.diag(precision), equilibrated=True)
        if found is None:
            return None
        inverse = found
        coef, used = inverse @ (rhs + sigma2 * precision * prior_mean), sigma2
        residual = yy - 2.0 * coef @ rhs + coef @ data @ coef
        # tr(AB) of symmetric matrices: Σ A∘B, without the product
        leverage = float(np.vdot(data, inverse))
        dof = max(n - leverage, 1.0)
        white = max(residual / dof, 1e-30)
        meat = blocks.newey_west(block_xty - blocks.times(weights @ coef) @ weights)  # of the scores
        inflation = float(np.vdot(inverse, meat)) / (white * leverage)
        sigma2 = white * max(inflation, 1.0)
        if abs(sigma2 - used) <= _SIGMA_SETTLED * used:  # a fit before's σ², or settled
            break
    cov = inverse @ (meat * n / dof + used * used * np.diag(precision)) @ inverse
    return Posterior(terms, coef, cov, used, dof, inverse)


_SIGMA_SETTLED = 1e-3  # σ² settled: the standard errors move by 0.05 % of themselves


def _precision(prior_sd: np.ndarray) -> np.ndarray:
    """Each prior's precision, 0 for a flat one (``prior_sd`` inf)."""
    finite = np.isfinite(prior_sd)
    return np.where(finite, 1.0 / np.square(np.where(finite, prior_sd, 1.0)), 0.0)


def left_out(blocks: Blocks, weights: np.ndarray, post: Posterior, column: int) -> np.ndarray | None:
    """How each coefficient of ``post`` (a fit on the terms ``weights`` makes) moves per unit of
    a statistics' ``column`` left out of it: the posterior mean's matrix applied to that column's
    cross-products. None where it cannot be told."""
    if post.inverse is None:
        return None
    return np.asarray(post.inverse @ (weights.T @ blocks.total[:, column]))


def data_alone(post: Posterior, term: int, prior_mean: float, prior_sd: float) -> tuple[float, float] | None:
    """What the data alone say of ``term`` under a Gaussian prior: the posterior's precision less
    the prior's, and the mean that leaves — (mean, variance), or None where the prior holds all of
    it (one speed for d)."""
    p = post.se(term) ** 2
    if p <= 0.0:
        return post.value(term), 0.0
    info = 1.0 / p - 1.0 / prior_sd**2
    if info <= 0.0:
        return None
    v = 1.0 / info
    return v * (post.value(term) / p - prior_mean / prior_sd**2), v


def wide_share(wide: Posterior, tape_m: float, tape_sd: float, wide_sd: float, share: float) -> float:
    """The wide d prior's posterior weight: its prior ``share`` times the evidence ratio, the data's
    own d (found from the wide posterior: ``data_alone``) under N(tape, v + σ²) for each prior's σ.
    Where the data hardly place d (one speed) the ratio is 1."""
    if share <= 0.0:
        return 0.0
    if share >= 1.0:
        return 1.0
    own = data_alone(wide, Term.D, tape_m, wide_sd)
    if own is None:
        return share
    x, v = own[0] - tape_m, own[1]
    a, b = v + tape_sd**2, v + wide_sd**2
    log_ratio = 0.5 * math.log(a / b) + 0.5 * x * x * (1.0 / a - 1.0 / b)
    log_odds = log_ratio + math.log(share / (1.0 - share))
    return 1.0 / (1.0 + math.exp(-log_odds)) if log_odds > -700 else 0.0


def mixture(
    means: list[float], ses: list[float], weights: list[float], dof: float, level: float
) -> tuple[float, tuple[float, float]]:
    """A mixture of Student-t's (``dof``) by ``weights``: its median and its central ``level``
    interval (one component: its mean ± t·se). The median, not the mean: a far component of small
    weight (d's wide prior at one speed) moves the mean by its weight times its distance, the
    median hardly."""
    from scipy.special import stdtrit

    w = np.asarray(weights, dtype=float) / sum(weights)
    if len(means) == 1 or w.max() == 1.0:
        i = int(w.argmax())
        q = float(stdtrit(dof, 0.5 + level / 2.0))
        return means[i], (means[i] - q * ses[i], means[i] + q * ses[i])
    tail = (1.0 - level) / 2.0
    low, median, high = mixture_quantiles(means, ses, w, dof, np.array([tail, 0.5, 1.0 - tail]))
    return median, (low, high)


def reciprocal_mixture(
    values: list[float], ses: list[float], weights: list[float], dof: float, level: float
) -> tuple[float, tuple[float, float]]:
    """``mixture`` of values that are reciprocals of the fit's coefficient (C2n = −1/(g·b)): the
    mixture is the coefficients' own, t's on 1/value with 1/value's errors se/value², and its
    median and interval are mapped back through 1/x, which keeps quantiles as they are. Exact
    where value ± t·se, the delta method's, is not: a 12-second drive's C2n of 12.5 ± 7.0 read
    [5.5, 19.5] where its coefficient's own interval is [8.0, 28.5]. Where the coefficient's
    interval reaches zero, C2n has no upper end (inf). Values not all positive (a role the wrong
    way round, refused by its caller's caller) are mixed as they are."""
    if min(values) <= 0.0:
        return mixture(values, ses, weights, dof, level)
    inverse = [1.0 / v for v in values]
    inverse_ses = [se / (v * v) for se, v in zip(ses, values, strict=True)]
    middle, (low, high) = mixture(inverse, inverse_ses, weights, dof, level)
    return 1.0 / middle, (1.0 / high, 1.0 / low if low > 0.0 else math.inf)


def mixture_quantiles(
    means: list[float], ses: list[float], weights: np.ndarray, dof: float, p: np.ndarray
) -> np.ndarray:
    """The quantiles ``p`` of a mixture of Student-t's: Newton's steps on its CDF from the heaviest
    component's own quantile, each kept inside a bracket it narrows, bisection where a step would
    leave it (Brent's method took about 30 of the CDF's values a quantile; this about 3)."""
    from scipy.special import stdtr, stdtrit

    m, s, w = np.asarray(means, dtype=float), np.asarray(ses, dtype=float), np.asarray(weights)
    # each quantile lies between the components' own (there every F_i is at most p, here at least),
    # and strictly inside them widened by the largest σ, where rounding cannot turn a sign
    own = m + s * stdtrit(dof, p)[:, None]
    lows, highs = own.min(axis=1) - s.max(), own.max(axis=1) + s.max()
    density = math.exp(math.lgamma((dof + 1) / 2) - math.lgamma(dof / 2)) / math.sqrt(dof * math.pi)
    components = [(float(mi), float(si), float(wi)) for mi, si, wi in zip(m, s, w, strict=True) if wi > 0]
    heaviest = int(w.argmax())

    def cdf_and_density(x: float) -> tuple[float, float]:
        value = slope = 0.0
        for mean, se, weight in components:
            if se <= 0.0:
                value += weight * (x >= mean)
                continue
            z = (x - mean) / se
            value += weight * float(stdtr(dof, z))
            slope += weight / se * density * (1.0 + z * z / dof) ** (-(dof + 1) / 2)
        return value, slope

    found = []
    for target, x, low, high in zip(p, own[:, heaviest], lows, highs, strict=True):
        tolerance = 1e-12 * (abs(low) + abs(high) + float(s.max()))
        for _ in range(200):  # Newton's steps converge in a few; a bisection halves the bracket
            value, slope = cdf_and_density(x)
            below = value - target
            if below == 0.0 or high - low <= tolerance:
                break
            step = x - below / slope if slope > 0.0 else math.nan
            if abs(step - x) <= tolerance:
                x = step
                break
            low, high = (x, high) if below < 0.0 else (low, x)
            x = step if low < step < high else 0.5 * (low + high)
        found.append(float(x))
    return np.array(found)
