"""What the user should know about a run, one line each: a registry of small advice functions.

Each function reads a ``Findings`` (what the run found, as plain values: the fits, the paired
crossings, the frame counts, the config's numbers, and the checks ``refusal.py`` made) and says
its line, or None (a few say one line per file, role or reason: a tuple). ``ADVICE`` holds them in
the order the result file lists their lines; ``advise`` asks each in turn. The summary only copies
what they say.
"""

import math
from collections.abc import Callable
from dataclasses import dataclass, field

from app.config import Config, FilterSettings
from app.decode.counts import FrameCounts
from app.detect.steady_state import WHEELBASE_M
from app.estimate.motion_model import FOLLOWS, MAX_CONSECUTIVE_REJECTS, FilterCounts
from app.results.combine import bracket
from app.results.headline import Headline, Method
from app.results.pairing import Paired
from app.results.regression import TIGHT_WHEELBASES, RegressionFit
from app.sources.logs import LogReport
from app.units import Z95

REQUIRED_ROLES = (("vx",), ("vy", "beta"))
SLOPE_WARN_PCT = 1.0  # a pad slope this steep, and beyond its noise, is worth a word
NOMINAL_OFF = 0.3  # C2n this far from the config's nominal: not the tyres of a test day
# the quasi-steady estimate's extrapolation to zero a_y, as simulated track laps show it (23 drives on
# each car model, tools/bench_coverage.py; docs/accuracy.md, 2026-11-28)
TRACK_LAPS = (
    "simulated track laps: within 1.0 % on one car model, 1.8 % on another, 3 in 23 outside their intervals"
)


@dataclass(frozen=True)
class Findings:
    """What the advice reads of a run: the snapshot's fields and outcomes as plain values (the
    summary fills it), the config, and how reading each log went."""

    config: Config
    reports: tuple[LogReport, ...] = ()
    frames: FrameCounts = field(default_factory=FrameCounts)
    filter_counts: FilterCounts = field(default_factory=FilterCounts)
    lost_in_samples: int = 0  # of the times the filter lost the car, those in a sample C2n rests on
    filter_lagged: bool = False  # lost in the samples, the config's process noise lowered: no C2n (Snapshot)
    result_fit: RegressionFit | None = None  # the fit the result rests on (refusal.resting_fit)
    regression: RegressionFit | None = None  # the steady samples'
    quasi: RegressionFit | None = None  # the quasi-steady samples'
    quasi_drives: tuple[RegressionFit | None, ...] = ()  # drives pooled: each one's alone
    paired: Paired | None = None
    headline: Headline | None = None
    crossings: int = 0  # sign changes fitted into crossings
    rejections: int = 0  # sign changes not used
    started: bool = False  # any frame arrived
    sign_problem: str | None = None  # refusal.sign_problem
    unsteady_crossings: str | None = None  # support.unsteady_crossings
    odd_sign: str | None = None  # signs.odd_sign, where no sign problem stands
    drives_disagree: str | None = None  # refusal.drives_disagree, or results.parts.parts_disagree
    replay_hint: str | None = None  # refusal.replay_hint
    d_witnessed: bool = False  # refusal.d_witnessed
    backwards: bool = False  # the optical speed read backwards (refusal.reads_backwards): a role's sign
    wrong_unit: bool = (
        False  # the vehicle speed's unit or sign against vx (Snapshot.unit_problem), in sign_problem
    )
    speed_reads: float | None = None  # the vehicle speed's ratio to vx, where off (speeds.reads_off)
    config_gated: bool = False  # the config's speed_min_mps above all the cornering (speed_min_problem)
    beyond_grip: bool = False  # most of the cornering beyond any tyre's grip: a unit (refusal.beyond_grip)

    @property
    def fit(self) -> RegressionFit | None:
        """The fit the advice speaks of: none where drives apart leave no pooled fit to speak of,
        or a role the wrong way round (or a filter lagging in its samples) leaves no fit's terms
        to trust."""
        untrusted = self.drives_disagree or self.sign_problem or self.filter_lagged
        return self.result_fit if not untrusted else None

    @property
    def on_quasi(self) -> bool:
        """The fit spoken of is the quasi-steady samples' (no sweep crossed zero)."""
        return self.fit is not None and self.fit is self.quasi


Said = str | tuple[str, ...] | None
Advice = Callable[[Findings], Said]


def frame_ids(config: Config, role: str) -> str:
    """The role's signal, with its frame id and channel where its DBC has them."""
    spec = config.roles[role]
    for dbc in config.dbcs:
        for message in dbc.database.messages:
            if message.name == spec.message:
                where = f" on channel {spec.channel}" if spec.channel is not None else ""
                return f"{spec.name}, id 0x{message.frame_id:X}{where}"
    return spec.name


def roles_without_frames(frames: FrameCounts, config: Config) -> list[str]:
    counts = frames.role_frames
    return [role for role in config.roles if counts[role] == 0]


def missing_required(frames: FrameCounts, config: Config) -> str | None:
    """A message naming the required role that had no frames, or None."""
    silent = set(roles_without_frames(frames, config))
    for group in REQUIRED_ROLES:
        configured = [r for r in group if r in config.roles]
        if configured and all(r in silent for r in configured):
            role = configured[0]
            return (
                f"no frames for role '{role}' ({frame_ids(config, role)}) — "
                "is the optical sensor on this bus/log and channel?"
            )
    return None


def sign_problem(f: Findings) -> str | None:
    return f.sign_problem or None


def unsteady_crossings(f: Findings) -> str | None:
    return f.unsteady_crossings or None


def odd_sign(f: Findings) -> str | None:
    return f.odd_sign or None


def logs_stopped(f: Findings) -> tuple[str, ...]:
    return tuple(f"{report.path}: {report.stopped}" for report in f.reports if report.stopped)


def silent_roles(f: Findings) -> tuple[str, ...]:
    return tuple(
        f"no frames for role '{role}' ({frame_ids(f.config, role)})"
        for role in roles_without_frames(f.frames, f.config)
    )


def no_turn_sensor(f: Findings) -> str | None:
    if "yaw_rate" in f.config.roles or "ay" in f.config.roles:
        return None
    return (
        "no yaw rate or lateral acceleration: the steady-state gate cannot check a_y or tell straight driving"
    )


def relaxed_dbcs(f: Findings) -> tuple[str, ...]:
    return tuple(
        f"{dbc.path.name} loaded with strict=False (overlapping or oversized signals)"
        for dbc in f.config.dbcs
        if dbc.relaxed
    )


def other_channel(f: Findings) -> str | None:
    if not f.frames.other_channel:
        return None
    return (
        f"{f.frames.other_channel} frames of known ids arrived on a channel their DBC "
        "is not decoded on ([channels])"
    )


def bad_length(f: Findings) -> str | None:
    counts = f.frames
    if not counts.bad_length:
        return None
    cut = sum(n for (_, kind), n in counts.bad_by_id.items() if kind == "cut")
    how = f" ({cut} with a data field cut short: a log's line or row damaged)" if cut else ""
    return f"{_frames(counts.bad_length)} not decoded: their length is not their DBC message's{how}"


def bad_time(f: Findings) -> str | None:
    if not f.frames.bad_time:
        return None
    return (
        f"{_frames(f.frames.bad_time)} without a usable timestamp (NaN, infinite, or beyond ±10¹⁵ s: a clock "
        "in µs or ns since 1970?): not used"
    )


def values_dropped(f: Findings) -> tuple[str, ...]:
    return tuple(
        f"{_frames_whose(n)} values dropped: {reason}" for reason, n in f.frames.rejected.most_common()
    )


def _frames(n: int) -> str:
    return "1 frame" if n == 1 else f"{n} frames"


def _frames_whose(n: int) -> str:
    return "1 frame's" if n == 1 else f"{n} frames'"


def time_jumps(f: Findings) -> str | None:
    jumps = f.filter_counts.time_jumps
    times = "once" if jumps == 1 else f"{jumps} times"
    return f"timestamps went backwards {times}: the filter restarted" if jumps else None


def optical_gaps(f: Findings) -> str | None:
    gaps = f.filter_counts.resets - f.filter_counts.time_jumps
    if not gaps:
        return None
    return (
        f"the optical data stopped {'once' if gaps == 1 else f'{gaps} times'} for over "
        f"{f.config.filter.gap_reset_s:g} s: the filter restarted"
    )


_SENSOR = {"vx": "optical vx", "speed": "vehicle speed", "lateral": "optical lateral", "yaw": "yaw"}


def _setting(key: str, value: float, default: float) -> str:
    """A [filter] key with its value, and its default where the value is not it."""
    return f"{key} ({value:g})" if value == default else f"{key} ({value:g}; default {default:g})"


def filter_lost(f: Findings) -> str | None:
    """The filter left behind by the car where C2n is measured: a sensor's frames beyond the gate
    several times running in a steady or quasi-steady sample, which its noise model gives no
    chance (FilterCounts). Its speeds and sideslip lag there, and C2n with them: on a standard
    session q_u = 1e-3 read C2n unchanged, 1e-5 +2.3 %, 1e-6 +18 % (docs/method.md). A loss
    elsewhere (a hard stop, a reversal) touches no sample: counted in the result file, not said."""
    lost = f.filter_counts.lost
    if not lost or not f.lost_in_samples or f.backwards or f.wrong_unit:  # the result names those
        return None
    settings, default = f.config.filter, FilterSettings()
    times = sum(lost.values())
    where = ", ".join(f"{_SENSOR[kind]} {n:,}" for kind, n in lost.items())
    gate = settings.innovation_gate
    if "speed" in lost and f.speed_reads is not None:  # the speed's own scale, not the filter's
        scale = f.config.roles["speed"].scale / f.speed_reads
        fix = f"set [roles] speed's scale = {scale:.3g}, or leave the role out"
        return (
            f"the filter lost the car {times:,} time{'s' if times != 1 else ''} ({where}) while the vehicle "
            f"speed reads {f.speed_reads:.2f} × the optical vx (a speedometer's reading, or a scale off) "
            f"— {fix}"
        )
    if gate < default.innovation_gate:  # a narrow gate rejects the sensor's own noise: it first
        knobs = _setting("innovation_gate", gate, default.innovation_gate)
    else:
        knobs = ", ".join(
            _setting(q, getattr(settings, q), getattr(default, q))
            for q in sorted({FOLLOWS[kind] for kind in lost})
        )
    return (
        f"the filter lost the car {times:,} time{'s' if times != 1 else ''} ({where}: frames beyond its "
        f"innovation gate {MAX_CONSECUTIVE_REJECTS} running, then believed), and in {f.lost_in_samples:,} "
        "samples of the cornering C2n is measured on: its speeds and sideslip lagged the car there, "
        f"and C2n with them — raise [filter] {knobs}, or check the sensor's signal"
    )


def d_disagrees(f: Findings) -> str | None:
    """The fitted sensor position outside its interval's reach of the config's."""
    fit, d_m = f.fit, f.config.d_m
    if fit is None or fit.d.ci95_m[0] <= d_m <= fit.d.ci95_m[1]:
        return None
    low, high = fit.d.ci95_m
    return (
        f"the fitted sensor position d = {fit.d.m:.3f} m [{low:.3f}, {high:.3f}] disagrees with the "
        f"config's {d_m:g} m: check sensor_ahead_of_rear_axle_m (the crossings' C2n scales "
        "with d; the regression's does not)"
    )


def crossings_apart(f: Findings) -> str | None:
    """Where the paired crossings' interval and the regression's headline's do not meet: which to
    believe, and why they differ."""
    head, paired = f.headline, f.paired
    if head is None or head.method is not Method.REGRESSION or paired is None:
        return None
    (low, high), (h_low, h_high) = paired.ci95, head.ci95
    if low <= h_high and h_low <= high:
        return None
    return (
        f"the paired crossings read {paired.c2n:.3f} {bracket(paired.ci95)}, apart from the "
        f"regression's {head.c2n:.3f}: each crossing rests on one speed and the config's d (eq. 7) "
        "and carries what the regression fits beside C2n (a head's yaw where only one direction "
        "crossed, the tyres' secant beyond its a_y, a tight turn's two wheels) — the regression's C2n "
        "is the result"
    )


def idle_drives(f: Findings) -> str | None:
    """Drives pooled that had too little quasi-steady cornering to be fitted alone."""
    idle = [str(k) for k, alone in enumerate(f.quasi_drives, 1) if alone is None]
    if not f.on_quasi or not idle:
        return None
    return (
        f"drive {', '.join(idle)} of the {len(f.quasi_drives)} pooled has too little "
        "quasi-steady cornering to be fitted alone (`cornering` counts why: tight turns, a_y beyond "
        "the linear range, transients): the pooled C2n rests on the others"
    )


def d_from_tape(f: Findings) -> str | None:
    """Where C2n rests on the config's d rather than the drive's: why, and how to measure both."""
    fit, config = f.fit, f.config
    if fit is None:
        return None
    tape = f"±{config.calibration.d_tolerance_mm:g} mm"
    if fit.d.held and f.on_quasi:
        return (
            f"quasi-steady cornering cannot place the sensor's d beside C2n as a sweep does: d is the "
            f"config's {config.d_m:g} m (its interval counts the tape's {tape}) — measure it with a tape"
        )
    if fit.d.held_tight:
        wheelbases = TIGHT_WHEELBASES * (config.vehicle.wheelbase_m or WHEELBASE_M)
        return (
            f"most steady samples turned on radii under {wheelbases:.0f} m ({TIGHT_WHEELBASES:g} "
            f"wheelbases), where the sensor's d cannot be fitted beside C2n: d is the config's "
            f"{config.d_m:g} m, and each cm of d moves C2n by {fit.d.per_tape_cm_pct or 0.0:.1f} % here "
            f"(its interval counts the tape's {tape}) — measure d to the millimetre, or sweep on wider "
            "circles"
        )
    if fit.d.held:
        low, high = fit.samples.speed_range_mps
        return (
            f"the steady samples span {low:.1f}–{high:.1f} m/s only: too narrow to fit the sensor's d beside "
            f"C2n, so d is the config's {config.d_m:g} m (its interval counts the tape's {tape}); sweep the "
            "speed through u0 to measure both"
        )
    apart = not fit.d.ci95_m[0] <= config.d_m <= fit.d.ci95_m[1]  # d_disagrees says so: not resting on it
    if fit.d.information is not None and fit.d.information < 1.0 and not apart:
        low, high = fit.samples.speed_range_mps
        steady = f"the steady samples ({low:.1f}–{high:.1f} m/s) place"
        where = "quasi-steady cornering places" if f.on_quasi else steady
        return (
            f"{where} the sensor's d less well than the tape does ({fit.d.information:.2f} of its "
            f"information): C2n rests on the config's {config.d_m:g} m more than on the drive (its interval "
            f"counts the tape's {tape}); sweep the speed through u0 on two radii to measure both"
        )
    return None


def softening(f: Findings) -> str | tuple[str, ...] | None:
    """The tyres soften with slip: C2n is the fit's extrapolation to zero a_y; where they soften so
    much that the series' next term, left out, moves C2n beyond its interval, that too."""
    fit = f.fit
    if fit is None or fit.models.chosen != "softening":
        return None
    beside = (  # the marginal fit has the softening in its model whatever the drive: no other line
        "its interval counts the softening's spread"
        if fit.estimator == "marginal"
        else f"a straight-line fit would give {fit.models.linear.c2n:.3f}"
    )
    said = (
        f"the tyres soften with slip (t = {fit.models.softening_t:.1f}): C2n is extrapolated to zero "
        f"lateral acceleration ({fit.c2n:.3f}; {beside})"
    )
    strong = fit.softening.next_term_pct if fit.softening else 0.0
    upper_pct = 100.0 * (fit.c2n_ci95[1] - fit.c2n) / fit.c2n
    if strong <= upper_pct:  # the lesser part of the interval's lower side
        return said
    top = fit.samples.ay_range_mps2[1]
    assert fit.softening is not None
    more = 100.0 * fit.softening.per_mps2_2 * top * top
    return (
        said,
        f"the tyres soften strongly (the rear slip {more:.0f} % above the linear at {top:.1f} m/s²): "
        f"the softening's next term, which the model leaves out, reads C2n about {strong:.1f} % high "
        "(r = 1, a stiffness falling with load), so the interval reaches that much further down; set "
        "[priors] softening_ratio = 4.75 and softening_ratio_sd = 3.75 to fit it, or keep the "
        "steady samples to a lower a_y ([detector] ay_max_mps2)",
    )


def softening_unresolved(f: Findings) -> str | None:
    """The a_y range too narrow to tell linear tyres from softening ones."""
    fit = f.fit
    if fit is None or fit.models.resolved:
        return None
    low, high = fit.samples.ay_range_mps2
    return (
        f"the steady samples span a_y {low:.1f}–{high:.1f} m/s² only: too narrow to tell linear tyres "
        f"from softening ones (a softening of {fit.models.hidden_pct:.0f} % could hide in it), so the "
        "interval covers both; steady laps at lower a_y (slower, or a larger circle) would narrow it"
    )


def slope(f: Findings) -> str | None:
    """A slope the regression found: where it falls, that it is taken out of C2n, and that the
    crossings (each at one heading) still carry it."""
    found = f.fit.slope if f.fit is not None else None
    if found is None or found.pct < SLOPE_WARN_PCT or found.ci95_pct[0] <= 0.0:
        return None
    towards = found.downhill_deg
    side = "left" if towards >= 0 else "right"
    low, high = found.ci95_pct
    return (
        f"the test pad slopes {found.pct:.1f} % [{low:.1f}, {high:.1f}] "
        f"(falling {abs(towards):.0f}° {side} of the start heading): the regression takes it out of C2n; "
        "each crossing happens at one heading and carries it — pair left and right circles, or find a "
        "level pad"
    )


def turn_force(f: Findings) -> str | None:
    """A rear force following the turn's direction, not its size."""
    turn = f.fit.turn_force if f.fit is not None else None
    if turn is None:
        return None
    low, high = turn.ci95_pct
    return (
        f"the rear tyres make a force that follows the turn's direction, not its size: "
        f"{turn.pct:+.2f} % [{low:+.2f}, {high:+.2f}] of the axle's weight (towards the "
        "turn's inside; a tyre's camber step, friction in the suspension): the regression takes it out "
        "of C2n; each crossing carries it (it moves the sign change as a sensor d·κ further ahead would)"
    )


def yaw_bias(f: Findings) -> str | None:
    """Where the quasi-steady fit found the yaw rate biased (its interval clear of zero)."""
    found = f.fit.yaw_bias if f.fit is not None else None
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


def sideslip_flip(f: Findings) -> str | None:
    """Circles at one speed cannot show a sideslip the wrong way round: nothing in them places d,
    and with β turned over they read 1/(g·(2d/u² − 1/(g·C2n))) for C2n. Where the config's nominal
    C2n is far from the reading and near what the other sign gives, say so."""
    fit, config = f.fit, f.config
    nominal = config.tyres.c2n_per_rad
    if fit is None or not nominal or f.d_witnessed or not fit.c2n > 0:
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


def replay_hint(f: Findings) -> str | None:
    return f.replay_hint or None


def crossing_beyond_gate(f: Findings) -> str | None:
    """Where no crossing was found on circles whose u0 lies beyond the a_y gate: the words saying
    so (the sideslip changed sign where the tyres are no longer linear, so nothing was counted).
    Not where the sideslip may be the wrong way round (``sideslip_flip``): its u0 is the reading's."""
    fit, limit = f.regression, f.config.detector.ay_max_mps2
    if f.crossings or fit is None or f.sign_problem or not fit.c2n > 0 or sideslip_flip(f) is not None:
        return None
    curvature = fit.samples.curvature_range_per_m[0]  # the largest circle driven
    if not curvature > 0 or fit.d.m <= 0:
        return None
    u0_squared = f.config.vehicle.gravity_mps2 * fit.c2n * fit.d.m
    ay_at_u0 = u0_squared * curvature
    if ay_at_u0 <= limit:
        return None
    return (
        f"on the largest circle driven (radius {1 / curvature:.0f} m) the sideslip changes sign at a_y ≈ "
        f"{ay_at_u0:.1f} m/s², beyond the tyres' linear range ({limit:g} m/s², [detector] ay_max_mps2), "
        f"so no crossing was counted: drive a circle of radius ≥ {1.2 * u0_squared / limit:.0f} m to meet "
        f"u0 ≈ {math.sqrt(u0_squared):.1f} m/s within it"
    )


def head_yawed(f: Findings) -> str | None:
    """Left and right turns' crossings disagree by a yaw of the sensor head."""
    paired = f.paired
    yaw, yaw_se = (paired.misalignment_rad, paired.misalignment_se) if paired is not None else (None, None)
    if yaw is None or yaw_se is None or not abs(yaw) > max(Z95 * yaw_se, math.radians(0.1)):
        return None
    return (
        f"the sensor head looks yawed by {math.degrees(yaw):+.2f}° (left and right turns disagree); "
        "pairing and the regression remove it, but align the head"
    )


def rejected_crossings(f: Findings) -> str | None:
    return f"{f.rejections} sign changes not used (see 'rejected_crossings')" if f.rejections else None


def no_crossing(f: Findings) -> str | None:
    """No sweep crossed zero: the quasi-steady estimate, what it counts, and how to measure C2n
    the method's own way; or, without even that, that no sign change was found."""
    if (
        f.backwards or f.config_gated or f.beyond_grip
    ):  # no driving to blame: the result names a role, or the config
        return None
    beyond = crossing_beyond_gate(f)
    if f.headline is not None and f.headline.method is Method.QUASI_STEADY:
        fit = f.fit
        low = f" from {fit.samples.ay_range_mps2[0]:.1f} m/s²" if fit is not None else ""
        counts = (
            "the samples' noise and the softening's spread under its prior"
            if fit is not None and fit.estimator == "marginal"
            else "the samples' noise, not the model's reach"
        )
        return (
            "no sweep crossed the sideslip's sign change: C2n is the quasi-steady estimate from cornering "
            "as driven (its model adds the yaw inertia's and braking's share of the rear tyres' force), "
            f"the corners' curve{low} extrapolated to zero lateral acceleration; its interval counts "
            f"{counts} ({TRACK_LAPS})"
            + (
                " — sweep the speed through u0 on a circle to measure it the method's own way"
                if beyond is None
                else ""
            )
        )
    sensed = missing_required(f.frames, f.config) is None  # without the sensor, no sideslip to change sign
    if f.started and not f.crossings and beyond is None and sensed:
        return "no sideslip sign change was found in steady cornering: sweep the speed through u0 on a circle"
    return None


ADVICE: tuple[Advice, ...] = (
    sign_problem,
    unsteady_crossings,
    odd_sign,
    logs_stopped,
    silent_roles,
    no_turn_sensor,
    relaxed_dbcs,
    other_channel,
    bad_length,
    bad_time,
    values_dropped,
    time_jumps,
    optical_gaps,
    filter_lost,
    d_disagrees,
    crossings_apart,
    idle_drives,
    d_from_tape,
    softening,
    softening_unresolved,
    slope,
    turn_force,
    yaw_bias,
    sideslip_flip,
    replay_hint,
    crossing_beyond_gate,
    head_yawed,
    rejected_crossings,
    no_crossing,
)


def advise(findings: Findings, advice: tuple[Advice, ...] = ADVICE) -> list[str]:
    """Each advice function's line(s), in the registry's order."""
    out: list[str] = []
    for said in (one(findings) for one in advice):
        if isinstance(said, str):
            out.append(said)
        elif said:
            out.extend(said)
    return out
