"""The gap's reading of a drive in blocks (``TraceBlocks`` on ``Pipeline.take_block``) against
the reference, TraceRecorder over the Records of the live loop one by one: the same rows, the same
values in every channel, the same measured drive — on the troubled drive of test_blocks.py, with
error, remote and cut frames among its frames (those go through ``decode`` alone)."""

import io
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import can
import numpy as np
import pytest

from app.cli import main
from app.gap.measured import frame_blocks, measure, measure_by_frame
from app.pipeline import Pipeline
from app.run_loop import run
from app.sinks.trace import Trace, TraceBlocks, TraceRecorder
from app.sources import logs
from app.sources.blocks import FrameBlock
from app.sources.logs import LogReport, read_log
from tests.test_blocks import CONFIG, _copy, troubled_drive


def odd_drive() -> tuple[can.Message, ...]:
    """The troubled drive with an error frame, a remote frame and a frame whose dlc is not its
    data's length every 997 frames."""
    out: list[can.Message] = []
    for k, m in enumerate(troubled_drive()):
        if k % 997 == 1:
            out.append(can.Message(timestamp=m.timestamp, is_error_frame=True, channel=m.channel))
        elif k % 997 == 2:
            out.append(_copy(m, data=b"", is_remote_frame=True) if not m.is_fd else m)
        elif k % 997 == 3 and not m.is_fd:
            cut = _copy(m)
            cut.dlc = len(m.data) + 1 if len(m.data) < 8 else len(m.data) - 1
            out.append(cut)
        out.append(m)
    return tuple(out)


def by_frame(messages: tuple[can.Message, ...]) -> Trace:
    pipeline = Pipeline(CONFIG)
    recorder = TraceRecorder(CONFIG.roles)
    run(iter(messages), pipeline, [recorder])
    return recorder.trace(pipeline.snapshot().t0)


def by_block(messages: tuple[can.Message, ...]) -> tuple[Trace, Pipeline]:
    pipeline = Pipeline(CONFIG)
    recorder = TraceBlocks(CONFIG.roles)
    pipeline.on_block = recorder.on_block
    for block in frame_blocks(iter(messages), pipeline.decoder):
        pipeline.take_block(pipeline.decoder.decode_block(block) if type(block) is FrameBlock else block)
    pipeline.finish()
    return recorder.trace(pipeline.snapshot().t0), pipeline


def test_the_blocks_trace_is_the_frame_by_frame_trace() -> None:
    messages = odd_drive()
    reference = by_frame(messages)
    trace, pipeline = by_block(messages)
    assert pipeline.decoder.counts.error_frames > 0 and pipeline.decoder.counts.bad_length > 0
    assert [c.name for c in trace.channels] == [c.name for c in reference.channels]
    assert len(reference) > 10_000
    for channel in reference.channels:
        assert np.array_equal(trace[channel.name], reference[channel.name], equal_nan=True), channel.name
    assert np.isfinite(trace["sideslip_measured"]).sum() > 1000  # the comparison holds measurements


def test_the_measured_drive_is_the_same_in_blocks(tmp_path: Path) -> None:
    log = tmp_path / "drive.blf"
    with can.Logger(str(log)) as writer:
        for m in troubled_drive():
            writer.on_message_received(m)
    frames = measure_by_frame([log], CONFIG)
    for blocks in (measure([log], CONFIG), measure([log], CONFIG, background=True)):
        for name in ("t", "u_vehicle", "u_optical", "delta", "ay", "r", "p", "beta", "steady"):
            assert np.array_equal(getattr(blocks, name), getattr(frames, name), equal_nan=True), name
        assert blocks.crossings == frames.crossings and blocks.regression == frames.regression
        assert blocks.summary == frames.summary
    assert frames.crossings and frames.regression is not None  # the comparison holds results


def test_c2n_gap_says_the_same_whether_a_blf_comes_in_blocks_or_as_messages(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``c2n gap --json`` byte for byte: the BLF reader's own FrameBlocks (its remote, error and
    cut frames as Messages among them) against its Messages packed into blocks by
    ``frame_blocks``, as before the reader gave blocks."""
    log = tmp_path / "drive.blf"
    with can.Logger(str(log)) as writer:
        for m in odd_drive():
            writer.on_message_received(m)
    items = list(read_log(log, LogReport(log), Pipeline(CONFIG).decoder, blocks=True))
    messages = [item for item in items if isinstance(item, can.Message)]
    assert any(isinstance(item, FrameBlock) for item in items) and any(m.is_remote_frame for m in messages)

    def gap_json(name: str) -> bytes:
        out = tmp_path / name
        with redirect_stdout(io.StringIO()), redirect_stderr(io.StringIO()) as err:
            code = main(["gap", str(log), "--json", str(out)])
        assert code == 0, err.getvalue()
        return out.read_bytes()

    in_blocks = gap_json("blocks.json")
    monkeypatch.delitem(logs._BLOCK_READERS, ".blf")  # the BLF read as Messages, the bulk reader's
    as_messages = gap_json("messages.json")
    assert b'"diagnosis"' in in_blocks
    assert in_blocks == as_messages
