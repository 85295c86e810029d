"""The one pipeline: frame → decode → estimate → steady-state gate → crossing detector.

Live and offline runs differ only in where the frames come from; both call ``process`` for each
frame in arrival order and ``finish`` at the end, so the same frames give the same crossings.
A bulk reader may hand over frames as a FrameBlock instead (``c2n analyze`` on MF4):
``process_block`` leaves the pipeline as ``process`` over its frames one by one would
(tests/test_blocks.py). A block goes through two stages: ``filter_block`` (the filter, the gates
and the heading, vectorised over the block) and ``take_filtered`` (the detector and the
regressions, row by row); the second needs nothing the first does not hand it, so ``c2n gap``
runs it in a forked process beside the diagnosis (app/gap/measured.py).
"""

import copy
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field, replace
from types import MappingProxyType
from typing import TypeVar

import can
import numpy as np

from app.config import OPTICAL_ROLES, Config, lowered_filter, raised_noise
from app.decode.decoder import Decoder
from app.detect.crossings import CrossingDetector
from app.detect.quasi_steady import QuasiSteadyGate
from app.detect.signs import SignVotes
from app.detect.speeds import SpeedVotes
from app.detect.steady_state import DIRECTIONS, STEADY, WHEELBASE_M, SteadyStateGate
from app.estimate.compiled import CompiledMotionFilter, estimate_of
from app.records import Crossing, CrossingRejected, Direction, Estimate, Event, Record, SteadyState
from app.results.combine import Combined, combine
from app.results.crossing_slope import with_tilt
from app.results.heading import Heading
from app.results.log_clock import sensor_messages
from app.results.pairing import Paired, pair
from app.results.parts import Part, parts_disagree
from app.results.regression import RegressionFit, SampleRegression
from app.results.secant import at_zero_ay
from app.results.sideslip_profile import SideslipProfile
from app.results.turn_step import without_step
from app.snapshot import FilterState, Pending, Snapshot
from app.sources.blocks import FrameBlock, RecordBlock

BlockHook = Callable[[RecordBlock, np.ndarray, np.ndarray, np.ndarray, np.ndarray], None]
_FILTER_ROLES = frozenset({"vx", "vy", "beta", "speed", "yaw_rate", "ay"})
_OPTICAL = frozenset(OPTICAL_ROLES)
_LATERAL = {"beta": ("beta",), "vy": ("vy",), "auto": ("beta", "vy")}  # what sideslip_source allows
_R = Estimate._fields.index("r_radps")  # the yaw rate's column of the filter's estimates
_V_MEAS = Estimate._fields.index("v_meas_mps")  # the measured lateral velocity's
_FIRST_STAGE_FIELDS = (  # the Snapshot's fields that the decoder and ``filter_block`` make
    "t_first",
    "t_last",
    "latest",
    "sensor_problem",
    "cornering",
    "speeds",
    "frames",
    "status",
    "filter",
    "message_names",
)
_REFIT_EVERY_S = 2.0  # frame time between live refits of the regression


@dataclass
class SessionState:
    """What the run has produced so far: the pipeline's own, mutable; the sinks read a Snapshot."""

    t_first: float | None = None
    t_last: float | None = None
    latest: dict[str, float] = field(default_factory=dict)  # role -> last usable value
    last: Record | None = None  # last record with an estimate
    sensor_problem: str | None = None  # why optical samples are being dropped, if they are
    crossings: list[Crossing] = field(default_factory=list)
    rejections: list[CrossingRejected] = field(default_factory=list)
    combined: Combined | None = None  # inverse-variance mean of the crossings
    paired: Paired | None = None  # crossings with misalignment and lag removed
    regression: RegressionFit | None = None  # every steady sample: the headline C2n
    quasi: RegressionFit | None = None  # every quasi-steady sample, while no sweep crossed zero
    quasi_drives: tuple[RegressionFit | None, ...] = ()  # drives pooled: each one's alone, at the end
    signs: SignVotes = field(default_factory=SignVotes)  # do a_y and the steering turn with the yaw rate?
    speeds: SpeedVotes = field(default_factory=SpeedVotes)  # do the vehicle speed and vx agree in size?


@dataclass(frozen=True)
class Filtered:
    """A block's rows as the filter and the gates took them (``Pipeline.filter_block``): what the
    detector and the regressions take row by row (``Pipeline.take_filtered``)."""

    t: np.ndarray  # the rows' times
    out: np.ndarray  # their estimates: rows of Estimate's fields, NaN for None
    kinds: list[int]  # the steady-state gate's decision (STEADY, HARD, SOFT, SETTLING)
    directions: list[int]  # its direction, an index into DIRECTIONS
    quasi: np.ndarray  # bool: the quasi-steady gate held, with a measured lateral velocity
    headings: np.ndarray  # the integrated heading (rad)
    ay: np.ndarray  # the lateral acceleration and the steering held at each row (the sign votes')
    steer: np.ndarray
    last: Record  # the block's last row, its events still to come


class Pipeline:
    def __init__(self, config: Config) -> None:
        self.config = config
        self.decoder = Decoder(config)
        self.filter = CompiledMotionFilter(
            config.filter,
            config.vehicle.sensor_lateral_m,
            frozenset(config.roles),
            {role: spec.resolution for role, spec in config.roles.items()},
        )
        self._lost_in_samples = 0  # samples the estimates take where the filter lost the car
        self.gate = SteadyStateGate(config.detector, config.vehicle.wheelbase_m)
        self._ay_votes = "yaw_rate" in config.roles  # without a gyro a_y gives the yaw rate: no vote on it
        self.detector = CrossingDetector(config.detector, config.d_m, config.vehicle.gravity_mps2)
        self.regression = self._sample_regression(transient=False)
        self.quasi_gate = QuasiSteadyGate(config.detector, config.vehicle.wheelbase_m)
        self.quasi = self._sample_regression(transient=True)
        self._drives: list[SampleRegression] = []  # drives pooled: each one's quasi-steady samples alone
        self.heading = Heading()
        self.profile = SideslipProfile()
        self.state = SessionState(speeds=SpeedVotes(config.detector.speed_min_mps))
        self._speed_votes = {"vx", "speed"} <= config.roles.keys()  # two measures of u to compare
        # the config's process noises against their defaults, said where a refusal names them
        self._raised_noise, self._lowered_filter = raised_noise(config.filter), lowered_filter(config.filter)
        self._speed_t = -math.inf  # the latest vehicle speed's time: a vote takes it while fresh
        self._fresh_s = config.filter.status_timeout_s  # older than this a value is unknown
        self._last_fit = -float("inf")
        self._fitted_on: tuple[int, int, bool] | None = None  # what the last refit saw (``_refit``)
        # Called by ``take_block`` with each block, the rows the filter took, their estimates (rows
        # of Estimate's fields, NaN for None), the gate's kinds and directions: what a Record
        # would carry, for a sink of blocks (app/sinks/trace.py's TraceBlocks).
        self.on_block: BlockHook | None = None

    def snapshot(self, first_stage: Snapshot | None = None) -> Snapshot:
        """The run as it stands, for the sinks: frozen, and copies of what changes. Where the
        first stage (``filter_block``) ran in another pipeline, which handed its blocks over to
        this one's second, ``first_stage`` is that one's snapshot: the fields it made come from it."""
        state, f = self.state, self.filter
        snapshot = Snapshot(
            t_first=state.t_first,
            t_last=state.t_last,
            last=state.last,
            latest=MappingProxyType(dict(state.latest)),
            sensor_problem=state.sensor_problem,
            crossings=tuple(state.crossings),
            rejections=tuple(state.rejections),
            combined=state.combined,
            paired=state.paired,
            regression=state.regression,
            quasi=state.quasi,
            quasi_drives=state.quasi_drives,
            cornering=self.quasi_gate.cornering,
            signs=state.signs.copy(),
            speeds=state.speeds.copy(),
            pending=tuple(Pending(direction, t, u) for direction, t, u in self.detector.pending),
            frames=self.decoder.counts.copy(),
            status=MappingProxyType(dict(self.decoder.status.values)),
            filter=FilterState(
                replace(f.counts), f.health, MappingProxyType(f.noise_sigma()), self._lost_in_samples
            ),
            message_names=self.decoder.message_names,
            d_m=self.config.d_m,
            g_mps2=self.config.vehicle.gravity_mps2,
            profile=self.profile.view(),
            settle_s=self.config.detector.settle_s,
            speed_min_mps=self.config.detector.speed_min_mps,
            vx_scale=self.config.roles["vx"].scale if "vx" in self.config.roles else 1.0,
            speed_scale=self.config.roles["speed"].scale if "speed" in self.config.roles else 1.0,
            raised_noise=self._raised_noise,
            lowered_filter=self._lowered_filter,
        )
        if first_stage is None:
            return snapshot
        return replace(snapshot, **{name: getattr(first_stage, name) for name in _FIRST_STAGE_FIELDS})

    def process(self, msg: can.Message) -> Record | None:
        """Take one frame; return its Record (None for frames that carry no role value)."""
        record = self.decoder.decode(msg)
        return None if record is None else self.take(record)

    def _optical_problem(self, rejected: Mapping[str, str], usable: Mapping[str, float]) -> str | None:
        """Why this frame's optical samples cannot be used: its vx was dropped, or every lateral
        measurement the filter may take (``sideslip_source``: the angle, vy, or either) was. An
        angle gated off (``[beta_status]``) beside a good vy is no problem where vy may be used."""
        if "vx" in rejected:
            return rejected["vx"]
        lateral = _LATERAL[self.config.filter.sideslip_source]
        dropped = [rejected[role] for role in lateral if role in rejected]
        if dropped and not any(role in usable for role in lateral):
            return dropped[0]
        return None

    def take(self, record: Record) -> Record:
        """Take one decoded frame (``process`` after the decoder): the Record with what the
        filter, the gates and the detector made of it. Its estimate goes on as ``take_filtered``'s
        rows do (``_route``)."""
        state = self.state
        if state.t_first is None:
            state.t_first = record.t
        state.t_last = record.t
        state.latest.update(record.signals)
        if self._speed_votes:
            if "speed" in record.signals:
                self._speed_t = record.t
            elif record.t >= state.speeds.next_t and "vx" in record.signals:
                fresh = record.t - self._speed_t <= self._fresh_s
                state.speeds.add(record.t, state.latest["speed"] if fresh else math.nan, record.signals["vx"])
        problem = self._optical_problem(record.rejected, record.signals) if record.rejected else None
        if problem:
            state.sensor_problem = problem
        elif state.sensor_problem is not None and not _OPTICAL.isdisjoint(record.signals):
            state.sensor_problem = None
        if _FILTER_ROLES.isdisjoint(record.signals):
            return record
        estimate = self.filter.step(record)
        if estimate is None:
            return record
        heading = self.heading.step(record.t, estimate.r_radps)
        latest = state.latest
        steady = self.gate.step(record.t, estimate, latest.get("steer"), state.sensor_problem)
        quasi = self.quasi_gate.step(record.t, estimate, state.sensor_problem is None)
        if (steady.steady or quasi) and self.filter.lost_now:
            self._lost_in_samples += 1
        events = self._route(
            record.t,
            estimate,
            steady.steady,
            steady.direction,
            quasi,
            heading,
            latest.get("ay") if self._ay_votes else None,
            latest.get("steer"),
        )
        record = Record(  # not dataclasses.replace: this runs for every filtered frame
            record.t,
            record.channel,
            record.frame_id,
            record.signals,
            record.rejected,
            estimate,
            steady,
            tuple(events),
        )
        state.last = record
        return record

    def process_block(self, block: FrameBlock) -> list[Event]:
        """Take a block of frames: what ``process`` over each would do. Returns the events."""
        return self.take_block(self.decoder.decode_block(block))

    def take_block(self, block: RecordBlock) -> list[Event]:
        """``take`` over a block of decoded frames: its two stages, ``filter_block`` (the filter and
        the gates over the whole block at once) and ``take_filtered`` (the detector and the
        regressions, which see the estimates one by one). Returns the events, in order."""
        filtered = self.filter_block(block)
        return [] if filtered is None else self.take_filtered(filtered)

    def filter_block(self, block: RecordBlock) -> "Filtered | None":
        """The first stage of ``take_block``: the filter, the gates and the heading over the block's
        rows, which ``on_block`` hears; None where the filter took no row. It needs nothing the
        second stage makes, so a caller may hold its blocks and take them later (``c2n gap``)."""
        n = len(block)
        if n == 0:
            return None
        state, t = self.state, block.t
        if state.t_first is None:
            state.t_first = float(t[0])
        state.t_last = float(t[-1])
        steer = _held(block.values.get("steer"), state.latest.get("steer"), n)
        ay = (
            _held(block.values.get("ay"), state.latest.get("ay"), n) if self._ay_votes else np.full(n, np.nan)
        )
        if self._speed_votes:
            self._vote_speeds(block, n)
        for role, column in block.values.items():
            given = np.flatnonzero(~np.isnan(column))
            if len(given):
                state.latest[role] = float(column[given[-1]])
        problems, problem_texts = self._sensor_problems(block)
        filtered = np.zeros(n, bool)
        for role in _FILTER_ROLES.intersection(block.values):
            filtered |= ~np.isnan(block.values[role])
        rows = np.flatnonzero(filtered)
        valid, out, lost = self.filter.steps(
            t[rows], {role: column[rows] for role, column in block.values.items()}
        )
        rows, out, lost = rows[valid], out[valid], lost[valid]
        if not len(rows):
            if self.on_block is not None:
                self.on_block(block, rows, out, np.zeros(0, np.int64), np.zeros(0, np.int64))
            return None
        kinds, directions, held = self.gate.steps(t[rows], out, steer[rows], problems[rows] < 0)
        quasi = self.quasi_gate.steps(t[rows], out, problems[rows] < 0)
        if lost.any():  # where the filter lost the car in a sample the estimates take
            self._lost_in_samples += int(np.count_nonzero(lost & (np.equal(kinds, STEADY) | quasi)))
        if self.on_block is not None:
            self.on_block(block, rows, out, np.asarray(kinds), np.asarray(directions))
        last, k = int(rows[-1]), len(rows) - 1
        estimate = estimate_of(out[k].tolist())
        problem = problem_texts[problems[last]] if problems[last] >= 0 else None
        return Filtered(
            t=t[rows],
            out=out,
            kinds=kinds,
            directions=directions,
            quasi=quasi & ~np.isnan(out[:, _V_MEAS]),
            headings=self.heading.steps(t[rows], out[:, _R]),
            ay=ay[rows],
            steer=steer[rows],
            last=Record(
                float(t[last]),
                block.channel[last],
                block.frame_id[last],
                block.signals(last),
                block.rejected.get(last, {}),
                estimate,
                self.gate.verdict(kinds[k], DIRECTIONS[directions[k]], estimate, problem, held[k]),
            ),
        )

    def _vote_speeds(self, block: RecordBlock, n: int) -> None:
        """The speed votes over a block (``speeds.SpeedVotes``), each taking the vehicle speed
        held at its row while it is fresh (a value of the standstill before a bus went quiet is
        no speed of the drive); before ``state.latest`` takes the block's last values."""
        t, column, vx = block.t, block.values.get("speed"), block.values.get("vx")
        before_t = self._speed_t
        if column is not None and (given := np.flatnonzero(~np.isnan(column))).size:
            self._speed_t = float(t[given[-1]])
        if vx is None or not len(rows := np.flatnonzero(~np.isnan(vx))):  # the vehicle bus alone
            return
        speed = _held(column, self.state.latest.get("speed"), n)
        when = _held(None if column is None else np.where(np.isnan(column), np.nan, t), before_t, n)
        fresh = t[rows] - when[rows] <= self._fresh_s
        self.state.speeds.add_block(t[rows], np.where(fresh, speed[rows], np.nan), vx[rows])

    def take_filtered(self, filtered: "Filtered") -> list[Event]:
        """The second stage of ``take_block``: each of a block's filtered rows in turn to what
        ``take`` routes a frame's estimate to (``_route``: the sign votes, the detector, the
        sideslip profile and the regressions, refitting on the frames' clock). Returns the
        events, in order."""
        kinds, directions = filtered.kinds, filtered.directions
        quasi_flags = filtered.quasi.tolist()
        # the rows a consumer takes a sample from: steady or quasi-steady, with a measured lateral
        # velocity (the quasi flag has it). Only they are made Estimates: the others, most rows of
        # a drive, are only a time for the detector's quiet runs and the refit
        taken = (np.equal(kinds, STEADY) | filtered.quasi) & ~np.isnan(filtered.out[:, _V_MEAS])
        taken_flags = taken.tolist()
        estimates = map(estimate_of, filtered.out[taken].tolist())
        headings, ay, steer = filtered.headings.tolist(), filtered.ay.tolist(), filtered.steer.tolist()
        route = self._route
        events: list[Event] = []
        own: list[Event] = []  # the last row's
        for k, now in enumerate(filtered.t.tolist()):
            own = route(
                now,
                next(estimates) if taken_flags[k] else None,
                kinds[k] == STEADY,
                DIRECTIONS[directions[k]],
                quasi_flags[k],
                headings[k],
                ay[k],
                steer[k],
            )
            if own:
                events += own
        self.state.last = filtered.last._replace(events=tuple(own))
        return events

    def _route(
        self,
        t: float,
        estimate: Estimate | None,
        steady: bool,
        direction: Direction | None,
        quasi: bool,
        heading: float,
        ay: float | None,
        steer: float | None,
    ) -> list[Event]:
        """One filtered sample at time t to everything after the gates, for ``take`` (a frame) and
        ``take_filtered`` (a block's row): the sign votes, the detector, the sideslip profile, the
        steady regression and the quasi-steady fits, then the refit every ``_REFIT_EVERY_S`` of
        the frames' clock. ``steady`` and ``direction`` are the steady-state gate's verdict,
        ``quasi`` the quasi-steady gate's, ``heading`` the integrated yaw rate (rad), ``ay`` and
        ``steer`` the latest measured values (None or NaN: none). ``estimate`` may be None where
        none of them takes the sample: neither gate held, or no lateral velocity was measured.
        Returns the detector's events, collected."""
        if steady and estimate is not None and estimate.v_meas_mps is not None:
            events = self.detector.step(t, estimate, SteadyState(True, direction), heading)
        else:  # all ``step`` does with a sample it does not take
            events = self.detector.end_quiet_runs(t)
        if events:
            self._collect(events)
        if (steady or quasi) and estimate is not None and estimate.v_meas_mps is not None:
            state = self.state
            u, r, v = estimate.u_mps, estimate.r_radps, estimate.v_meas_mps
            if t >= state.signs.next_t and r is not None:  # one vote per VOTE_EVERY_S
                state.signs.add(t, u, r, ay, steer)
            if steady:
                self.profile.add(u, v, direction)
                if r is not None:  # with u̇: a small pad's sweeps move load (regression.py)
                    self.regression.add(t, u, r, v, heading, u_dot=estimate.u_dot_mps2)
            if quasi and not state.crossings:  # after a crossing, no quasi-steady fit
                r_dot, u_dot = estimate.r_dot_radps2, estimate.u_dot_mps2
                assert r is not None and r_dot is not None  # the gate saw them
                self.quasi.add(t, u, r, v, heading, r_dot, u_dot)
                if self._drives:
                    self._drives[-1].add(t, u, r, v, heading, r_dot, u_dot)
        if not 0.0 <= t - self._last_fit < _REFIT_EVERY_S:
            self._last_fit = t
            self._refit()
        return events

    def _sensor_problems(self, block: RecordBlock) -> tuple[np.ndarray, list[str]]:
        """``state.sensor_problem`` after each record of the block (an index into the texts,
        -1 for None), as ``take`` sets it; leaves it as the last record left it."""
        n, texts = len(block), []
        change = np.full(n, -2)  # -2: no change, -1: cleared, else the new problem
        for role in _OPTICAL.intersection(block.values):
            change[~np.isnan(block.values[role])] = -1
        present = _OPTICAL.intersection(block.values)
        for row, rejected in block.rejected.items():
            usable = {r: 0.0 for r in present if not np.isnan(block.values[r][row])}
            problem = self._optical_problem(rejected, usable)
            if problem:
                texts.append(problem)
                change[row] = len(texts) - 1
        before = -1
        if self.state.sensor_problem is not None:
            texts.append(self.state.sensor_problem)
            before = len(texts) - 1
        latest = np.maximum.accumulate(np.where(change != -2, np.arange(n), -1))
        problems = np.where(latest >= 0, change[np.maximum(latest, 0)], before)
        self.state.sensor_problem = texts[problems[-1]] if problems[-1] >= 0 else None
        return problems, texts

    def finish(self) -> list[Event]:
        """End of input: fit pending sign changes. Returns the events this produced."""
        events = self.detector.finish()
        self._collect(events)
        self._refit()
        if self._drives and self.state.quasi is not None:  # each drive alone: do they agree?
            self.state.quasi_drives = tuple(drive.fit() for drive in self._drives)
        return events

    def new_log(self) -> None:
        """The frames from here on are another drive of the same car (``c2n analyze --pool``):
        the filter, the heading and the gates start afresh; the regressions give the drive its
        own ψ0 (the head mounted again) and keep every sample, and each drive's quasi-steady
        samples are also fitted alone at the end (``Snapshot.drives_disagree``)."""
        self.finish()
        self.filter.restart()
        self.heading = Heading()
        self.gate = SteadyStateGate(self.config.detector, self.config.vehicle.wheelbase_m)
        self.quasi_gate.new_log()
        self.regression.new_log()
        if not self._drives:  # the first drive's samples: all the pooled regression holds so far
            self._drives.append(copy.deepcopy(self.quasi))
        self._drives.append(self._sample_regression(transient=True))
        self.quasi.new_log()
        self._last_fit = -float("inf")
        self._fitted_on = None  # the same samples, now of two drives

    def _sample_regression(self, transient: bool) -> SampleRegression:
        """The every-sample regression on the config's car: steady samples, or (``transient``)
        quasi-steady ones; the sensors' scale tolerances (and the tape's, where d is held) counted in
        its intervals."""
        config = self.config
        return SampleRegression(
            config.vehicle.gravity_mps2,
            d_tape_m=config.d_m,
            d_tape_se_m=config.calibration.d_se_m,
            transient=transient,
            scale_se=config.calibration.fit_se,
            wheelbase_m=config.vehicle.wheelbase_m or WHEELBASE_M,
            priors=config.priors if config.priors.estimator == "marginal" else None,
        )

    def _refit(self) -> None:
        """The regression over every sample so far; a slope it found goes to the detector, and a
        new slope or turn step pairs the crossings again. The quasi-steady samples' regression too
        while no sweep has crossed zero. Nothing new since the last refit (no sample, no first
        crossing): the same fits, not worked out again."""
        seen = (self.regression.n_samples, self.quasi.n_samples, bool(self.state.crossings))
        if seen == self._fitted_on:
            return
        self._fitted_on = seen
        before = self.state.regression
        self.state.quasi = self.quasi.fit() if not self.state.crossings else None
        fit = self.state.regression = self.regression.fit()
        self.detector.tilt = fit.slope.tilt if fit is not None and fit.slope is not None else None
        if self.state.crossings and _pairing_terms(before) != _pairing_terms(fit):
            self._pair()

    def _pair(self) -> None:
        """The crossings combined and paired. Where the regression finds a slope, every crossing
        is moved to it (``with_tilt``; one without a lever that carries it is left out). Where it finds
        a turn step, it is taken out of every crossing (``without_step``); where it keeps the tyres'
        softening, every crossing is scaled to zero a_y (``at_zero_ay``)."""
        state, g = self.state, self.config.vehicle.gravity_mps2
        tilt = self.detector.tilt or (0.0, 0.0, 0.0, 0.0)  # every crossing moved to the last slope
        used = [with_tilt(c, tilt, self.config.d_m, g) for c in state.crossings]
        if self.detector.tilt is not None:  # a crossing without a lever ("beta") keeps what it had
            used = [c for c in used if c.slope_corrected] or used
        fit = state.regression
        turn = fit.turn_force if fit is not None else None
        if turn is not None:  # every crossing carries it: out
            used = [without_step(c, turn.step_rad, turn.step_se_rad, self.config.d_m, g) for c in used]
        softening = fit.softening if fit is not None else None
        if softening is not None:  # each reads its own a_y's secant
            used = [at_zero_ay(c, softening.per_mps2_2, softening.se_per_mps2_2) for c in used]
        state.combined = combine(used)
        state.paired = pair(
            used, self.config.d_m, g, self.config.priors.head_yaw_deg, self.config.detector.settle_s
        )
        scale = self.config.calibration.crossing_se(self.config.d_m)  # the speed's scale, the tape's d:
        # in every crossing alike
        if scale > 0:
            state.combined = _with_scale(state.combined, scale)
            state.paired = _with_scale(state.paired, scale)

    def _collect(self, events: list[Event]) -> None:
        for event in events:
            if isinstance(event, Crossing):
                state = self.state
                state.crossings.append(event)
                self._pair()
            elif isinstance(event, CrossingRejected):
                self.state.rejections.append(event)


_Result = TypeVar("_Result", Combined, Paired)


def _with_scale(result: _Result | None, share: float) -> _Result | None:
    """The crossings' result with a relative error common to all of them (a scale) counted."""
    if result is None:
        return None
    return replace(result, se=math.hypot(result.se, share * result.c2n), data_se=result.se)


def _pairing_terms(
    fit: RegressionFit | None,
) -> tuple[tuple[float, float, float, float] | None, float | None, float | None]:
    """What of the regression the pairing uses: the slope, the turn step and the softening it
    takes out of every crossing. A change pairs them again."""
    if fit is None:
        return (None, None, None)
    return (
        fit.slope.tilt if fit.slope is not None else None,
        fit.turn_force.step_rad if fit.turn_force is not None else None,
        fit.softening.per_mps2_2 if fit.softening is not None else None,
    )


def _held(column: np.ndarray | None, before: float | None, n: int) -> np.ndarray:
    """The latest value at each of n rows (the row's own included): sample and hold, NaN for none."""
    start = np.nan if before is None else before
    if column is None:
        return np.full(n, start)
    latest = np.maximum.accumulate(np.where(~np.isnan(column), np.arange(n), -1))
    return np.where(latest >= 0, column[np.maximum(latest, 0)], start)


class PartedPipeline(Pipeline):
    """``c2n live``'s pipeline: the one pipeline over the whole run, and each part between the optical
    sensor's pauses alone beside it (``results/parts.py`` says why).

    A pause is what ``c2n analyze`` calls one in a log (``sources/spacing.py``): no frame of the
    optical sensor's messages for longer than ``gap_reset_s``, from its last frame before to its first
    after. The pooled pipeline is the run as before, frame for frame. From the first pause on, the
    frames go to one more pipeline, the current part's; the part before it keeps only its C2n as it
    stood at the pause (the first part's is the pooled pipeline's then, which had seen it alone). So
    the cost is the pooled run's until the sensor first pauses, and twice it after. A sign change
    still being fitted when the sensor paused is not in its part's C2n (the pooled run's filter
    restarts there too).

    Frame by frame only: a bus gives no blocks (``take_block`` raises).
    """

    def __init__(self, config: Config) -> None:
        super().__init__(config)
        self._sensor = frozenset(sensor_messages(config))  # the optical sensor's frame ids
        self._pause_s = config.filter.gap_reset_s
        self._seen: float | None = None  # the optical sensor's last frame time
        self._begin: float | None = None  # the current part's first frame time, from the first pause
        self._part: Pipeline | None = None  # the current part alone, from the first pause
        self._ended: list[Part] = []
        self._take_pooled = super().take  # bound once: ``take`` runs for every frame

    def take(self, record: Record) -> Record:
        if record.frame_id in self._sensor:
            seen = self._seen
            if seen is not None and record.t - seen > self._pause_s:
                self._end_part(seen, record.t)
            self._seen = record.t
        if self._part is not None:
            self._part.take(record)
        return self._take_pooled(record)

    def take_block(self, block: RecordBlock) -> list[Event]:
        raise TypeError("PartedPipeline takes frames one by one (c2n live): a bus gives no blocks")

    def _end_part(self, last_t: float, next_t: float) -> None:
        """The sensor paused from ``last_t`` to ``next_t``: the current part ends with its C2n as
        it stands, and a new one begins."""
        if self._part is None:  # the first part: the pooled pipeline has seen it alone
            begin, headline = self.state.t_first, super().snapshot().headline
        else:
            begin, headline = self._begin, self._part.snapshot().headline
        self._ended.append(Part(begin if begin is not None else last_t, last_t, headline))
        self._part, self._begin = Pipeline(self.config), next_t

    def finish(self) -> list[Event]:
        events = super().finish()
        if self._part is not None:
            self._part.finish()
        return events

    def snapshot(self, first_stage: Snapshot | None = None) -> Snapshot:
        pooled = super().snapshot(first_stage)
        if self._part is None or self._begin is None:
            return pooled
        end = self._seen if self._seen is not None else self._begin
        parts = (*self._ended, Part(self._begin, end, self._part.snapshot().headline))
        return replace(pooled, parts=parts, parts_disagree=parts_disagree(parts, pooled.t0))
