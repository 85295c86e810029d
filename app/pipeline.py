"""The one pipeline: frame → decode → estimate → steady-state gate → crossing detector.

Live and offline runs differ only in where the frames come from; both call ``process`` for each
frame in arrival order and ``finish`` at the end, so the same frames give the same crossings.
"""

from dataclasses import dataclass, field, replace

import can

from app.combine import Combined, combine
from app.config import OPTICAL_ROLES, Config
from app.crossing_detector import CrossingDetector
from app.decode import Decoder
from app.estimator import MotionFilter
from app.records import Crossing, CrossingRejected, Event, Record
from app.steady_state import SteadyStateGate

_FILTER_ROLES = frozenset({"vx", "vy", "beta", "speed", "yaw_rate", "ay"})


@dataclass
class SessionState:
    """What the run has produced so far; the dashboard and the summary read it."""

    t_first: float | None = None
    t_last: float | None = None
    latest: dict[str, float] = field(default_factory=dict)  # role -> last usable value
    last: Record | None = None  # last record with an estimate
    sensor_problem: str | None = None  # why optical samples are being dropped, if they are
    crossings: list[Crossing] = field(default_factory=list)
    rejections: list[CrossingRejected] = field(default_factory=list)
    combined: Combined | None = None


class Pipeline:
    def __init__(self, config: Config) -> None:
        self.config = config
        self.decoder = Decoder(config)
        self.filter = MotionFilter(config.filter, config.vehicle.sensor_lateral_m, frozenset(config.roles))
        self.gate = SteadyStateGate(config.detector)
        self.detector = CrossingDetector(config.detector, config.d_m, config.vehicle.gravity_mps2)
        self.state = SessionState()

    def process(self, msg: can.Message) -> Record | None:
        """Take one frame; return its Record (None for frames that carry no role value)."""
        record = self.decoder.decode(msg)
        if record is None:
            return None
        state = self.state
        if state.t_first is None:
            state.t_first = record.t
        state.t_last = record.t
        state.latest.update(record.signals)
        optical_rejected = [record.rejected[r] for r in OPTICAL_ROLES if r in record.rejected]
        if optical_rejected:
            state.sensor_problem = optical_rejected[0]
        elif any(r in record.signals for r in OPTICAL_ROLES):
            state.sensor_problem = None
        if _FILTER_ROLES.isdisjoint(record.signals):
            return record
        estimate = self.filter.step(record)
        if estimate is None:
            return record
        steady = self.gate.step(record.t, estimate, state.latest.get("steer"), state.sensor_problem)
        events = self.detector.step(record.t, estimate, steady)
        self._collect(events)
        record = replace(record, estimate=estimate, steady=steady, events=tuple(events))
        state.last = record
        return record

    def finish(self) -> list[Event]:
        """End of input: fit pending sign changes. Returns the events this produced."""
        events = self.detector.finish()
        self._collect(events)
        return events

    def _collect(self, events: list[Event]) -> None:
        for event in events:
            if isinstance(event, Crossing):
                self.state.crossings.append(event)
                self.state.combined = combine(self.state.crossings)
            elif isinstance(event, CrossingRejected):
                self.state.rejections.append(event)
