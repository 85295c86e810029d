"""The trace and summary of a simulated drive as ``c2n export`` makes them: the input of the plot
and report tests, built once per test session."""

from dataclasses import dataclass
from functools import cache

from app.config import load_config
from app.pipeline import Pipeline
from app.run_loop import run
from app.sinks import summary
from app.sinks.trace import Trace, TraceRecorder
from tests.simulated import cached_drive


@dataclass(frozen=True)
class Exported:
    trace: Trace
    summary: summary.Summary


def exported_drive() -> Exported:
    """The conftest's drive (constant radius, left and right, up and down) run through the
    pipeline with a TraceRecorder (the summary is frozen: a test changes a copy)."""
    trace, result = _build()
    return Exported(trace, result)


@cache
def _build() -> tuple[Trace, summary.Summary]:
    config = load_config()
    pipeline = Pipeline(config)
    recorder = TraceRecorder(config.roles)
    run(cached_drive().messages, pipeline, [recorder])  # the same call as conftest's: simulated once
    snapshot = pipeline.snapshot()
    return recorder.trace(snapshot.t0), summary.build(snapshot, config, ["sim"])
