"""The session summary: what ``c2n analyze --json``, ``c2n export`` and a live session write.

``Summary`` is the result file in typed form, its fields the file's keys (stable:
docs/result-file.md), its numbers rounded as the file holds them, so the report shows what the file
says. ``build`` makes it from a Snapshot; ``to_json`` gives the file's content.
"""

import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict, astuple, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Literal

from app import __version__
from app.config import Config
from app.detect.signs import SignVotes
from app.detect.speeds import reads_off
from app.output.files import json_ready, write_json
from app.records import Crossing, CrossingRejected, Direction, Sweep
from app.results import advice, refusal
from app.results.combine import Combined
from app.results.pairing import Paired
from app.results.parts import Part
from app.results.regression import RegressionFit
from app.snapshot import Snapshot
from app.sources.logs import LogReport

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
    softening_next_term_pct: float | None  # C2n read high by the series' next term, left out
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
    backwards_s: float  # cornering with the optical speed backwards: vx's sign flipped, the head turned
    below_speed_s: float  # in a turn, but under [detector] speed_min_mps
    beyond_grip_s: float  # of turning_s, |a_y| beyond any tyre's grip (3 g): a yaw rate's unit, not the car


@dataclass(frozen=True)
class PartRow:
    """A live run's part between its optical sensor's pauses, alone (``results/parts.py``)."""

    from_s: float | None  # s since the first frame: its first frame, its sensor's last
    to_s: float | None
    c2n: float | None  # its own headline; null where it has none
    c2n_ci95: Interval | None
    c2n_method: str | None


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
    lost_vx: int = 0  # times the filter lost the car on each sensor (FilterCounts)
    lost_lateral: int = 0
    lost_speed: int = 0
    lost_yaw: int = 0
    lost_in_samples: int = 0  # of those, in a steady or quasi-steady sample: said in the warnings
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
    no_result: str | None = None  # why there is no C2n (the terminal's "C2n: no result (…)"), else null
    combined: CombinedRow | None = None
    rejected_crossings: tuple[RejectedRow, ...] = ()
    quasi_steady: RegressionRow | None = None  # the quasi-steady samples' fit, where no sweep crossed zero
    cornering: CorneringRow | None = None
    quasi_steady_drives: tuple[RegressionRow | None, ...] = ()  # drives pooled: each one's fit alone
    parts: tuple[PartRow, ...] = ()  # c2n live: the parts between the optical sensor's pauses, each alone
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
        no_result=snapshot.refusal if headline is None and snapshot.t_first is not None else None,
        c2n_scale_se_pct=_round(100.0 * config.calibration.c2n_se(headline.method.is_fit, config.d_m))
        if headline
        else None,
        u0_mps=_round(u0) if u0 is not None else None,
        crossings=tuple(_crossing(c, t0) for c in snapshot.crossings),
        regression=_regression(snapshot.regression),
        quasi_steady=_regression(snapshot.quasi),
        cornering=CorneringRow(*(round(getattr(snapshot.cornering, f.name), 1) for f in fields(CorneringRow)))
        if snapshot.t_first is not None
        else None,
        quasi_steady_drives=tuple(_regression(fit) for fit in snapshot.quasi_drives)
        if snapshot.quasi is not None
        else (),
        parts=tuple(_part(p, t0) for p in snapshot.parts),
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
            lost_in_samples=snapshot.filter.lost_in_samples,
            health=_round(snapshot.filter.health, 3),
            noise={k: _round(v, 5) for k, v in snapshot.filter.noise_sigma.items()},
        ),
    )


def write(path: Path, summary: Summary) -> None:
    """Write atomically: a crash leaves the old file or the new one, never half of one."""
    write_json(path, summary.to_json(), "the summary")


def roles_without_frames(snapshot: Snapshot, config: Config) -> list[str]:
    return advice.roles_without_frames(snapshot.frames, config)


def missing_required(snapshot: Snapshot, config: Config) -> str | None:
    """A message naming the required role that had no frames, or None."""
    return advice.missing_required(snapshot.frames, config)


def findings(snapshot: Snapshot, config: Config, reports: Sequence[LogReport] = ()) -> advice.Findings:
    """What the advice reads of the run (``results/advice.py``)."""
    cornering = snapshot.cornering
    return advice.Findings(
        config=config,
        reports=tuple(reports),
        frames=snapshot.frames,
        filter_counts=snapshot.filter.counts,
        result_fit=snapshot.fit,
        regression=snapshot.regression,
        quasi=snapshot.quasi,
        quasi_drives=snapshot.quasi_drives,
        paired=snapshot.paired,
        headline=snapshot.headline,
        crossings=len(snapshot.crossings),
        rejections=len(snapshot.rejections),
        started=snapshot.t_first is not None,
        sign_problem=snapshot.sign_problem,
        unsteady_crossings=snapshot.unsteady_crossings,
        odd_sign=snapshot.odd_sign,
        drives_disagree=snapshot.parts_disagree or snapshot.drives_disagree,
        replay_hint=snapshot.replay_hint,
        d_witnessed=snapshot.d_witnessed,
        backwards=refusal.reads_backwards(cornering.backwards_s, cornering.turning_s) is not None,
        wrong_unit=snapshot.unit_problem is not None,
        speed_reads=reads_off(snapshot.speeds),
        config_gated=refusal.speed_min_problem(cornering, snapshot.speed_min_mps) is not None,
        beyond_grip=refusal.beyond_grip(cornering) is not None,
        lost_in_samples=snapshot.filter.lost_in_samples,
        filter_lagged=snapshot.filter_lagged,
    )


def warnings(snapshot: Snapshot, config: Config, reports: Sequence[LogReport] = ()) -> list[str]:
    """What the user should know about the run, one line each: what ``results/advice.py``'s
    registry says, in its order."""
    return advice.advise(findings(snapshot, config, reports))


def _sign_votes(votes: SignVotes) -> SignVotesRow | None:
    row = SignVotesRow(votes.ay_with, votes.ay_against, votes.steer_with, votes.steer_against)
    return row if any(astuple(row)) else None  # no cornering, or no a_y or steering to vote


def format_id(frame_id: int, extended: bool) -> str:
    """0x7E5 for an 11-bit id, 0x000007E5 for a 29-bit one, as CAN tools write them."""
    return f"0x{frame_id:08X}" if extended else f"0x{frame_id:X}"


def _round(value: float, digits: int = 4) -> float | None:
    return round(float(value), digits) if math.isfinite(value) else None


def _maybe(value: float | None, digits: int = 4, scale: float = 1.0) -> float | None:
    return None if value is None else _round(value * scale, digits)


def _pair(values: tuple[float, float], scale: float = 1.0, digits: int = 4) -> Interval:
    return (_round(values[0] * scale, digits), _round(values[1] * scale, digits))


def _part(part: Part, t0: float) -> PartRow:
    headline = part.headline
    return PartRow(
        from_s=_round(part.begin_t - t0, 3),
        to_s=_round(part.end_t - t0, 3),
        c2n=_round(headline.c2n) if headline else None,
        c2n_ci95=_pair(headline.ci95) if headline else None,
        c2n_method=headline.method.value if headline else None,
    )


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
        softening_next_term_pct=_maybe(fit.softening.next_term_pct if fit.softening else None, 3),
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


def _paired(paired: Paired | None) -> PairedRow | None:
    if paired is None:
        return None
    deg = math.degrees(1.0)
    misalignment, lag = paired.misalignment_ci95_rad, paired.lag_ci95_s
    return PairedRow(
        c2n=_round(paired.c2n),
        c2n_ci95=_pair(paired.ci95),
        misalignment_deg=_round(paired.misalignment_rad * deg)
        if paired.misalignment_rad is not None
        else None,
        misalignment_ci95_deg=_pair(misalignment, deg) if misalignment is not None else None,
        lag_s=_maybe(paired.lag_s),
        lag_ci95_s=_pair(lag) if lag is not None else None,
        cancels=tuple(paired.cancels),
        cells={key: _round(value) for key, value in paired.cells.items()},
        n=paired.n,
        birge_ratio=_round(paired.birge_ratio, 3),
    )


def _combined(combined: Combined) -> CombinedRow:
    return CombinedRow(combined.n, _round(combined.birge_ratio, 3), _round(combined.se, 5))
