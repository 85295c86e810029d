"""The least squares both of the regression's fits share, on its blocks' statistics: a fit on a
subset of the terms with its Newey–West covariance (``solve``), the drives' own columns (``per_log``),
how much of a term the others leave (``term_spread``), a term appended as a combination of others
(``combined``), and what is read off a fit — C2n's error, a Wald test, a slope, a turn force, a
yaw rate's bias."""

import math
from dataclasses import dataclass
from typing import NamedTuple, Protocol

import numpy as np

from app.results.fit_groups import FitSamples
from app.results.marginal import Term, well_conditioned_inverse

K = len(Term)  # the columns each block keeps (``SampleRegression``), in ``Term``'s order
TERM_NAMES = {t.value: t.name.lower() for t in Term}  # the result file's names of the terms
SLOPE_SPREAD = 0.3  # the headings' spread (of sin ψ, cos ψ beside the other terms; full circles 0.5)
# beyond which a slope's two terms are fitted (the cascade), or reported (the marginal fit)
SLOPE_WALD = -2.0 * math.log(0.05)  # χ²(2) at 95 %: a slope found, its load transfer fitted too
WIDE_SPEEDS = 1.2  # the fastest sample this many times the slowest: speeds apart, not one speed
TURN_SPREAD = 0.02  # of sign(κ) beside the other terms beyond which it is tried: one radius each way
# leaves 0; a small pad, every sample at a_y ≥ 1.2 m/s², 0.024 (at 0.05 it was not tried there, and
# CommonRoad's car read 8–21 % high, the truth outside every interval)


class Statistics(NamedTuple):
    """The samples' statistics by block: XᵀX, Xᵀy, yᵀy, each block's run and drive."""

    xtx: np.ndarray
    xty: np.ndarray
    yty: np.ndarray
    run: np.ndarray
    log: np.ndarray


class Samples(Protocol):
    """What a fit reads of the samples beside their statistics (``SampleRegression``'s)."""

    g: float
    wheelbase_m: float
    d_tape_m: float | None  # the sensor's d as measured with a tape
    d_tape_se_m: float
    transient: bool  # quasi-steady samples
    scale_se: float  # C2n's relative error from the sensors' scales
    softening_t: float  # the cascade's bar for the a_y³ term

    @property
    def n_samples(self) -> int: ...

    @property
    def speeds_apart(self) -> bool: ...

    @property
    def mostly_tight(self) -> bool: ...

    def fit_samples(
        self, blocks: int, logs: int, transient_terms: bool, tight_terms: tuple[str, ...] = ()
    ) -> FitSamples: ...


@dataclass(frozen=True)
class Solution:
    terms: list[int]
    coef: np.ndarray
    cov: np.ndarray


def solve(xtx: np.ndarray, xty: np.ndarray, run: np.ndarray, terms: list[int], n: int) -> Solution | None:
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
    return Solution(terms, coef, cov)


def term_se(fit: Solution, term: int) -> float:
    """A coefficient's standard error."""
    i = fit.terms.index(term)
    return math.sqrt(max(float(fit.cov[i, i]), 0.0))


def c2n_se_of(fit: Solution, g: float) -> float:
    """C2n's standard error: the delta method on C2n = −1/(g·b_ay)."""
    return term_se(fit, Term.AY) / (g * float(fit.coef[fit.terms.index(Term.AY)]) ** 2)


def wald(fit: Solution, terms: list[int]) -> float:
    """The Wald statistic of ``terms`` being zero together (χ² with len(terms) degrees)."""
    where = [fit.terms.index(t) for t in terms]
    coef = fit.coef[where]
    try:
        return float(coef @ np.linalg.solve(fit.cov[np.ix_(where, where)], coef))
    except np.linalg.LinAlgError:
        return 0.0


def term_spread(total: np.ndarray, base: list[int], extra: list[int], n: int) -> float:
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


def per_log(
    xtx: np.ndarray, xty: np.ndarray, log: np.ndarray
) -> tuple[np.ndarray, np.ndarray, list[int], list[tuple[int, int]]]:
    """The blocks' statistics with the intercept and the speed columns u, 1/u split by drive: drive
    k ≥ 1 has them as terms ``K + 3·(k − 1)`` on (the first drive's stay PSI0, U and INV_U).
    Returns them, the ψ0 terms and the speed columns' pairs."""
    logs = np.unique(log)
    split = (Term.PSI0, Term.U, Term.INV_U)
    size = K + len(split) * (len(logs) - 1)
    wide_xtx = np.zeros((len(xtx), size, size))
    wide_xty = np.zeros((len(xty), size))
    offsets: list[int] = [Term.PSI0]
    speeds: list[tuple[int, int]] = [(Term.U, Term.INV_U)]
    for k, drive in enumerate(logs):
        columns = np.arange(K)
        if k:
            first = K + len(split) * (k - 1)
            columns[list(split)] = range(first, first + len(split))
            offsets.append(first)
            speeds.append((first + 1, first + 2))
        where = np.flatnonzero(log == drive)
        wide_xtx[np.ix_(where, columns, columns)] = xtx[where]
        wide_xty[np.ix_(where, columns)] = xty[where]
    return wide_xtx, wide_xty, offsets, speeds


def tilt_of(fit: Solution) -> tuple[float, float, float, float] | None:
    """The slope's four coefficients (sin ψ, cos ψ, a_y·sin ψ, a_y·cos ψ), where they were fitted."""
    if 4 not in fit.terms:
        return None
    a, b, c, d = (float(fit.coef[fit.terms.index(k)]) for k in (Term.SIN, Term.COS, Term.AY_SIN, Term.AY_COS))
    return (a, b, c, d)


def turn_share(fit: Solution, g: float) -> float:
    """The force that follows the turn, as a share of the rear axle's weight: the sideslip step
    δ·sign(κ) it makes is f/C2n, so f = δ·C2n (+ towards the turn's inside)."""
    c2n = -1.0 / (g * float(fit.coef[fit.terms.index(Term.AY)]))
    return float(fit.coef[fit.terms.index(Term.TURN)]) * c2n


def turn_ci(fit: Solution, g: float, q: float) -> tuple[float, float]:
    """Its 95 % interval in %, from the step's own (C2n's share of the error is second order)."""
    c2n = -1.0 / (g * float(fit.coef[fit.terms.index(Term.AY)]))
    half = q * term_se(fit, Term.TURN) * abs(c2n) * 100.0
    centre = 100.0 * turn_share(fit, g)
    return (centre - half, centre + half)


def slope_of(fit: Solution, c2n: float, q: float) -> tuple[float, tuple[float, float], float]:
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


def bias_of(fit: Solution, term: int, q: float) -> tuple[float, tuple[float, float]]:
    """The yaw rate's bias in °/s with its 95 % interval: the term's coefficient is b itself."""
    i = fit.terms.index(term)
    value, se = float(fit.coef[i]), math.sqrt(max(float(fit.cov[i, i]), 0.0))
    return math.degrees(value), (math.degrees(value - q * se), math.degrees(value + q * se))


def combination_weights(k: int, combinations: list[dict[int, float]]) -> np.ndarray:
    """The weights (k × combinations) that make each combination (Σ weight·term) of k columns."""
    w = np.zeros((k, len(combinations)))
    for j, combination in enumerate(combinations):
        for term, weight in combination.items():
            w[term, j] = weight
    return w


def combined(
    xtx: np.ndarray, xty: np.ndarray, combinations: list[dict[int, float]]
) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """The blocks' statistics with a term appended for each combination (Σ weight·term); returns
    their indices too."""
    k, extra = xtx.shape[1], len(combinations)
    w = combination_weights(k, combinations)
    cross = xtx @ w  # (blocks, k, extra)
    wide_xtx = np.zeros((len(xtx), k + extra, k + extra))
    wide_xtx[:, :k, :k] = xtx
    wide_xtx[:, :k, k:] = cross
    wide_xtx[:, k:, :k] = cross.transpose(0, 2, 1)
    wide_xtx[:, k:, k:] = w.T @ cross
    return wide_xtx, np.concatenate([xty, xty @ w], axis=1), list(range(k, k + extra))
