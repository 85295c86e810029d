"""Seeded simulated drives for the tests, cached so each is made once per test session."""

import threading
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from functools import cache
from pathlib import Path
from typing import Any

import can

from app.config import Config, load_config
from app.pipeline import Pipeline
from app.records import Event
from app.sim.simulated_drive import DriveOptions, SimulatedDrive, simulate_drive
from app.sinks.sink import Sink

REPO = Path(__file__).resolve().parents[1]

# The S-Motion's default cycle (20 ms) and a vehicle bus at 50 Hz keep the tests quick.
FAST_SENSORS: dict[str, Any] = {"optical_hz": 50.0, "vehicle_hz": 50.0}


@cache
def cached_drive(
    scenario: str = "constant_radius", seed: int = 7, c2n: float | None = None, **sensor: Any
) -> SimulatedDrive:
    return simulate_drive(
        load_config(), DriveOptions(scenario=scenario, seed=seed, c2n=c2n, sensor=FAST_SENSORS | sensor)
    )


def run_pipeline(config: Config, drive: SimulatedDrive) -> Pipeline:
    pipeline = Pipeline(config)
    for message in drive.messages:
        pipeline.process(message)
    pipeline.finish()
    return pipeline


class EventLog(Sink):
    """A sink that keeps every event, in order."""

    def __init__(self) -> None:
        self.events: list[Event] = []

    def on_events(self, events: Sequence[Event], t0: float) -> None:
        self.events.extend(events)


@contextmanager
def sent_on_virtual_bus(channel: str, frames: Sequence[can.Message]) -> Iterator[None]:
    """``frames`` sent on python-can's virtual bus ``channel`` from a thread, starting 0.3 s after
    the ``with`` body starts (time for the receiver to open the bus); joined at its end."""

    def send() -> None:
        with can.Bus(interface="virtual", channel=channel, preserve_timestamps=True) as bus:
            time.sleep(0.3)
            for m in frames:
                bus.send(m)

    sender = threading.Thread(target=send)
    sender.start()
    try:
        yield
    finally:
        sender.join()
