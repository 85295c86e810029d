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

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from threadpoolctl import threadpool_limits

from app.config import Config, DetectorSettings
from app.errors import NoResultError
from app.gap.calibration import NuisanceFit, calibrate, ci95_of
from app.gap.candidates import (
    CANDIDATES,
    HIDDEN_BY_CALIBRATION,
    HIDDEN_BY_RIVAL,
    NUISANCE_TWINS,
    RIVAL_NUISANCE,
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
from app.gap.heldout import (
    Added,
    Heldout,
    Scored,
    add_to,
    baselines_for,
    fit_every_sample,
    held_out_scores,
    pooled_gap,
    score_variant,
    variants_of,
)
from app.gap.measured import Measured
from app.gap.method_effects import DIRECT, HELDOUT_FIT, method_effects, with_method_effects
from app.gap.nominal_model import Mods, Simulated
from app.gap.problem import (
    LINEAR_AY_MPS2,
    MIN_USABLE_S,
    SPEED_WEIGHT,
    YAW_WEIGHT,
    Fit,
    Problem,
    fit,
    folds,
    manoeuvres,
    problem,
)
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
from app.sim.effects import EffectName


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
    variants = [v for c in CANDIDATES for v in variants_of(calibration, ho, c, rivals.get(c.effect))]

    def whole(index: int) -> tuple[tuple[float, ...], float, tuple[tuple[float, float], ...]]:
        variant = variants[index]
        done = fit_every_sample(pb, variant)
        return done.values, done.cost, ci95_of(pb, done)[-len(variant.candidate.params) :]

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
        scored = score_variant(pb, variant, everything[k], folds)
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
        s = lead.scored
        before = (s.gap_after, s.yaw_after, s.speed_after)  # judged on what the finding left
        scored = held_out_scores(pb, j.scored.candidate, added.fit, added.folds, ho.held, before)
        ci95 = ci95_of(pb, added.fit)[-len(j.scored.candidate.params) :]
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
    _refuse_without_crossings(pb, calibration, config.detector.speed_min_mps)
    calibrated = pb.simulate(calibration.mods())
    ids = manoeuvres(m)
    fold = folds(m, ids)
    names = {p.name for p in calibration.params}
    imitated = {rival: effect for effect, rival in RIVAL_NUISANCE.items() if rival in names}
    ho, *rival_ho = baselines_for(pb, calibration, fold, ["none", *imitated.values()], workers)
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


def _refuse_without_crossings(pb: Problem, calibration: NuisanceFit, speed_min_mps: float) -> None:
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
        if (
            speed_min_mps > DetectorSettings.speed_min_mps and u0 < speed_min_mps
        ):  # the config's, not the drive's
            raise NoResultError(
                f"no steady cornering near the sideslip's sign change: u0 ≈ {u0:.1f} m/s lies under "
                f"[detector] speed_min_mps = {speed_min_mps:g} m/s in the config — lower speed_min_mps "
                f"(default {DetectorSettings.speed_min_mps:g}; in m/s, not km/h)"
            )
        raise NoResultError(
            f"no steady cornering near the sideslip's sign change ({seconds[0]:.0f} s left, "
            f"{seconds[1]:.0f} s right within ±50 % of u0² = g·d·C2n, u0 ≈ {u0:.1f} m/s, "
            f"|a_y| ≤ {LINEAR_AY_MPS2:g} m/s²): what an effect does to C2n cannot be judged — drive "
            "constant-radius sweeps through u0, left and right"
        )


def _shrink_with(pb: Problem, ho: Heldout, added: Added) -> float:
    """The held-out sideslip gap's shrink with the findings fitted together."""
    sims = [pb.simulate(mods_of(f.fields())) for f in added.folds]
    gap = pooled_gap(pb.rms_beta_deg, list(zip(sims, ho.held, strict=True)))
    return 1.0 - gap / ho.gap if ho.gap > 0 else 0.0


def _calibrated(pb: Problem, calibration: NuisanceFit, beside: Fit) -> dict[str, Calibrated]:
    """Each nuisance as fitted beside the effects named, with its 95 % interval there; one the
    drive did not show keeps the calibration's interval (which covers its nominal value), one held
    beside the effect it imitates has none."""
    intervals = ci95_of(pb, beside) if beside is not calibration.fit else calibration.ci95
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
