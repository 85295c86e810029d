"""The block path (``c2n analyze`` on MF4: frames as columns, the filter and the gate's limits run
over a block at once) against the frame-by-frame pipeline, the reference: the same counts, the
same Records, the same steady-state verdicts, the same state and results, on a drive with the
troubles that make the sequential parts work — a sensor status that goes bad and goes stale,
values out of range, frames of the wrong length, time that jumps back."""

import dataclasses
import json
import math
from collections.abc import Iterator
from functools import cache
from typing import Any

import can
import numpy as np
import pytest

from app.config import load_config
from app.decode.decoder import Decoder
from app.detect.steady_state import DIRECTIONS, SteadyStateGate
from app.pipeline import Pipeline
from app.records import Record
from app.run_loop import run
from app.sinks import summary
from app.sinks.sink import Sink
from app.sources.blocks import FrameBlock
from tests.simulated import cached_drive

CONFIG = load_config()


@cache
def troubled_drive() -> tuple[can.Message, ...]:
    """The test drive with a bad and a silent spell of the sensor status, out-of-range and
    wrong-length frames of the optical sensor, and a second of the drive played again (time
    goes back)."""
    kistler = next(dbc.database for dbc in CONFIG.dbcs if dbc.path.name.startswith("kistler"))
    status, velocity = kistler.get_message_by_name("Status"), kistler.get_message_by_name("Correvit")
    drive = list(cached_drive().messages)
    t0 = drive[0].timestamp
    out: list[can.Message] = []
    for m in drive:
        age = m.timestamp - t0
        if m.arbitration_id == status.frame_id:
            if 30.0 < age < 31.0:
                continue  # silent: older than the timeout
            if 40.0 < age < 42.0:  # the head reports a fault
                values = status.decode(bytes(m.data), decode_choices=False) | {"HeadStatus": 0}
                m = _copy(m, data=status.encode(values))
        elif m.arbitration_id == velocity.frame_id:
            if 50.0 < age < 50.2:  # beyond the DBC's ±100 km/h
                values = velocity.decode(bytes(m.data), decode_choices=False) | {"VelY_cor": 300.0}
                m = _copy(m, data=velocity.encode(values, strict=False))
            elif 55.0 < age < 55.1:
                m = _copy(m, data=bytes(m.data)[:5])  # short
            elif 56.0 < age < 56.1:
                m = _copy(m, data=bytes(m.data) + b"\0\0", is_fd=True)  # long, CAN FD
        out.append(m)
    replay = [_copy(m) for m in drive if 60.0 < m.timestamp - t0 < 61.0]
    cut = next(k for k, m in enumerate(out) if m.timestamp - t0 > 70.0)
    return tuple(out[:cut] + replay + out[cut:])


def _copy(m: can.Message, **changes: Any) -> can.Message:
    fields = {
        "timestamp": m.timestamp,
        "arbitration_id": m.arbitration_id,
        "is_extended_id": m.is_extended_id,
        "data": bytes(m.data),
        "channel": m.channel,
        "is_fd": m.is_fd,
    }
    return can.Message(**(fields | changes))


def blocks_of(messages: tuple[can.Message, ...], size: int) -> Iterator[FrameBlock]:
    """The frames as FrameBlocks of ``size`` frames, a 64-byte data column as an MF4 has."""
    for start in range(0, len(messages), size):
        part = messages[start : start + size]
        data = np.zeros((len(part), 64), np.uint8)
        for k, m in enumerate(part):
            data[k, : len(m.data)] = np.frombuffer(bytes(m.data), np.uint8)
        yield FrameBlock(
            t=np.array([m.timestamp for m in part]),
            frame_id=np.array([m.arbitration_id for m in part], np.uint32),
            extended=np.array([m.is_extended_id for m in part]),
            channel=np.array([m.channel for m in part], np.uint8),
            data=data,
            length=np.array([len(m.data) for m in part]),
            fd=np.array([m.is_fd for m in part]),
        )


def test_the_troubled_drive_has_its_troubles() -> None:
    decoder = Decoder(CONFIG)
    for m in troubled_drive():
        decoder.decode(m)
    reasons = " ".join(decoder.counts.rejected)
    for trouble in ("no sensor status yet", "sensor status older than", "HeadStatus=0", "out of range"):
        assert trouble in reasons
    assert decoder.counts.bad_by_id.keys() >= {(0x7E5, "short"), (0x7E5, "long")}


@pytest.mark.parametrize("size", [1, 997, 200_000])
def test_blocks_decode_to_the_records_and_counts_of_frame_by_frame(size: int) -> None:
    frames, blocks = Decoder(CONFIG), Decoder(CONFIG)
    one_by_one = [r for m in troubled_drive() if (r := frames.decode(m)) is not None]
    in_blocks = []
    for block in blocks_of(troubled_drive(), size):
        records = blocks.decode_block(block)
        in_blocks += [
            (
                float(records.t[k]),
                records.channel[k],
                records.frame_id[k],
                records.signals(k),
                records.rejected.get(k, {}),
            )
            for k in range(len(records))
        ]
    assert in_blocks == [(r.t, r.channel, r.frame_id, dict(r.signals), dict(r.rejected)) for r in one_by_one]
    ours, theirs = blocks.counts, frames.counts
    assert ours.as_dict() == theirs.as_dict()
    for name in ("by_id", "bad_by_id", "role_frames", "rejected"):
        assert getattr(ours, name) == getattr(theirs, name), name
    assert (blocks.status.t, blocks.status.values) == (frames.status.t, frames.status.values)


def test_the_gate_over_a_block_words_every_verdict_as_step_does() -> None:
    pipeline, seen = Pipeline(CONFIG), []
    for m in troubled_drive():
        record = pipeline.process(m)
        if record is not None and record.estimate is not None:
            seen.append((record, pipeline.state.latest.get("steer"), pipeline.state.sensor_problem))
    one, block = SteadyStateGate(CONFIG.detector), SteadyStateGate(CONFIG.detector)
    expected = [one.step(r.t, r.estimate, steer, problem) for r, steer, problem in seen]  # type: ignore[arg-type]
    estimates = np.array([[math.nan if v is None else v for v in r.estimate] for r, _, _ in seen])  # type: ignore[union-attr]
    steer = np.array([math.nan if s is None else s for _, s, _ in seen])
    kinds, directions, held = block.steps(
        np.array([r.t for r, _, _ in seen]), estimates, steer, np.array([p is None for _, _, p in seen])
    )
    words = [
        block.verdict(kind, DIRECTIONS[d], r.estimate, problem, h)  # type: ignore[arg-type]
        for kind, d, h, (r, _, problem) in zip(kinds, directions, held, seen, strict=True)
    ]
    assert words == expected
    assert {v.reasons[0].split(" ")[0] for v in expected if v.reasons} >= {
        "sensor:",
        "settling",
        "driving",
        "sweep",
    }
    assert (block._since, block._soft_since) == (one._since, one._soft_since)


@pytest.mark.parametrize("size", [1, 997, 200_000])
def test_a_pipeline_fed_blocks_ends_as_one_fed_frame_by_frame(size: int) -> None:
    reference, events = Pipeline(CONFIG), []
    for m in troubled_drive():
        record = reference.process(m)
        if record is not None:
            events += record.events
    pipeline, in_blocks = Pipeline(CONFIG), []
    for block in blocks_of(troubled_drive(), size):
        in_blocks += pipeline.process_block(block)
    assert in_blocks == events and events, "the drive gives events"
    assert pipeline.finish() == reference.finish()
    ours, theirs = pipeline.state, reference.state
    assert ours.last == theirs.last
    assert (ours.t_first, ours.t_last, ours.latest, ours.sensor_problem) == (
        theirs.t_first,
        theirs.t_last,
        theirs.latest,
        theirs.sensor_problem,
    )
    assert pipeline.filter.counts == reference.filter.counts and pipeline.filter.counts.time_jumps > 0
    assert ours.signs == theirs.signs and ours.signs.ay_with > 0 and ours.signs.steer_with > 0
    quasi = pipeline.quasi.fit()
    assert quasi is not None and quasi == reference.quasi.fit(), "the quasi-steady samples are the same"
    tally, their_tally = pipeline.quasi_gate.cornering, reference.quasi_gate.cornering
    assert tally.usable_s > 0 and tally.turning_s == pytest.approx(their_tally.turning_s, abs=1e-6)
    assert tally.usable_s == pytest.approx(their_tally.usable_s, abs=1e-6)
    for a, b in zip(pipeline.filter.state(), reference.filter.state(), strict=True):
        np.testing.assert_array_equal(a, b)
    ours_json, theirs_json = (
        json.dumps(summary.build(p.snapshot(), CONFIG, ["drive"]).to_json(), sort_keys=True)
        for p in (pipeline, reference)
    )
    assert ours_json == theirs_json


def test_where_the_filter_lost_the_car_in_a_sample_blocks_count_as_frames_do() -> None:
    """A filter too slow for the sweeps (q_u a 50,000th of its default) loses the car in samples
    the estimates take: counted alike frame by frame (live) and in blocks (a log)."""
    slow = dataclasses.replace(CONFIG, filter=dataclasses.replace(CONFIG.filter, q_u=1e-6))
    reference, pipeline = Pipeline(slow), Pipeline(slow)
    for m in cached_drive().messages:
        reference.process(m)
    for block in blocks_of(cached_drive().messages, 997):
        pipeline.process_block(block)
    ours, theirs = pipeline.snapshot().filter, reference.snapshot().filter
    assert ours.counts == theirs.counts and ours.counts.lost_vx > ours.lost_in_samples > 0
    assert ours.lost_in_samples == theirs.lost_in_samples
    plain = Pipeline(CONFIG)
    for block in blocks_of(cached_drive().messages, 997):
        plain.process_block(block)
    assert plain.snapshot().filter.lost_in_samples == 0 and not plain.filter.counts.lost


def test_blocks_give_no_records_to_watch() -> None:
    class Watch(Sink):
        def on_record(self, record: Record) -> None:
            raise AssertionError("not reached")

    with pytest.raises(ValueError, match="no records"):
        run([], Pipeline(CONFIG), [Watch()], blocks=True)
