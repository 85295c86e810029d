"""Each candidate effect scored held out: fitted with the nuisances on one fold of manoeuvres,
its sideslip, yaw-rate and speed gaps measured on the other, against the calibrated model's."""

import itertools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from app.gap.calibration import NuisanceFit
from app.gap.candidates import Candidate, Param, mods_of
from app.gap.nominal_model import Mods, Simulated
from app.gap.problem import Fit, FitJob, Problem, best_start, fit, fit_all
from app.sim.effects import EffectName


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
    made by ``baselines_for``)."""
    held = tuple(pb.rows & (fold == k) for k in (0, 1))
    sims = [pb.simulate(mods_of(f.fields())) for f in baseline]
    parts = list(zip(sims, held, strict=True))
    noise = math.sqrt(sum(pb.gap_noise_deg(rows) ** 2 for rows in held) / 2)
    return Heldout(
        fold,
        held,
        baseline,
        pooled_gap(pb.rms_beta_deg, parts),
        pooled_gap(pb.rms_yaw_degps, parts),
        pooled_gap(pb.rms_speed_mps, parts),
        noise,
        math.degrees(pb.scale_r),
    )


def _baseline_jobs(
    pb: Problem, calibration: NuisanceFit, fold: np.ndarray, effect: EffectName
) -> list[FitJob]:
    """The calibrated model's fits on each training fold (with the nuisances ``effect`` is
    fitted beside)."""
    params, start = calibration.params_for(effect), calibration.start_for(effect)
    return [FitJob(params, pb.rows & (fold != k), (start,)) for k in (0, 1)]


def baselines_for(
    pb: Problem, calibration: NuisanceFit, fold: np.ndarray, effects: Sequence[EffectName], workers: int
) -> list[Heldout]:
    """``heldout`` for each of ``effects``, their fits made together in ``workers`` processes."""
    jobs = [job for effect in effects for job in _baseline_jobs(pb, calibration, fold, effect)]
    fits = fit_all(pb, jobs, workers)
    return [heldout(pb, fold, tuple(fits[2 * k : 2 * k + 2])) for k in range(len(effects))]


@dataclass(frozen=True)
class Variant:
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


def variants_of(
    calibration: NuisanceFit, ho: Heldout, candidate: Candidate, rival: Heldout | None
) -> list[Variant]:
    """The candidate with the nuisances; one a nuisance imitates also with that nuisance held."""
    if rival is None:
        return [Variant(candidate, calibration.params, calibration.values, ho)]
    effect = candidate.effect
    return [
        Variant(candidate, calibration.params_for(effect, rival_free=True), calibration.values, ho),
        Variant(candidate, calibration.params_for(effect), calibration.start_for(effect), rival, held=True),
    ]


def fit_every_sample(pb: Problem, variant: Variant) -> Fit:
    """The candidate fitted with the nuisances on every sample. The nuisances start both from the
    calibration and from the config's values (a large effect the calibration could not see may
    have bent it): the better fit wins."""
    params = variant.params
    effect_starts = list(itertools.product(*(p.starts for p in variant.candidate.params)))

    def from_(base: tuple[float, ...]) -> Fit:
        return fit(
            pb, params, pb.rows, start=best_start(pb, params, pb.rows, [(*base, *e) for e in effect_starts])
        )

    everything = from_(variant.calibrated)
    if everything.at_bound():  # a large effect may have bent the calibration: start again from the config
        nominal = tuple(p.nominal for p in variant.nuisance_params)
        everything = min((everything, from_(nominal)), key=lambda f: f.cost)
    return everything


def score_variant(pb: Problem, variant: Variant, everything: Fit, folds: tuple[Fit, ...]) -> Scored:
    """A variant's held-out gaps, against the calibrated model's."""
    ho = variant.ho
    return held_out_scores(pb, variant.candidate, everything, folds, ho.held, (ho.gap, ho.yaw, ho.speed))


def held_out_scores(
    pb: Problem,
    candidate: Candidate,
    everything: Fit,
    folds: Sequence[Fit],
    held: Sequence[np.ndarray],
    before: tuple[float, float, float],
) -> Scored:
    """A candidate's held-out gaps — each fold's samples (``held``) from its fit on the other —
    against the sideslip, yaw-rate and speed gaps ``before`` it."""
    sims = [pb.simulate(mods_of(f.fields())) for f in folds]
    parts = list(zip(sims, held, strict=True))
    gap, yaw, speed = before
    return Scored(
        candidate,
        everything,
        tuple(folds),
        gap,
        pooled_gap(pb.rms_beta_deg, parts),
        yaw,
        pooled_gap(pb.rms_yaw_degps, parts),
        speed,
        pooled_gap(pb.rms_speed_mps, parts),
    )


def pooled_gap(
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
        FitJob(params, pb.rows & (ho.fold != k), tuple((*best.folds[k].values, *s) for s in starts))
        for k in (0, 1)
    ]
    jobs.append(FitJob(params, pb.rows, tuple((*best.fit.values, *s) for s in starts)))
    *folds, everything = fit_all(pb, jobs, workers)
    return Added(other, tuple(folds), everything)
