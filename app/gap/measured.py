"""A measured drive on a uniform time grid: what the model is driven by and compared with.

The logs go through the one pipeline (decode, filter, steady-state gate); the trace's columns are
averaged into bins of ``dt``. Inputs of the model (vehicle speed, steering, lateral acceleration)
come from the vehicle bus where the config maps them; the comparison is with the optical sensor's
sideslip and the yaw rate.
"""

import itertools
import logging
import math
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import can
import numpy as np

from app.config import Config
from app.decode.decoder import Decoder
from app.errors import NoResultError
from app.gap.forked import Background, Later
from app.pipeline import Pipeline
from app.records import Crossing
from app.results.log_clock import clock_notes, sensor_messages
from app.results.regression import RegressionFit
from app.run_loop import run
from app.sinks.summary import Summary
from app.sinks.summary import build as build_summary
from app.sinks.trace import Trace, TraceBlocks, TraceRecorder
from app.snapshot import Snapshot
from app.sources.blocks import FrameBlock, RecordBlock
from app.sources.logs import LogReport, LogSource

log = logging.getLogger(__name__)

DT_S = 0.02
ACCEL_SMOOTHING_S = 0.5  # the speed is averaged over this before it is differentiated


@dataclass(frozen=True)
class Method:
    """What the pipeline's method made of the drive: its crossings, its regression, the summary."""

    crossings: tuple[Crossing, ...]
    regression: RegressionFit | None
    summary: Summary
    sign_problem: str | None  # a role the wrong way round (``Snapshot.sign_problem``)


@dataclass(frozen=True)
class Measured:
    """Per grid step (``dt``): the measured drive. Angles in rad, the rest SI; NaN where missing."""

    dt: float
    t: np.ndarray
    u_vehicle: np.ndarray  # the model's speed input: vehicle speed, else the optical speed
    u_optical: np.ndarray
    delta: np.ndarray  # road-wheel steer angle (steering-wheel angle / ratio), NaN without steer
    ay: np.ndarray  # u·r from the optical speed and the yaw rate (no roll or slope in it)
    r: np.ndarray  # measured yaw rate
    p: np.ndarray  # measured roll rate (+ leaning right), 0 without the role
    beta: np.ndarray  # measured sideslip at the sensor (optical)
    steady: np.ndarray  # bool: the steady-state gate held
    speed_source: str
    vehicle_roles: frozenset[str]  # roles read from the vehicle bus (they share its latency)
    method: Later[Method]  # what the pipeline's method made of the drive, maybe still being made
    reports: tuple[LogReport, ...] = ()  # how reading each log went: its optical sensor's pauses

    @property
    def crossings(self) -> tuple[Crossing, ...]:
        return self.method.get().crossings

    @property
    def regression(self) -> RegressionFit | None:
        return self.method.get().regression

    @property
    def summary(self) -> Summary:
        return self.method.get().summary

    @property
    def sign_problem(self) -> str | None:
        return self.method.get().sign_problem

    @property
    def heading(self) -> np.ndarray:
        """Heading from the integrated yaw rate (rad, 0 at the start)."""
        return np.cumsum(np.nan_to_num(self.r)) * self.dt

    @cached_property
    def ax(self) -> np.ndarray:
        """Longitudinal acceleration from the optical speed (m/s², smoothed over 0.5 s)."""
        width = max(1, round(ACCEL_SMOOTHING_S / self.dt))
        u = _fill(self.u_optical)
        padded = np.pad(np.nan_to_num(u), width // 2, mode="edge")
        smooth = np.convolve(padded, np.ones(width) / width, mode="valid")[: len(u)]
        return np.gradient(smooth, self.dt) if len(u) > 1 else np.zeros(len(u))


def _binned(time: np.ndarray, values: np.ndarray, index: np.ndarray, n: int) -> np.ndarray:
    ok = np.isfinite(values)
    total = np.bincount(index[ok], values[ok], minlength=n)
    count = np.bincount(index[ok], minlength=n)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.where(count > 0, total / np.maximum(count, 1), np.nan)


def _fill(values: np.ndarray) -> np.ndarray:
    """Hold the last value over gaps (a held CAN signal), the first one before it."""
    ok = np.isfinite(values)
    if not ok.any():
        return values
    index = np.where(ok, np.arange(len(values)), 0)
    np.maximum.accumulate(index, out=index)
    filled = values[index]
    filled[: np.argmax(ok)] = values[np.argmax(ok)]
    return filled


def _vehicle_roles(config: Config) -> frozenset[str]:
    """Roles whose DBC is not the optical sensor's: they ride the vehicle bus."""

    def dbc_of(role: str) -> Path | None:
        message = config.roles[role].message
        return next(
            (dbc.path for dbc in config.dbcs if any(m.name == message for m in dbc.database.messages)),
            None,
        )

    optical = dbc_of("vx") if "vx" in config.roles else None
    return frozenset(role for role in config.roles if dbc_of(role) != optical)


def measure(logs: Sequence[Path], config: Config, dt: float = DT_S, *, background: bool = False) -> Measured:
    """The drive through the pipeline, its frames taken in blocks: the filter and the gates over
    each block (``Pipeline.filter_block``) give the trace, and the detector and the regressions
    take the filtered rows after them (``take_filtered``). A BLF's or an MF4's frames come as the
    reader hands them over (``LogSource.items``); the trace is the same as frame by frame
    (``measure_by_frame``, tests/test_trace_blocks.py).

    With ``background``, the second stage (row by row: twice the first's time) runs in a
    forked process, which takes the blocks as the first stage makes them; ``Measured.method``
    waits for its result while the caller goes on with the trace."""
    pipeline = Pipeline(config)
    source = _source(logs, config, pipeline)
    messages = source.items(blocks=True)
    first = next(messages, None)
    if isinstance(first, can.Message) and not (first.channel is None or type(first.channel) is int):
        return measure_by_frame(logs, config, dt)  # named channels (candump's can0): frame by frame
    recorder = TraceBlocks(config.roles)
    pipeline.on_block = recorder.on_block
    frames = messages if first is None else itertools.chain([first], messages)

    def method(first_stage: Snapshot) -> Method:
        pipeline.finish()
        return _method(pipeline.snapshot(first_stage), config, logs)

    second = Background(pipeline.take_filtered, method, background)
    try:
        for block in frame_blocks(frames, pipeline.decoder):
            records = pipeline.decoder.decode_block(block) if isinstance(block, FrameBlock) else block
            filtered = pipeline.filter_block(records)
            if filtered is not None:
                second.put(filtered)
        trace = _checked(source, recorder.trace(pipeline.state.t_first or 0.0), logs, config)
    except BaseException:
        second.stop()
        raise
    return _on_grid(trace, config, second.end(pipeline.snapshot()), dt, source.reports)


def measure_by_frame(logs: Sequence[Path], config: Config, dt: float = DT_S) -> Measured:
    """``measure`` frame by frame through the live loop's path: the reference the blocks keep to."""
    pipeline = Pipeline(config)
    source = _source(logs, config, pipeline)
    recorder = TraceRecorder(config.roles)
    run(source, pipeline, [recorder])
    snapshot = pipeline.snapshot()
    trace = _checked(source, recorder.trace(snapshot.t0), logs, config)
    return _on_grid(trace, config, Later.now(_method(snapshot, config, logs)), dt, source.reports)


def _source(logs: Sequence[Path], config: Config, pipeline: Pipeline) -> LogSource:
    """The logs, merged where several are one drive's channels; each file's report keeps where its
    optical sensor paused beyond what the filter bridges (``c2n gap`` checks the parts agree)."""
    return LogSource(
        logs,
        merge=len(logs) > 1,
        triage=pipeline.decoder,
        spaced=frozenset(sensor_messages(config)),
        pause_s=config.filter.gap_reset_s,
    )


def _checked(source: LogSource, trace: Trace, logs: Sequence[Path], config: Config) -> Trace:
    """The trace, once the reader's notes are logged; refused where the optical sensor's frames
    lie further apart than the filter bridges (a clock not in seconds, a gap_reset_s shorter than
    a frame's spacing: ``clock_notes``) and without an optical sideslip."""
    for report in source.notes:
        if report.stopped:
            log.warning("%s: %s", report.path, report.stopped)
    for note in clock_notes(source.reports, config):
        raise NoResultError(f"{note.path}: {note.stopped}")
    if not len(trace) or not np.isfinite(trace["sideslip_measured"]).any():
        raise NoResultError(
            f"{', '.join(map(str, logs))}: no optical sideslip — the gap needs the optical sensor's frames"
        )
    return trace


def _method(snapshot: Snapshot, config: Config, logs: Sequence[Path]) -> Method:
    return Method(
        snapshot.crossings,
        snapshot.regression,
        build_summary(snapshot, config, [str(p) for p in logs]),
        snapshot.sign_problem,
    )


BLOCK_FRAMES = 4096  # frames per block: the per-block work (a few numpy calls per role) amortised


def frame_blocks(
    messages: Iterable[can.Message | FrameBlock], decoder: Decoder
) -> Iterator[FrameBlock | RecordBlock]:
    """The frames as FrameBlocks of up to BLOCK_FRAMES, in order; a reader's own FrameBlocks as
    they are. A frame a block cannot hold as ``decode`` would read it (error and remote frames, a
    dlc other than its data's length, a channel named rather than numbered, as a candump log's
    ``can0``) comes decoded, alone, as a RecordBlock; a block holds channels of None or numbers,
    not both."""
    part: list[can.Message] = []
    for msg in messages:
        if isinstance(msg, FrameBlock):
            if part:
                yield _block(part)
                part = []
            yield msg
            continue
        channel = msg.channel
        if (
            msg.is_error_frame
            or msg.is_remote_frame
            or msg.dlc != len(msg.data)
            or not (channel is None or type(channel) is int)  # a named channel: a key's object
        ):
            if part:
                yield _block(part)
                part = []
            record = decoder.decode(msg)
            if record is not None:
                yield RecordBlock(
                    np.array([record.t]),
                    [record.channel],
                    [record.frame_id],
                    {role: np.array([value]) for role, value in record.signals.items()},
                    {0: dict(record.rejected)} if record.rejected else {},
                )
            continue
        if part and (msg.channel is None) != (part[0].channel is None):
            yield _block(part)
            part = []
        part.append(msg)
        if len(part) == BLOCK_FRAMES:
            yield _block(part)
            part = []
    if part:
        yield _block(part)


def _block(part: list[can.Message]) -> FrameBlock:
    width = max(8, max(len(m.data) for m in part))
    data = np.zeros((len(part), width), np.uint8)
    for k, m in enumerate(part):
        data[k, : len(m.data)] = np.frombuffer(m.data, np.uint8)
    return FrameBlock(
        t=np.array([m.timestamp for m in part]),
        frame_id=np.array([m.arbitration_id for m in part], np.uint32),
        extended=np.array([m.is_extended_id for m in part]),
        channel=None if part[0].channel is None else np.array([m.channel for m in part]),
        data=data,
        length=np.array([len(m.data) for m in part]),
        fd=np.array([m.is_fd for m in part]),
    )


def _on_grid(
    trace: Trace, config: Config, method: Later[Method], dt: float, reports: Sequence[LogReport] = ()
) -> Measured:
    time = trace["time"]
    n = int(time[-1] / dt) + 1
    index = np.minimum((time / dt).astype(np.int64), n - 1)
    deg = math.pi / 180.0

    def column(name: str, scale: float = 1.0) -> np.ndarray:
        if name not in trace.columns:
            return np.full(n, np.nan)
        return _fill(_binned(time, trace[name] * scale, index, n))

    u_optical = column("speed")
    has_speed = "vehicle_speed" in trace.columns and np.isfinite(trace["vehicle_speed"]).any()
    u_vehicle = column("vehicle_speed") if has_speed else u_optical
    r = column("yaw_rate_measured", deg) if "yaw_rate_measured" in trace.columns else column("yaw_rate", deg)
    ratio = config.vehicle.steering_ratio or 15.0
    delta = column("steer", deg / ratio)
    ay = u_optical * r  # steady lateral acceleration: an accelerometer also reads roll and slope
    beta = _binned(time, trace["sideslip_measured"] * deg, index, n)
    steady = _binned(time, trace["steady"], index, n) > 0.5
    return Measured(
        dt=dt,
        t=np.arange(n) * dt,
        u_vehicle=u_vehicle,
        u_optical=u_optical,
        delta=delta,
        ay=ay,
        r=r,
        p=np.nan_to_num(column("roll_rate_measured", deg)),
        beta=beta,
        steady=steady,
        speed_source="vehicle speed" if has_speed else "optical speed",
        vehicle_roles=_vehicle_roles(config),
        method=method,
        reports=tuple(reports),
    )
