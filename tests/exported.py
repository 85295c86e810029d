"""The trace and summary of a simulated drive as ``c2n export`` makes them: the input of the plot
and report tests, built once per test session."""

import copy
from dataclasses import dataclass
from functools import cache
from typing import Any

from app.config import load_config
from app.pipeline import Pipeline
from app.sinks import summary
from app.sinks.trace import Trace, TraceRecorder
from tests.simulated import cached_drive


@dataclass(frozen=True)
class Exported:
    trace: Trace
    summary: dict[str, Any]


def exported_drive() -> Exported:
    """The conftest's drive (constant radius, left and right, up and down) run through the
    pipeline with a TraceRecorder; the summary is a fresh copy, so a test may change it."""
    trace, result = _build()
    return Exported(trace, copy.deepcopy(result))


@cache
def _build() -> tuple[Trace, dict[str, Any]]:
    config = load_config()
    pipeline = Pipeline(config)
    recorder = TraceRecorder(config.roles)
    for message in cached_drive().messages:  # the same call as conftest's: simulated once
        record = pipeline.process(message)
        if record is not None:
            recorder(record)
    pipeline.finish()
    return recorder.trace(pipeline.state.t_first or 0.0), summary.build(pipeline, ["sim"])
