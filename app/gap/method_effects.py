"""Effects the method itself measured on the drive, beside the bicycle model's held-out fits.

Three effects of the vocabulary act on the sideslip exactly as terms the C2n regression fits over
every steady sample, or as a difference between the axle C2n the drive measures and the tyre
figure the config gives; a held-out fit of the bicycle model sees them only through what its
calibrated C2n leaves, which takes most of them:

- **sensor_position_error**: the regression places d from the radii driven (β at the sensor moves
  by d·κ); its 95 % interval against the tape's value.
- **load_transfer_nonlinearity**: the regression's a_y³ term, s in α2 = a_y/(g·C2n)·(1 + s·a_y²);
  a crossing at a_y reads C2n/(1 + s·a_y²).
- **roll_steer** (and compliance steer): in steady state a rear steer k·a_y is a change of the
  axle's C2n, 1/C2n_axle = 1/C2n_tyre − g·k. The drive measures the axle (the headline); the
  config's ``[tyres] c2n_per_rad`` is the tyre's figure, as a rig gives it, known to
  ``c2n_tolerance_pct``. The two apart by more than both errors allow is a rear steer.

Each is present when its estimate stands ``Z_TEST`` standard errors from nothing (the test every
candidate of the vocabulary passes, the error shared among them), and matters by the same
tolerances as the held-out fits: what it does to C2n, and its size against its own tolerance.
"""

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np

from app.config import Config
from app.gap import effects
from app.gap.effects import Z_INTERVAL, Z_TEST, C2nShift
from app.gap.measured import Measured
from app.gap.result import C2nEffect, Effect
from app.results.headline import Method
from app.sim.effects import EffectName

HELDOUT_FIT = "held-out fit"
# effects whose own parameter the method measures on every steady sample, where the bicycle
# model's fit sees only what its calibrated C2n leaves: the method's entry is the effect's
DIRECT = frozenset({"sensor_position_error", "roll_steer"})
BY_REGRESSION = "the C2n regression"
BY_PAIRING = "the crossings' left/right pairing"
BY_RIG = "the headline against the tyre rig's C2n"


@dataclass(frozen=True)
class _Estimate:
    value: float
    se: float

    @property
    def z(self) -> float:
        return self.value / self.se if self.se > 0 else (math.inf if self.value else 0.0)

    def ci95(self, scale: float = 1.0, shift: float = 0.0) -> tuple[float, float]:
        lo, hi = self.value - Z_INTERVAL * self.se, self.value + Z_INTERVAL * self.se
        return (round(scale * lo + shift, 5), round(scale * hi + shift, 5))


def method_effects(m: Measured, config: Config) -> list[Effect]:
    """Every effect the regression and the headline measured, present or not (``matters`` and
    ``judged`` say which)."""
    found = [
        _sensor_position(m, config),
        _misalignment(m, config),
        _softening(m, config),
        _roll_steer(m, config),
    ]
    return [e for e in found if e is not None]


def with_method_effects(
    fitted: Sequence[Effect], measured: Sequence[Effect], lead_importance: float, config: Config
) -> list[Effect]:
    """The held-out fits' effects and the method's together, one entry per effect, those that
    matter first, the one that matters most leading. The method's measurement of d and of the
    axle's C2n is the effect's own parameter (``DIRECT``): it replaces the fit's always. An offset
    or a softening the held-out fit found to matter keeps the fit's entry (with its held-out gap);
    else the method's replaces it."""
    proven = {e.effect for e in fitted if e.matters} - DIRECT
    taken = [e for e in measured if e.effect not in proven]
    fits = [e for e in fitted if e.effect not in {t.effect for t in taken}]
    ranked = sorted((e for e in taken if e.matters), key=lambda e: -importance(e, config))
    ahead = [e for e in ranked if importance(e, config) > lead_importance]
    behind = [e for e in ranked if e not in ahead]
    return [
        *ahead,
        *(e for e in fits if e.matters),
        *behind,
        *(e for e in fits if not e.matters),
        *(e for e in taken if not e.matters),
    ]


def importance(e: Effect, config: Config) -> float:
    """What the effect does over what the config tolerates (≥ 1 matters), by the held-out fits' measure."""
    shift = C2nShift(e.c2n_effect_pct.crossing, e.c2n_effect_pct.headline)
    return effects.importance(shift, effects.own_size(e.effect, e.params, config), config)


def _judged(present: bool, z: float, matters: bool, what: str, config: Config) -> str:
    if not present:
        return f"not present: {z:+.1f} standard errors from nothing, within the drive's own spread"
    verb = "matters" if matters else "within tolerance"
    return f"{verb}: {what} (tolerance ±{config.gap.c2n_pct:g} % of C2n)"


def _effect(
    effect: EffectName,
    channel: str,
    params: dict[str, float],
    ci95: dict[str, tuple[float, float]],
    z: float,
    shift: C2nEffect,
    size_ratio: float,
    what: str,
    action: str,
    measured_by: str,
    config: Config,
) -> Effect:
    present = bool(abs(z) > Z_TEST)
    moved = max((abs(x) for x in (shift.crossing, shift.headline) if x is not None), default=0.0)
    matters = present and bool(moved >= config.gap.c2n_pct or size_ratio >= 1.0)
    judged = _judged(present, z, matters, what, config)
    return Effect(
        effect=effect,
        channel=channel,
        params=params,
        ci95=ci95,
        shrink_heldout=0.0,
        heldout_before=None,
        heldout_after=None,
        gain_sigmas=round(z, 2),
        c2n_effect_pct=shift,
        matters=matters,
        judged=judged,
        confounded_with=(),
        action=action if matters else f"within tolerance: nothing to do ({judged})",
        measured_by=measured_by,
    )


def _sensor_position(m: Measured, config: Config) -> Effect | None:
    """d as the regression placed it, against the tape's."""
    fit, tape = m.regression, config.vehicle.sensor_ahead_of_rear_axle_m
    if fit is None or fit.d.held or fit.d.held_tight or not tape:
        return None
    lo, hi = fit.d.ci95_m
    est = _Estimate(fit.d.m - tape, (hi - lo) / (2.0 * Z_INTERVAL))
    crossing = 100.0 * (fit.d.m / tape - 1.0)  # u0²/(g·tape) against u0²/(g·d)
    headline = 0.0 if m.summary.c2n_method == Method.REGRESSION else crossing
    shift = C2nEffect(round(crossing, 3), round(headline, 3))
    tolerance_m = config.calibration.d_tolerance_mm / 1000.0
    what = (
        f"C2n {crossing:+.2f} % on a single crossing, {headline:+.2f} % on the headline; "
        f"size {abs(est.value):.4g} m against the tape's tolerance of {tolerance_m:g} m"
    )
    action = (
        f"the sensor sits {fit.d.m:.3f} m [{lo:.3f}, {hi:.3f}] ahead of the rear axle, not the tape's "
        f"{tape:g} m: measure d again (single crossings, which rest on the tape's d, move "
        f"{crossing:+.1f} %; the regression places d itself)"
    )
    return _effect(
        "sensor_position_error",
        "sideslip",
        {"d_error_m": round(est.value, 5)},
        {"d_error_m": est.ci95()},
        est.z,
        shift,
        abs(est.value) / tolerance_m if tolerance_m > 0 else math.inf,
        what,
        action,
        BY_REGRESSION,
        config,
    )


def _misalignment(m: Measured, config: Config) -> Effect | None:
    """The crossings' left/right pairing: a constant sideslip offset in the sensor's frame moves a
    left and a right crossing opposite ways, C2n·(1 ± R·ψ/d) — a yawed head, or the tyres' ply
    steer (the car crabs; the drive cannot tell them apart once the steering's centre is
    calibrated). Measured where the method reads C2n, on the crossings themselves, with their
    scatter (the model's floor there included), not on every sample as the regression's ψ0."""
    paired, tape = m.summary.paired, config.vehicle.sensor_ahead_of_rear_axle_m
    if paired is None or paired.misalignment_deg is None or paired.misalignment_ci95_deg is None or not tape:
        return None
    lo, hi = paired.misalignment_ci95_deg
    if lo is None or hi is None:
        return None
    head = _Estimate(paired.misalignment_deg, (hi - lo) / (2.0 * Z_INTERVAL))
    radii = [abs(c.radius_m) for c in m.crossings if math.isfinite(c.radius_m) and c.radius_m]
    crossing = 100.0 * math.radians(abs(head.value)) * float(np.mean(radii)) / tape if radii else None
    shift = C2nEffect(None if crossing is None else round(crossing, 3), 0.0)
    tolerance = config.gap.sideslip_deg
    side = "left" if head.value > 0 else "right"
    what = (
        f"C2n ±{crossing:.2f} % on a single crossing (left and right opposite), 0 on the headline; "
        if crossing is not None
        else ""
    ) + f"size {abs(head.value):.4g}° against the sensor's {tolerance:g}°"
    action = (
        f"the sideslip reads {abs(head.value):.3f}° off in the sensor's frame (a head yawed to the {side}, "
        "or the tyres' ply steer): re-align the head if it is the head, or keep it and let left/right "
        "pairing and the regression's ψ0 cancel it"
        + (f" (single crossings move ±{crossing:.1f} %, the headline 0)" if crossing is not None else "")
    )
    found = _effect(
        "sensor_yaw_misalignment",
        "sideslip",
        {"misalignment_deg": round(head.value, 5)},
        {"misalignment_deg": head.ci95()},
        head.z,
        shift,
        abs(head.value) / tolerance if tolerance > 0 else math.inf,
        what,
        action,
        BY_PAIRING,
        config,
    )
    return replace(found, confounded_with=("tyre_ply_steer",))


def _crossing_ay(m: Measured) -> Sequence[float]:
    return [abs(c.ay_mps2) for c in m.crossings if math.isfinite(c.ay_mps2)]


def _softening(m: Measured, config: Config) -> Effect | None:
    """The regression's a_y³ term: the tyres' (and the load transfer's) softening with slip."""
    fit = m.regression
    softening = fit.softening if fit is not None else None
    if fit is None or softening is None or not softening.se_per_mps2_2:
        return None
    s = _Estimate(softening.per_mps2_2, softening.se_per_mps2_2)
    ay = np.asarray(_crossing_ay(m))
    crossing = float(np.mean(-100.0 * s.value * ay**2 / (1.0 + s.value * ay**2))) if len(ay) else None
    chosen = fit.models.chosen == "softening" and m.summary.c2n_method == Method.REGRESSION
    headline = 0.0 if chosen else crossing
    shift = C2nEffect(
        None if crossing is None else round(crossing, 3), None if headline is None else round(headline, 3)
    )
    at_3 = 100.0 * 9.0  # % of C2n at a_y = 3 m/s² per unit of s
    # what it does to the linear model's sideslip where the drive turned hardest (the 95th
    # percentile of |a_y| over the drive, beyond the steady gate's limit too: the model is driven
    # there), a_y/(g·C2n)·s·a_y², against the sensor's accuracy
    ay_all = np.abs(m.ay[np.isfinite(m.ay)])
    top = float(np.percentile(ay_all, 95)) if len(ay_all) else 0.0
    g_c2n = config.vehicle.gravity_mps2 * fit.c2n
    model_deg = math.degrees(top**3 * abs(s.value) / g_c2n) if g_c2n > 0 else 0.0
    where = f"crossings at |a_y| {np.min(ay):.1f}–{np.max(ay):.1f} m/s²" if len(ay) else "crossings"
    what = (
        f"C2n {crossing:+.2f} % on a single crossing ({where}), {headline:+.2f} % on the headline; "
        if crossing is not None and headline is not None
        else ""
    ) + (
        f"the linear model's sideslip {model_deg:.3f}° off at |a_y| {top:.1f} m/s² against the "
        f"sensor's {config.gap.sideslip_deg:g}°"
    )
    action = (
        f"the rear axle softens with lateral acceleration ({s.value * at_3:.1f} % of C2n at 3 m/s², "
        f"t = {s.z:.1f}): {where} read {crossing:+.1f} %; c2n reports the linear value at zero "
        "a_y — sweep at two radii up to 4 m/s² to keep it apart from C2n"
        if crossing is not None
        else f"the rear axle softens with lateral acceleration ({s.value * at_3:.1f} % of C2n at 3 m/s², "
        f"t = {s.z:.1f}): a linear model's sideslip is {model_deg:.2f}° off at {top:.1f} m/s² — model "
        "the softening, or keep to the linear range"
    )
    return _effect(
        "load_transfer_nonlinearity",
        "sideslip",
        {"rear_softening_pct_at_3mps2": round(s.value * at_3, 4)},
        {"rear_softening_pct_at_3mps2": s.ci95(at_3)},
        s.z,
        shift,
        model_deg / config.gap.sideslip_deg,
        what,
        action,
        BY_REGRESSION,
        config,
    )


def _roll_steer(m: Measured, config: Config) -> Effect | None:
    """The axle's C2n the drive measured against the tyre's the config gives: their difference in
    1/C2n over g is a rear steer per lateral acceleration (with the turn: > 0)."""
    rig, tolerance = config.tyres.c2n_per_rad, config.tyres.c2n_tolerance_pct
    axle, ci = m.summary.c2n, m.summary.c2n_ci95
    g = config.vehicle.gravity_mps2
    low, high = ci if ci is not None else (None, None)
    if rig is None or axle is None or low is None or high is None or axle <= 0:
        return None
    se_axle = (high - low) / (2.0 * Z_INTERVAL) / axle**2
    se_rig = tolerance / 100.0 / Z_INTERVAL / rig  # (x % of rig) / rig²
    k = _Estimate((1.0 / rig - 1.0 / axle) / g, math.hypot(se_axle, se_rig) / g)
    moved = 100.0 * (axle / rig - 1.0)
    shift = C2nEffect(round(moved, 3), round(moved, 3))
    deg = 180.0 / math.pi
    side = "into" if k.value > 0 else "out of"
    what = (
        f"the axle's C2n {axle:.3f} is {moved:+.2f} % from the tyre's {rig:g} "
        f"(known to ±{tolerance:g} %): the model's C2n must be the axle's"
    )
    action = (
        f"the rear axle's C2n on the road ({axle:.2f}) is {moved:+.1f} % from the tyre's ({rig:g}, ±"
        f"{tolerance:g} %): the rear steers {abs(k.value) * deg:.3f}° per m/s² {side} the turn with roll "
        "or compliance — what c2n measures is the axle's, so model the car with it; the axle's "
        "kinematics-and-compliance data, or step steers (roll lags a_y), tell roll steer from compliance "
        "steer, and a tyre figure from another rig from both"
    )
    return _effect(
        "roll_steer",
        "c2n",
        {"rear_steer_deg_per_mps2": round(k.value * deg, 5)},
        {"rear_steer_deg_per_mps2": k.ci95(deg)},
        k.z,
        shift,
        0.0,
        what,
        action,
        BY_RIG,
        config,
    )
