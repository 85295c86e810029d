"""The run loop and its sinks: each sink hears what it overrides, every sink is closed whatever
happens, and what a sink sees is the pipeline's result, not the pipeline."""

import json
from collections.abc import Sequence
from pathlib import Path

import can
import pytest

from app.config import Config
from app.pipeline import Pipeline
from app.records import Event, Record
from app.run_loop import run
from app.sinks import summary
from app.sinks.recorder import SessionRecorder
from app.sinks.sink import Sink, overrides
from app.snapshot import Snapshot
from tests.simulated import cached_drive


class Tally(Sink):
    def __init__(self) -> None:
        self.frames = self.records = self.events = self.flushes = self.closes = 0
        self.snapshots: list[Snapshot] = []

    def on_frame(self, msg: can.Message) -> None:
        self.frames += 1

    def on_record(self, record: Record) -> None:
        self.records += 1

    def on_events(self, events: Sequence[Event], t0: float) -> None:
        self.events += len(events)

    def on_snapshot(self, snapshot: Snapshot) -> None:
        self.snapshots.append(snapshot)

    def flush(self) -> None:
        self.flushes += 1

    def close(self) -> None:
        self.closes += 1


class OnlyEvents(Sink):
    def __init__(self) -> None:
        self.events: list[Event] = []

    def on_events(self, events: Sequence[Event], t0: float) -> None:
        self.events.extend(events)


def test_each_sink_hears_every_frame_record_and_event_and_is_closed_once(config: Config) -> None:
    messages = cached_drive().messages
    pipeline, tally, events = Pipeline(config), Tally(), OnlyEvents()
    assert run(messages, pipeline, [tally, events])
    decoded = Pipeline(config)
    records = sum(decoded.process(m) is not None for m in messages)
    assert tally.frames == len(messages) and tally.records == records > 0
    assert tally.events == len(events.events) >= 4
    assert tally.closes == 1 and tally.flushes >= 1
    assert tally.snapshots[-1] == pipeline.snapshot()  # the last one is of the end
    assert [overrides(events, hook) for hook in ("on_frame", "on_events", "close")] == [False, True, False]


def test_the_snapshot_is_a_copy_the_run_does_not_change(config: Config) -> None:
    messages = cached_drive().messages
    pipeline = Pipeline(config)
    half = len(messages) // 2
    for m in messages[:half]:
        pipeline.process(m)
    early = pipeline.snapshot()
    frames, crossings, t_last = early.frames.total, early.crossings, early.t_last
    for m in messages[half:]:
        pipeline.process(m)
    pipeline.finish()
    assert (early.frames.total, early.crossings, early.t_last) == (frames, crossings, t_last)
    assert pipeline.snapshot().frames.total == len(messages) > frames


def test_the_recording_is_finished_when_the_analysis_fails(config: Config, tmp_path: Path) -> None:
    """A failure after the frames (here the final fit) still leaves every frame on disk and the
    events table closed: the run loop closes its sinks whatever happens."""
    messages = cached_drive().messages[:3000]
    pipeline = Pipeline(config)

    def broken_finish() -> list[Event]:
        raise ValueError("math domain error")

    pipeline.finish = broken_finish  # type: ignore[method-assign]
    recorder, tally = SessionRecorder(tmp_path / "session", config, ".blf"), Tally()
    with pytest.raises(ValueError, match="math domain"):
        run(messages, pipeline, [recorder, tally])
    assert tally.closes == 1
    recorded = list(can.LogReader(recorder.raw_path))  # a BLF reads back only once it is finished
    assert [bytes(m.data) for m in recorded] == [bytes(m.data) for m in messages]
    assert (tmp_path / "session" / "events.csv").read_text(encoding="utf-8").startswith("t,event,")


def test_the_summary_is_the_result_file_in_json_types(config: Config) -> None:
    pipeline = Pipeline(config)
    run(cached_drive().messages, pipeline)
    result = summary.build(pipeline.snapshot(), config, ["sim"])
    data = result.to_json()
    assert json.loads(json.dumps(data)) == data  # lists, not tuples; nothing JSON cannot hold
    assert list(data)[:8] == [
        "c2n",
        "c2n_ci95",
        "c2n_method",
        "u0_mps",
        "crossings",
        "regression",
        "paired",
        "frames",
    ]
    assert data["c2n"] == result.c2n and data["crossings"][0]["u0_mps"] == result.crossings[0].u0_mps
    assert result.warned(["a loss"]).warnings == ("a loss", *result.warnings)
