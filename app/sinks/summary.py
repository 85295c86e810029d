"""The session summary: what ``c2n analyze --json``, ``c2n export`` and a live session write.

``Summary`` is the result file in typed form, its fields the file's keys (stable:
docs/result-file.md), its numbers rounded as the file holds them, so the report shows what the file
says. ``build`` makes it from a Snapshot; ``to_json`` gives the file's content.
"""

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, astuple, dataclass, field, replace
from pathlib import Path
from typing import Any, Literal

from app import __version__
from app.config import Config
from app.detect.signs import SignVotes
from app.detect.steady_state import WHEELBASE_M
from app.output.files import json_ready, write_json
from app.records import Crossing, CrossingRejected, Direction, Sweep
from app.results.combine import Combined
from app.results.headline import Method
from app.results.pairing import Paired
from app.results.regression import TIGHT_WHEELBASES, RegressionFit
from app.snapshot import Snapshot
from app.sources.logs import LogReport
from app.units import Z95

REQUIRED_ROLES = (("vx",), ("vy", "beta"))

Interval = tuple[float | None, float | None]


@dataclass(frozen=True)
class CrossingRow:
    t: float | None  # s since the first frame
    t_abs: float
    u0_mps: float | None
    u0_kmh: float | None
    u0_ci95: Interval
    c2n: float | None
    ci95: Interval
    direction: Direction
    sweep: Sweep
    ay_mps2: float | None
    radius_m: float | None
    sweep_rate_mps2: float | None
    n_samples: int
    method: Literal["v/r", "beta"]
    slope_corrected: bool  # the pad's slope, as the regression found it, taken out before the fit


@dataclass(frozen=True)
class RejectedRow:
    t: float | None
    direction: Direction | None
    sweep: Sweep
    u_mps: float | None
    reason: str


@dataclass(frozen=True)
class RegressionRow:
    c2n: float | None
    c2n_ci95: Interval
    d_m: float | None
    d_ci95: Interval
    psi0_deg: float | None
    psi0_ci95_deg: Interval | None
    model: Literal["linear", "softening"]
    softening_t: float | None
    softening_per_mps2_2: float | None
    c2n_linear_model: float | None
    c2n_softening_model: float | None
    c2n_linear_ci95: Interval | None  # each model's own interval, whichever was chosen
    c2n_softening_ci95: Interval | None
    n_samples: int
    ay_range_mps2: Interval
    softening_resolved: bool  # False: the a_y range cannot tell linear from softening tyres
    softening_hidden_pct: float | None  # softening that could hide in the data, % of C2n
    slope_pct: float | None  # the test pad's slope, fitted where the headings cover full circles
    slope_ci95_pct: Interval | None
    slope_downhill_deg: float | None  # where it falls: degrees from the start heading, left positive
    d_fixed: bool  # True: the samples could not place d beside C2n; d is the config's
    d_held_tight: bool  # True: held because most samples turned on radii under 20 wheelbases
    c2n_per_tape_cm_pct: float | None  # where d is held: how far 1 cm of d moves C2n
    tight_terms: list[str]  # a small pad's terms fitted: "ay_u_dot" (its sweeps), "k2_ay" (two wheels)
    speed_range_mps: Interval
    turn_force_pct: float | None  # a rear force following the turn's direction, % of the axle's weight
    turn_force_ci95_pct: Interval | None
    seconds: float  # of driving the samples cover
    logs: int  # drives pooled (c2n analyze --pool), each with its own ψ0; psi0_deg is the first's
    transient_terms: bool  # quasi-steady: the yaw inertia's and braking's terms were fitted
    yaw_bias_degps: float | None  # quasi-steady: the yaw rate reads this much high, where fitted
    yaw_bias_ci95_degps: Interval | None
    estimator: Literal["cascade", "marginal"]  # [priors] estimator: terms chosen by tests, or all with priors
    held_open_by: str | None  # marginal: the term whose uncertainty holds C2n's interval open most
    held_open_share: float | None  # ... and its share of C2n's variance
    d_information: float | None  # marginal: what the drive tells of d over what the tape does


@dataclass(frozen=True)
class CorneringRow:
    """Seconds of cornering (a turn, above the speed limit, the sensor well) and what they were."""

    turning_s: float
    ay_high_s: float  # beyond the tyres' linear range
    transient_s: float  # speed or steering changing too fast for quasi-steady, or settling
    usable_s: float  # quasi-steady
    tight_s: float  # on a radius under eight wheelbases: the bicycle model's small steer angles fail


@dataclass(frozen=True)
class SignVotesRow:
    """Cornering samples (one per 0.1 s) whose a_y and steering turn with the yaw rate, and against."""

    ay_with: int
    ay_against: int
    steer_with: int
    steer_against: int


@dataclass(frozen=True)
class PairedRow:
    c2n: float | None
    c2n_ci95: Interval
    misalignment_deg: float | None
    misalignment_ci95_deg: Interval | None
    lag_s: float | None
    lag_ci95_s: Interval | None
    cancels: tuple[str, ...]
    cells: Mapping[str, float | None]
    n: int
    birge_ratio: float | None


@dataclass(frozen=True)
class CombinedRow:
    n: int
    birge_ratio: float | None
    se: float | None


@dataclass(frozen=True)
class Frames:
    """What the frames were (``total`` is the sum of the kinds after it; ``fd_frames`` aside)."""

    total: int = 0
    used: int = 0
    unused: int = 0
    unknown_id: int = 0
    other_channel: int = 0
    bad_length: int = 0
    undecodable: int = 0
    bad_time: int = 0
    error_frames: int = 0
    remote_frames: int = 0
    fd_frames: int = 0


@dataclass(frozen=True)
class FrameIdRow:
    channel: str
    id: str
    frames: int


@dataclass(frozen=True)
class FilterRow:
    resets: int = 0
    time_jumps: int = 0
    late_frames: int = 0
    outliers: int = 0
    health: float | None = None
    noise: Mapping[str, float | None] = field(default_factory=dict)


@dataclass(frozen=True)
class Summary:
    """The result file; ``Summary()`` is a run that found nothing."""

    c2n: float | None = None
    c2n_ci95: Interval | None = None
    c2n_method: str | None = None
    u0_mps: float | None = None
    crossings: tuple[CrossingRow, ...] = ()
    regression: RegressionRow | None = None
    paired: PairedRow | None = None
    frames: Frames = Frames()
    warnings: tuple[str, ...] = ()
    combined: CombinedRow | None = None
    rejected_crossings: tuple[RejectedRow, ...] = ()
    quasi_steady: RegressionRow | None = None  # the quasi-steady samples' fit, where no sweep crossed zero
    cornering: CorneringRow | None = None
    quasi_steady_drives: tuple[RegressionRow | None, ...] = ()  # drives pooled: each one's fit alone
    sign_votes: SignVotesRow | None = None  # do a_y and the steering turn with the yaw rate?
    d_m: float | None = None
    g_mps2: float | None = None
    # C2n's relative standard error [%] from the sensors' scale tolerances ([calibration]), counted
    # in c2n_ci95; 0 where none is given
    c2n_scale_se_pct: float | None = None
    duration_s: float | None = None
    inputs: tuple[str, ...] = ()
    config: str | None = None
    frames_by_id: tuple[FrameIdRow, ...] = ()
    filter: FilterRow = FilterRow()
    version: str = __version__

    def to_json(self) -> dict[str, Any]:
        """The file's content: JSON types only, in the file's key order."""
        return dict(json_ready(self))

    def warned(self, lost: Sequence[str]) -> "Summary":
        """The same summary with what the run lost (a recording stopped, a bus gone) first, before
        what the drive shows: the user reads the loss of data before any advice."""
        return replace(self, warnings=(*lost, *self.warnings)) if lost else self


def build(
    snapshot: Snapshot, config: Config, inputs: Sequence[str], reports: Sequence[LogReport] = ()
) -> Summary:
    t0 = snapshot.t0
    headline = snapshot.headline
    counts = snapshot.frames
    combined = snapshot.combined
    u0 = snapshot.u0_mps
    return Summary(
        c2n=_round(headline.c2n) if headline else None,
        c2n_ci95=_pair(headline.ci95) if headline else None,
        c2n_method=headline.method.value if headline else None,
        c2n_scale_se_pct=_scale_se_pct(headline.method, config) if headline else None,
        u0_mps=_round(u0) if u0 is not None else None,
        crossings=tuple(_crossing(c, t0) for c in snapshot.crossings),
        regression=_regression(snapshot.regression),
        quasi_steady=_regression(snapshot.quasi),
        cornering=CorneringRow(*(round(x, 1) for x in astuple(snapshot.cornering)))
        if snapshot.t_first is not None
        else None,
        quasi_steady_drives=tuple(_regression(fit) for fit in snapshot.quasi_drives)
        if snapshot.quasi is not None
        else (),
        sign_votes=_sign_votes(snapshot.signs),
        paired=_paired(snapshot.paired),
        frames=Frames(**counts.as_dict()),
        warnings=tuple(warnings(snapshot, config, reports)),
        combined=_combined(combined) if combined else None,
        rejected_crossings=tuple(_rejected(r, t0) for r in snapshot.rejections),
        d_m=snapshot.d_m,
        g_mps2=snapshot.g_mps2,
        duration_s=_round(snapshot.elapsed_s, 3),
        inputs=tuple(inputs),
        config=str(config.path),
        frames_by_id=tuple(
            FrameIdRow(str(ch), format_id(i, ext), n)
            for (ch, i, ext), n in sorted(
                counts.by_id.items(), key=lambda kv: (str(kv[0][0]), kv[0][1], kv[0][2])
            )
        ),
        filter=FilterRow(
            **asdict(snapshot.filter.counts),
            health=_round(snapshot.filter.health, 3),
            noise={k: _round(v, 5) for k, v in snapshot.filter.noise_sigma.items()},
        ),
    )


def write(path: Path, summary: Summary) -> None:
    """Write atomically: a crash leaves the old file or the new one, never half of one."""
    write_json(path, summary.to_json(), "the summary")


def _frame_ids(config: Config, role: str) -> str:
    spec = config.roles[role]
    for dbc in config.dbcs:
        for message in dbc.database.messages:
            if message.name == spec.message:
                where = f" on channel {spec.channel}" if spec.channel is not None else ""
                return f"{spec.name}, id 0x{message.frame_id:X}{where}"
    return spec.name


def roles_without_frames(snapshot: Snapshot, config: Config) -> list[str]:
    counts = snapshot.frames.role_frames
    return [role for role in config.roles if counts[role] == 0]


def missing_required(snapshot: Snapshot, config: Config) -> str | None:
    """A message naming the required role that had no frames, or None."""
    silent = set(roles_without_frames(snapshot, config))
    for group in REQUIRED_ROLES:
        configured = [r for r in group if r in config.roles]
        if configured and all(r in silent for r in configured):
            role = configured[0]
            return (
                f"no frames for role '{role}' ({_frame_ids(config, role)}) — "
                "is the optical sensor on this bus/log and channel?"
            )
    return None


def warnings(snapshot: Snapshot, config: Config, reports: Sequence[LogReport] = ()) -> list[str]:
    """What the user should know about the run, one line each."""
    counts = snapshot.frames
    out: list[str] = []
    if snapshot.sign_problem:
        out.append(snapshot.sign_problem)
    if snapshot.unsteady_crossings:
        out.append(snapshot.unsteady_crossings)
    if snapshot.odd_sign:
        out.append(snapshot.odd_sign)
    for report in reports:
        if report.stopped:
            out.append(f"{report.path}: {report.stopped}")
    for role in roles_without_frames(snapshot, config):
        out.append(f"no frames for role '{role}' ({_frame_ids(config, role)})")
    if "yaw_rate" not in config.roles and "ay" not in config.roles:
        out.append(
            "no yaw rate or lateral acceleration: the steady-state gate cannot check a_y "
            "or tell straight driving"
        )
    for dbc in config.dbcs:
        if dbc.relaxed:
            out.append(f"{dbc.path.name} loaded with strict=False (overlapping or oversized signals)")
    if counts.other_channel:
        out.append(
            f"{counts.other_channel} frames of known ids arrived on a channel their DBC "
            "is not decoded on ([channels])"
        )
    if counts.bad_length:
        cut = sum(n for (_, kind), n in counts.bad_by_id.items() if kind == "cut")
        how = f" ({cut} with a data field cut short in a text log's line)" if cut else ""
        out.append(f"{counts.bad_length} frames not decoded: their length is not their DBC message's{how}")
    if counts.bad_time:
        out.append(f"{counts.bad_time} frames without a usable timestamp (NaN or infinite): not used")
    for reason, n in counts.rejected.most_common():
        out.append(f"{n} frames' values dropped: {reason}")
    f = snapshot.filter.counts
    if f.time_jumps:
        out.append(f"timestamps went backwards {f.time_jumps} times: the filter restarted")
    if f.resets - f.time_jumps:
        out.append(
            f"the optical data stopped {f.resets - f.time_jumps} times for over "
            f"{config.filter.gap_reset_s:g} s: the filter restarted"
        )
    # drives apart: no pooled fit to speak of; a role the wrong way round: no fit's terms to trust
    fit = snapshot.fit if not snapshot.drives_disagree and not snapshot.sign_problem else None
    if fit is not None and not fit.d.ci95_m[0] <= config.d_m <= fit.d.ci95_m[1]:
        low, high = fit.d.ci95_m
        out.append(
            f"the fitted sensor position d = {fit.d.m:.3f} m [{low:.3f}, {high:.3f}] disagrees with the "
            f"config's {config.d_m:g} m: check sensor_ahead_of_rear_axle_m (the crossings' C2n scales "
            "with d; the regression's does not)"
        )
    apart = _crossings_apart(snapshot)
    if apart is not None:
        out.append(apart)
    idle = [str(k) for k, alone in enumerate(snapshot.quasi_drives, 1) if alone is None]
    if fit is not None and fit is snapshot.quasi and idle:
        out.append(
            f"drive {', '.join(idle)} of the {len(snapshot.quasi_drives)} pooled has too little "
            "quasi-steady cornering to be fitted alone (`cornering` counts why: tight turns, a_y beyond "
            "the linear range, transients): the pooled C2n rests on the others"
        )
    tape = f"±{config.calibration.d_tolerance_mm:g} mm"
    if fit is not None and fit.d.held and fit is snapshot.quasi:
        out.append(
            f"quasi-steady cornering cannot place the sensor's d beside C2n as a sweep does: d is the "
            f"config's {config.d_m:g} m (its interval counts the tape's {tape}) — measure it with a tape"
        )
    elif fit is not None and fit.d.held_tight:
        wheelbases = TIGHT_WHEELBASES * (config.vehicle.wheelbase_m or WHEELBASE_M)
        out.append(
            f"most steady samples turned on radii under {wheelbases:.0f} m ({TIGHT_WHEELBASES:g} "
            f"wheelbases), where the sensor's d cannot be fitted beside C2n: d is the config's "
            f"{config.d_m:g} m, and each cm of d moves C2n by {fit.d.per_tape_cm_pct or 0.0:.1f} % here "
            f"(its interval counts the tape's {tape}) — measure d to the millimetre, or sweep on wider "
            "circles"
        )
    elif fit is not None and fit.d.held:
        low, high = fit.samples.speed_range_mps
        out.append(
            f"the steady samples span {low:.1f}–{high:.1f} m/s only: too narrow to fit the sensor's d beside "
            f"C2n, so d is the config's {config.d_m:g} m (its interval counts the tape's {tape}); sweep the "
            "speed through u0 to measure both"
        )
    elif fit is not None and fit.d.information is not None and fit.d.information < 1.0:
        low, high = fit.samples.speed_range_mps
        where = (
            "quasi-steady cornering"
            if fit is snapshot.quasi
            else f"the steady samples ({low:.1f}–{high:.1f} m/s)"
        )
        out.append(
            f"{where} place the sensor's d less well than the tape does ({fit.d.information:.2f} of its "
            f"information): C2n rests on the config's {config.d_m:g} m more than on the drive (its interval "
            f"counts the tape's {tape}); sweep the speed through u0 on two radii to measure both"
        )
    if fit is not None and fit.models.chosen == "softening":
        beside = (  # the marginal fit has the softening in its model whatever the drive: no other line
            "its interval counts the softening's spread"
            if fit.estimator == "marginal"
            else f"a straight-line fit would give {fit.models.linear.c2n:.3f}"
        )
        out.append(
            f"the tyres soften with slip (t = {fit.models.softening_t:.1f}): C2n is extrapolated to zero "
            f"lateral acceleration ({fit.c2n:.3f}; {beside})"
        )
    if fit is not None and not fit.models.resolved:
        low, high = fit.samples.ay_range_mps2
        out.append(
            f"the steady samples span a_y {low:.1f}–{high:.1f} m/s² only: too narrow to tell linear tyres "
            f"from softening ones (a softening of {fit.models.hidden_pct:.0f} % could hide in it), so the "
            "interval covers both; steady laps at lower a_y (slower, or a larger circle) would narrow it"
        )
    slope = _slope_warning(fit)
    if slope is not None:
        out.append(slope)
    turn = fit.turn_force if fit is not None else None
    if turn is not None:
        low, high = turn.ci95_pct
        out.append(
            f"the rear tyres make a force that follows the turn's direction, not its size: "
            f"{turn.pct:+.2f} % [{low:+.2f}, {high:+.2f}] of the axle's weight (towards the "
            "turn's inside; a tyre's camber step, friction in the suspension): the regression takes it out "
            "of C2n; each crossing carries it (it moves the sign change as a sensor d·κ further ahead would)"
        )
    bias = _yaw_bias_warning(fit)
    if bias is not None:
        out.append(bias)
    flipped = _sideslip_flip_warning(snapshot, fit, config)
    if flipped is not None:
        out.append(flipped)
    if snapshot.replay_hint:
        out.append(snapshot.replay_hint)
    beyond = _crossing_beyond_gate(snapshot, config) if flipped is None else None  # its u0 is the reading's
    if beyond is not None:
        out.append(beyond)
    paired = snapshot.paired
    yaw, yaw_se = (paired.misalignment_rad, paired.misalignment_se) if paired is not None else (None, None)
    if yaw is not None and yaw_se is not None and abs(yaw) > max(Z95 * yaw_se, math.radians(0.1)):
        out.append(
            f"the sensor head looks yawed by {math.degrees(yaw):+.2f}° (left and right turns disagree); "
            "pairing and the regression remove it, but align the head"
        )
    rejected = snapshot.rejections
    if rejected:
        out.append(f"{len(rejected)} sign changes not used (see 'rejected_crossings')")
    quasi = snapshot.headline is not None and snapshot.headline.method is Method.QUASI_STEADY
    if quasi:
        out.append(
            "no sweep crossed the sideslip's sign change: C2n is the quasi-steady estimate from cornering "
            "as driven (its model adds the yaw inertia's and braking's share of the rear tyres' force); its "
            "interval counts the samples' noise, not the model's reach (simulated track laps: within 0.9 % "
            "on one car model, 1.3 % on another)"
            + (
                " — sweep the speed through u0 on a circle to measure it the method's own way"
                if not beyond
                else ""
            )
        )
    elif snapshot.t_first is not None and not snapshot.crossings and beyond is None:
        out.append(
            "no sideslip sign change was found in steady cornering: sweep the speed through u0 on a circle"
        )
    return out


SLOPE_WARN_PCT = 1.0  # a pad slope this steep, and beyond its noise, is worth a word


def _slope_warning(fit: RegressionFit | None) -> str | None:
    """A slope the regression found: where it falls, that it is taken out of C2n, and that the
    crossings (each at one heading) still carry it."""
    slope = fit.slope if fit is not None else None
    if slope is None or slope.pct < SLOPE_WARN_PCT or slope.ci95_pct[0] <= 0.0:
        return None
    towards = slope.downhill_deg
    side = "left" if towards >= 0 else "right"
    low, high = slope.ci95_pct
    return (
        f"the test pad slopes {slope.pct:.1f} % [{low:.1f}, {high:.1f}] "
        f"(falling {abs(towards):.0f}° {side} of the start heading): the regression takes it out of C2n; "
        "each crossing happens at one heading and carries it — pair left and right circles, or find a "
        "level pad"
    )


def _sign_votes(votes: SignVotes) -> SignVotesRow | None:
    row = SignVotesRow(votes.ay_with, votes.ay_against, votes.steer_with, votes.steer_against)
    return row if any(astuple(row)) else None  # no cornering, or no a_y or steering to vote


NOMINAL_OFF = 0.3  # C2n this far from the config's nominal: not the tyres of a test day


def _sideslip_flip_warning(snapshot: Snapshot, fit: RegressionFit | None, config: Config) -> str | None:
    """Circles at one speed cannot show a sideslip the wrong way round: nothing in them places d,
    and with β turned over they read 1/(g·(2d/u² − 1/(g·C2n))) for C2n. Where the config's nominal
    C2n is far from the reading and near what the other sign gives, say so."""
    nominal = config.tyres.c2n_per_rad
    if fit is None or not nominal or snapshot.d_witnessed or not fit.c2n > 0:
        return None
    u = 0.5 * (fit.samples.speed_range_mps[0] + fit.samples.speed_range_mps[1])
    g = config.vehicle.gravity_mps2
    turned = 2.0 * fit.d.m / u**2 - 1.0 / (g * fit.c2n)
    other = 1.0 / (g * turned) if turned > 0 else math.nan
    off = abs(fit.c2n / nominal - 1.0)
    if not (off > NOMINAL_OFF and abs(other / nominal - 1.0) < off / 3.0):
        return None
    return (
        f"C2n {fit.c2n:.2f} is {100 * off:.0f} % off the config's nominal {nominal:g}; with the sideslip "
        f"the other way round these samples at one speed would read {other:.2f}: check `scale` of the "
        "roles vy and beta (+ to the left) — one speed cannot tell, a sweep through u0 can"
    )


def _crossing_beyond_gate(snapshot: Snapshot, config: Config) -> str | None:
    """Where no crossing was found on circles whose u0 lies beyond the a_y gate: the words saying
    so (the sideslip changed sign where the tyres are no longer linear, so nothing was counted)."""
    fit, limit = snapshot.regression, config.detector.ay_max_mps2
    if snapshot.crossings or fit is None or snapshot.sign_problem or not fit.c2n > 0:
        return None
    curvature = fit.samples.curvature_range_per_m[0]  # the largest circle driven
    if not curvature > 0 or fit.d.m <= 0:
        return None
    u0_squared = config.vehicle.gravity_mps2 * fit.c2n * fit.d.m
    ay_at_u0 = u0_squared * curvature
    if ay_at_u0 <= limit:
        return None
    return (
        f"on the largest circle driven (radius {1 / curvature:.0f} m) the sideslip changes sign at a_y ≈ "
        f"{ay_at_u0:.1f} m/s², beyond the tyres' linear range ({limit:g} m/s², [detector] ay_max_mps2), "
        f"so no crossing was counted: drive a circle of radius ≥ {1.2 * u0_squared / limit:.0f} m to meet "
        f"u0 ≈ {math.sqrt(u0_squared):.1f} m/s within it"
    )


def format_id(frame_id: int, extended: bool) -> str:
    """0x7E5 for an 11-bit id, 0x000007E5 for a 29-bit one, as CAN tools write them."""
    return f"0x{frame_id:08X}" if extended else f"0x{frame_id:X}"


def _round(value: float, digits: int = 4) -> float | None:
    return round(float(value), digits) if math.isfinite(value) else None


def _crossings_apart(snapshot: Snapshot) -> str | None:
    """Where the paired crossings' interval and the regression's headline's do not meet: which to
    believe, and why they differ."""
    head, paired = snapshot.headline, snapshot.paired
    if head is None or head.method is not Method.REGRESSION or paired is None:
        return None
    (low, high), (h_low, h_high) = paired.ci95, head.ci95
    if low <= h_high and h_low <= high:
        return None
    return (
        f"the paired crossings read {paired.c2n:.3f} [{low:.3f}, {high:.3f}], apart from the "
        f"regression's {head.c2n:.3f}: each crossing rests on one speed and the config's d (eq. 7) "
        "and carries what the regression fits beside C2n (a head's yaw where only one direction "
        "crossed, the tyres' secant beyond its a_y, a tight turn's two wheels) — the regression's C2n "
        "is the result"
    )


def _maybe(value: float | None, digits: int = 4, scale: float = 1.0) -> float | None:
    return None if value is None else _round(value * scale, digits)


def _pair(values: tuple[float, float], scale: float = 1.0, digits: int = 4) -> Interval:
    return (_round(values[0] * scale, digits), _round(values[1] * scale, digits))


def _crossing(c: Crossing, t0: float) -> CrossingRow:
    return CrossingRow(
        t=_round(c.t - t0, 3),
        t_abs=c.t,
        u0_mps=_round(c.u0_mps),
        u0_kmh=_round(c.u0_kmh, 3),
        u0_ci95=_pair(c.u0_ci95),
        c2n=_round(c.c2n),
        ci95=_pair(c.ci95),
        direction=c.direction,
        sweep=c.sweep,
        ay_mps2=_round(c.ay_mps2, 3),
        radius_m=_round(c.radius_m, 2),
        sweep_rate_mps2=_round(c.sweep_rate_mps2, 3),
        n_samples=c.n_samples,
        method=c.method,
        slope_corrected=c.slope_corrected,
    )


def _rejected(r: CrossingRejected, t0: float) -> RejectedRow:
    return RejectedRow(_round(r.t - t0, 3), r.direction, r.sweep, _round(r.u_mps, 3), r.reason)


def _scale_se_pct(method: Method, config: Config) -> float:
    """What the sensors' scales add to the headline's error: a fit's C2n scales with the gyro's
    and the speed's, a crossing's with the speed's twice."""
    calibration = config.calibration
    share = calibration.fit_se if method.is_fit else calibration.crossing_se(config.d_m)
    return round(100.0 * share, 4)


def _regression(fit: RegressionFit | None) -> RegressionRow | None:
    if fit is None:
        return None
    deg = math.degrees(1.0)
    samples, d, psi0, models = fit.samples, fit.d, fit.psi0, fit.models
    slope, turn, bias, held = fit.slope, fit.turn_force, fit.yaw_bias, fit.held_open
    softening = models.softening
    return RegressionRow(
        c2n=_round(fit.c2n),
        c2n_ci95=_pair(fit.c2n_ci95),
        d_m=_round(d.m),
        d_ci95=_pair(d.ci95_m),
        psi0_deg=_maybe(psi0.rad if psi0 else None, scale=deg),
        psi0_ci95_deg=_pair(psi0.ci95_rad, deg) if psi0 else None,
        model=models.chosen,
        softening_t=_round(models.softening_t, 2),
        softening_per_mps2_2=_maybe(fit.softening.per_mps2_2 if fit.softening else None, 6),
        c2n_linear_model=_round(models.linear.c2n),
        c2n_softening_model=_maybe(softening.c2n if softening else None),
        c2n_linear_ci95=_pair(models.linear.ci95) if models.linear.ci95 else None,
        c2n_softening_ci95=_pair(softening.ci95) if softening and softening.ci95 else None,
        n_samples=samples.count,
        ay_range_mps2=_pair(samples.ay_range_mps2, digits=3),
        softening_resolved=models.resolved,
        softening_hidden_pct=_round(models.hidden_pct, 2),
        slope_pct=_maybe(slope.pct if slope else None, 2),
        slope_ci95_pct=_pair(slope.ci95_pct, digits=2) if slope else None,
        slope_downhill_deg=_maybe(slope.downhill_deg if slope else None, 0),
        d_fixed=d.held,
        d_held_tight=d.held_tight,
        c2n_per_tape_cm_pct=_maybe(d.per_tape_cm_pct, 3),
        tight_terms=list(samples.tight_terms),
        speed_range_mps=_pair(samples.speed_range_mps, digits=3),
        turn_force_pct=_maybe(turn.pct if turn else None, 2),
        turn_force_ci95_pct=_pair(turn.ci95_pct, digits=2) if turn else None,
        seconds=round(samples.duration_s, 1),
        logs=samples.logs,
        transient_terms=samples.transient_terms,
        yaw_bias_degps=_maybe(bias.degps if bias else None, 4),
        yaw_bias_ci95_degps=_pair(bias.ci95_degps, digits=4) if bias else None,
        estimator=fit.estimator,
        held_open_by=held.by if held else None,
        held_open_share=_maybe(held.share if held else None, 3),
        d_information=_maybe(d.information, 3),
    )


def _yaw_bias_warning(fit: RegressionFit | None) -> str | None:
    """Where the quasi-steady fit found the yaw rate biased (its interval clear of zero)."""
    found = fit.yaw_bias if fit is not None else None
    if found is None:
        return None
    low, high = found.ci95_degps
    if low <= 0.0 <= high:
        return None
    bias = round(found.degps, 4)  # as the result file has it: one rounding, not two
    return (
        f"the yaw rate reads {bias:+.3f} °/s [{low:+.3f}, {high:+.3f}] high: the quasi-steady "
        "fit takes it out of C2n (on corners turning mostly one way it would lean on it); zero the gyro "
        "at standstill before the drive"
    )


def _paired(paired: Paired | None) -> PairedRow | None:
    if paired is None:
        return None
    deg = math.degrees(1.0)

    def ci(value: float | None, se: float | None, scale: float = 1.0) -> Interval | None:
        if value is None or se is None:
            return None
        return (_round((value - Z95 * se) * scale), _round((value + Z95 * se) * scale))

    return PairedRow(
        c2n=_round(paired.c2n),
        c2n_ci95=_pair(paired.ci95),
        misalignment_deg=_round(paired.misalignment_rad * deg)
        if paired.misalignment_rad is not None
        else None,
        misalignment_ci95_deg=ci(paired.misalignment_rad, paired.misalignment_se, deg),
        lag_s=_maybe(paired.lag_s),
        lag_ci95_s=ci(paired.lag_s, paired.lag_se),
        cancels=tuple(paired.cancels),
        cells={key: _round(value) for key, value in paired.cells.items()},
        n=paired.n,
        birge_ratio=_round(paired.birge_ratio, 3),
    )


def _combined(combined: Combined) -> CombinedRow:
    return CombinedRow(combined.n, _round(combined.birge_ratio, 3), _round(combined.se, 5))
