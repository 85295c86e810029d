"""Why a run gives no C2n, and the checks a result must pass first: pure functions of what the
run found. ``snapshot.py`` asks them and keeps their outcomes; the sinks read those.

- ``resting_fit``: which regression the result rests on (the steady samples', or the quasi-steady's).
- ``sign_problem``: a role the wrong way round, or a C2n that is not positive.
- ``drives_disagree``: drives pooled that do not measure one C2n.
- ``unbounded_fit``: a positive C2n whose interval has no upper end.
- ``standing_headline``: the headline, unless one of these refuses it.
- ``refusal``: why there is no C2n at all.
- ``speed_min_problem``: the config's least speed above all the drive's cornering.
- ``replay_hint``: optical frames far faster than a sensor sends them.
"""

import math
from collections.abc import Sequence

from app.config import DetectorSettings
from app.detect.quasi_steady import GRIP_MAX_MPS2, Cornering
from app.detect.signs import SignVotes, which_of_the_two, yaw_rate_problem
from app.results.agreement import DriveResult, disagreement
from app.results.combine import Combined
from app.results.headline import Headline, headline, positive
from app.results.pairing import Paired
from app.results.regression import AY_SPAN_MPS2, MIN_SAMPLES, RegressionFit
from app.units import G0

SENSOR_MAX_HZ = 400.0  # an optical sensor sends at 50–250 Hz; far beyond that is not its own pace
HINT_AFTER_S = 2.0  # of frame time: a burst at the start is no rate


def resting_fit(
    regression: RegressionFit | None, quasi: RegressionFit | None, crossed: bool
) -> RegressionFit | None:
    """The regression the result rests on: the steady samples', or where no sweep crossed
    zero, the quasi-steady samples'. Without a sweep the car's speed and yaw rate were never
    held for the method's own measurement, and samples that passed the steady gate still carry
    slow transients (corners taken braking gently: C2n 0.5–1.1 % low on four simulated track
    days, the truth outside each interval; −0.06 to −0.41 % and inside with the quasi-steady
    model's terms)."""
    if quasi is None or crossed:
        return regression
    return quasi


def witness(
    fit: RegressionFit | None, regression: RegressionFit | None, quasi: RegressionFit | None
) -> RegressionFit | None:
    """The fit whose own d shows the roles' signs (d held at the tape's hides them): the steady
    samples' where there are any (the quasi-steady ones' transitions can place d anywhere:
    circles at one speed, 4 m behind), else the result's (``fit``)."""
    return regression if fit is quasi and regression is not None else fit


def d_witnessed(witnessed: RegressionFit | None) -> bool:
    """Do the samples place d themselves (speeds apart: ``DResult.free_m`` where d is held)?
    ``witnessed`` is ``witness``'s fit."""
    if witnessed is None:
        return False
    if witnessed.estimator == "marginal":  # d under the tape's prior: the samples' own, if any
        return witnessed.d.free_m is not None
    return not witnessed.d.held or witnessed.d.free_m is not None


def sign_problem(fit: RegressionFit | None, witnessed: RegressionFit | None, signs: SignVotes) -> str | None:
    """Why the regression's C2n is not a result, when it is not positive. A role the wrong way
    round (the yaw rate, or the sideslip) turns both of β = ψ0 + d·κ − a_y/(g·C2n)'s terms
    over: the fit then puts the sensor behind the rear axle and C2n below zero; the car's a_y
    and steering (``signs``) say which of the two it is. Where d is held (circles at one
    speed), nothing in the fit shows a flipped yaw rate: the votes alone do. ``fit`` is the
    result's (``resting_fit``), ``witnessed`` its ``witness``."""
    if fit is None:
        return None
    d, where = fit.d.m, f"{-fit.d.m:.2f} m behind the rear axle and C2n at {fit.c2n:.2f}"
    assert witnessed is not None  # there is a fit
    seen = d_witnessed(witnessed)
    if witnessed.estimator == "marginal" and not seen:  # d is the tape's prior's: the
        problem = yaw_rate_problem(signs)  # votes alone show the signs, as where d is held
        if problem is not None or positive(fit.c2n):
            return problem
        d = 0.0
    elif witnessed.d.free_m is not None and witnessed.d.free_m < 0:
        d, where = witnessed.d.free_m, f"at least {-witnessed.d.free_m:.2f} m behind the rear axle"
    elif not witnessed.d.held and witnessed.d.m < 0:
        d, where = witnessed.d.m, f"{-witnessed.d.m:.2f} m behind the rear axle"
    if positive(fit.c2n) and d >= 0:  # no d of the samples' own (one speed): the votes show the signs
        return None if seen else yaw_rate_problem(signs)
    if d < 0:
        return (
            f"the sideslip and the yaw rate disagree in sign (the regression puts the sensor "
            f"{where}): {which_of_the_two(signs)}"
        )
    return (
        f"the regression's C2n is {fit.c2n:.2f}, not positive: the steady samples do not show the "
        "sideslip falling with speed on a circle — not a result"
    )


def drives_disagree(
    fit: RegressionFit | None, quasi: RegressionFit | None, quasi_drives: Sequence[RegressionFit | None]
) -> str | None:
    """Why drives pooled give no one C2n: drives each alone whose C2n differ beyond their errors
    (each pair's z, Holm's step-down at 95 % over all pairs: ``agreement.py``, as analyze checks
    drives before pooling them) — not one car on one set of tyres, whose C2n a pooled fit would
    bend its terms to split. ``fit`` is the result's, ``quasi_drives`` each drive's alone."""
    if fit is None or fit is not quasi:
        return None
    alone = [(k, f) for k, f in enumerate(quasi_drives, 1) if f is not None and positive(f.c2n)]
    if disagreement([DriveResult(f"drive {k}", f.c2n, f.c2n_ci95) for k, f in alone]) is None:
        return None
    each = "; ".join(f"drive {k} {f.c2n:.3f} [{f.c2n_ci95[0]:.3f}, {f.c2n_ci95[1]:.3f}]" for k, f in alone)
    return (
        f"the drives pooled disagree, each alone: {each} — not one car on one set of tyres "
        "(a tyre change, pressures, temperatures?): analyse them apart"
    )


def unbounded_fit(fit: RegressionFit | None) -> str | None:
    """Why the regression's C2n is no result though positive: its interval has no upper end (its
    a_y coefficient's reaches zero: too few samples, or too narrow an a_y range, to rule out a
    sideslip that does not change with a_y). ``fit`` is the result's (``resting_fit``)."""
    if fit is None or not positive(fit.c2n) or math.isfinite(fit.c2n_ci95[1]):
        return None
    low, high = fit.samples.ay_range_mps2
    held = f"; what holds it open most: {fit.held_open.by}" if fit.held_open and fit.held_open.by else ""
    return (
        f"the regression over {fit.samples.count:,} samples reads C2n {fit.c2n:.2f} but does not bound "
        f"it: its 95 % interval runs from {fit.c2n_ci95[0]:.2f} with no upper end (a_y "
        f"{low:.1f}–{high:.1f} m/s²{held}) — drive longer: steady circles at 2–4 m/s² with the speed "
        "swept slowly through the sign change"
    )


def reads_backwards(backwards_s: float, forwards_s: float, vx_scale: float = 1.0) -> str | None:
    """The car cornering backwards by the optical speed for longer than forwards (a test drive
    corners forwards; reversing is driven straight): vx the wrong way round, or the head turned;
    None otherwise. ``vx_scale`` is the config's, whose sign the fix turns."""
    if backwards_s <= max(forwards_s, 1.0):
        return None
    return (
        f"the optical speed reads backwards ({backwards_s:.0f} s cornering backwards, "
        f"{forwards_s:.0f} s forwards): vx's sign is the wrong way round, or the head faces the rear "
        f"— set [roles] vx's scale = {-vx_scale:g} (and vy's turned too where the head faces the rear)"
    )


def refusal(
    sign: str | None,
    disagree: str | None,
    unsteady: str | None,
    regression: RegressionFit | None,
    cornering: Cornering,
    unbounded: str | None = None,
    lost_in_samples: int = 0,
    vx_scale: float = 1.0,
    speed_min_mps: float = DetectorSettings.speed_min_mps,
    raised_noise: Sequence[str] = (),
) -> str:
    """Why there is no C2n: the filter lost the car in the samples (its estimates there lag the
    car, so a sign or a fit read from them is the filter's), a wrong sign (``sign_problem``),
    drives apart (``drives_disagree``), a fit that does not bound C2n (``unbounded_fit``),
    crossings whose sweeps disagree or that do not bound it (``support``), or the manoeuvre the
    drive lacked."""
    if lost_in_samples:  # q_u = 1e-6 on track laps read as "the sideslip and the yaw rate disagree"
        return (
            f"the filter lost the car in {lost_in_samples:,} of the samples C2n is measured on: its "
            "estimates lag the car there (the warning below names the process noise to raise)"
        )
    if sign:
        return sign
    if disagree:
        return disagree
    if unbounded:
        return unbounded
    if unsteady and (regression is None or not positive(regression.c2n)):
        return unsteady
    c = cornering
    backwards = reads_backwards(c.backwards_s, c.turning_s, vx_scale)
    if backwards:
        return backwards
    beyond = beyond_grip(c)
    if beyond:
        return beyond
    above = speed_min_problem(c, speed_min_mps)
    if above:
        return above
    if c.turning_s < 1.0:
        return (
            "no cornering in the drive: drive steady circles at 2–4 m/s² with the speed swept "
            "slowly through the sign change"
        )
    tight = f"{c.tight_s:.0f} s on radii under eight wheelbases, " if c.tight_s >= 0.5 else ""
    raised = speed_min_mps > DetectorSettings.speed_min_mps and c.below_speed_s >= 1.0
    under = (
        f" ({c.below_speed_s:.0f} s more under the config's speed_min_mps {speed_min_mps:g} m/s)"
        if raised
        else ""
    )
    seconds = (
        f"of {c.turning_s:.0f} s cornering{under}, {c.ay_high_s:.0f} s beyond the tyres' linear range "
        "of a_y, "
        f"{c.transient_s:.0f} s speed or steering changing too fast, {tight}{c.usable_s:.0f} s quasi-steady"
    )
    span = c.usable_ay_mps2
    if span is not None and span[1] - span[0] < AY_SPAN_MPS2 and c.usable_samples >= MIN_SAMPLES:
        what, seconds = (
            "quasi-steady cornering at one a_y only",
            f"{seconds}, all at a_y {span[0]:.1f}–{span[1]:.1f} m/s² where a fit needs "
            f"{AY_SPAN_MPS2:g} m/s² between its least and most",
        )
    else:
        what = "too little quasi-steady cornering"
    noisy = (
        f"the config raises the filter's process noise ({', '.join(raised_noise)}): its rates follow the "
        "sensor's noise, and steady cornering reads as changing too fast — restore the default, or "
        if raised_noise and c.transient_s >= 0.5 * c.turning_s
        else ""
    )
    return (
        f"no sideslip sign change and {what}: {seconds} — {noisy}drive steady circles at 2–4 m/s² with "
        "the speed swept slowly through the sign change, or corners held at 1–4 m/s² at several speeds"
    )


def beyond_grip(c: Cornering) -> str | None:
    """Most of the cornering at an a_y no tyre holds (``GRIP_MAX_MPS2``): the speed × yaw rate
    the gate reads it from is a unit's mistake — a yaw rate in deg/s read as rad/s reads 57.3×, and
    was told to drive steady circles. None where most of it is within a tyre's grip."""
    if c.turning_s < 1.0 or c.beyond_grip_s < 0.5 * c.turning_s:
        return None
    return (
        f"of {c.turning_s:.0f} s cornering, {c.beyond_grip_s:.0f} s at a lateral acceleration (speed × yaw "
        f"rate) over {GRIP_MAX_MPS2 / G0:.0f} g, which no tyre holds — the yaw rate reads too large: check "
        "its unit (the DBC's, or [units] yaw_rate in the config; deg/s read as rad/s is 57.3×), and "
        "the optical vx's"
    )


def speed_min_problem(c: Cornering, speed_min_mps: float) -> str | None:
    """The config's least speed above all the drive's cornering (a drive at 8–17 m/s under
    ``speed_min_mps = 100``, or 40 meant as km/h): the config to blame, not the driving. None
    where some cornering is above it, or it is at its default or below (a drive too slow for
    the method is the driving's)."""
    default = DetectorSettings.speed_min_mps
    if c.turning_s >= 1.0 or c.below_speed_s < 1.0 or speed_min_mps <= default:
        return None
    return (
        f"no cornering above [detector] speed_min_mps = {speed_min_mps:g} m/s in the config, "
        f"{c.below_speed_s:.0f} s of it under: lower speed_min_mps (default {default:g}; in m/s, not km/h)"
    )


def replay_hint(elapsed_s: float, optical_frames: int) -> str | None:
    """Optical frames far faster than a sensor sends them: a drive replayed faster than it was
    driven and taken at arrival time, so every sweep looks that much too fast to use.
    ``optical_frames``: the most frames any optical role (vx, vy, beta) had."""
    if elapsed_s < HINT_AFTER_S or optical_frames / elapsed_s <= SENSOR_MAX_HZ:
        return None
    return (
        f"optical frames arrive at {optical_frames / elapsed_s:.0f} Hz, faster than a sensor sends them "
        f"(≤ {SENSOR_MAX_HZ:g} Hz): a replay faster than it was driven? Its sweeps look that much "
        "too fast to use: give c2n live the replay's rate (--rate)"
    )


def standing_headline(
    sign: str | None,
    disagree: str | None,
    unsteady: str | None,
    fit: RegressionFit | None,
    regression: RegressionFit | None,
    quasi: RegressionFit | None,
    paired: Paired | None,
    combined: Combined | None,
) -> Headline | None:
    """The C2n to report (``headline.py``: by what the drive held), unless a refusal stands: a
    role's sign the wrong way round (``sign``), pooled drives that disagree (``disagree``), or —
    with no fit to rest on — crossings whose sweeps disagree or that do not bound C2n
    (``unsteady``)."""
    if sign:
        return None
    held = fit if fit is not None and fit is quasi else None  # no sweep crossed zero
    if (held is not None and disagree) or (fit is None and unsteady):
        return None
    return headline(None if held else regression, held, paired, combined)
