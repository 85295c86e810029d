"""The decoded and filtered channels of a run, as columns with units: what ``c2n export`` writes
and plots.

One row per decoded frame (each frame that carried a usable role value). Filtered channels are
the filter's state after that frame (NaN until the filter starts); decoded channels hold the
latest usable value of their role (sample-and-hold, as a measurement tool shows it); the
``*_measured`` channels are this frame's own optical measurement, else NaN. Angles are in degrees,
the rest in SI units.
"""

import math
from array import array
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from app.records import Record
from app.sinks.sink import Sink


@dataclass(frozen=True, slots=True)
class Channel:
    name: str
    unit: str
    description: str
    decimals: int = 4  # what the CSV keeps: the measurement's resolution, with a digit to spare


_DEG = 180.0 / math.pi
_NAN = math.nan

# Filtered channels: (channel, value from a record with an estimate).
_FILTERED: tuple[tuple[Channel, Callable[[Record], float]], ...] = (
    (
        Channel("speed", "m/s", "filtered longitudinal velocity at the sensor"),
        lambda r: r.estimate.u_mps if r.estimate else _NAN,
    ),
    (
        Channel("sweep_rate", "m/s²", "filtered rate of change of speed"),
        lambda r: r.estimate.u_dot_mps2 if r.estimate else _NAN,
    ),
    (
        Channel("lateral_velocity", "m/s", "filtered lateral velocity at the sensor position"),
        lambda r: r.estimate.v_mps if r.estimate else _NAN,
    ),
    (
        Channel("sideslip", "deg", "filtered sideslip angle at the sensor"),
        lambda r: r.estimate.sideslip_rad * _DEG if r.estimate else _NAN,
    ),
    (
        Channel("sideslip_sigma", "deg", "standard deviation of the filtered sideslip", 5),
        lambda r: r.estimate.sideslip_sigma_rad * _DEG if r.estimate else _NAN,
    ),
    (
        Channel("yaw_rate", "deg/s", "filtered yaw rate (+ turning left)"),
        lambda r: _deg(r.estimate.r_radps) if r.estimate else _NAN,
    ),
    (
        Channel("lateral_acceleration", "m/s²", "steady lateral acceleration u·r (+ left)"),
        lambda r: _num(r.estimate.ay_mps2) if r.estimate else _NAN,
    ),
    (
        Channel("filter_health", "", "mean normalised innovation² (≈ 1 when the noise model fits)", 3),
        lambda r: r.estimate.health if r.estimate else _NAN,
    ),
    (
        Channel("steady", "", "1 while the steady-state gate holds, else 0", 0),
        lambda r: 1.0 if r.steady is not None and r.steady.steady else 0.0,
    ),
    (
        Channel("direction", "", "+1 turning left, -1 right, 0 straight or unknown", 0),
        lambda r: {"left": 1.0, "right": -1.0}.get((r.steady.direction or "") if r.steady else "", 0.0),
    ),
)
# This frame's own optical measurement, at the sensor position (NaN on other frames).
_MEASURED: tuple[tuple[Channel, Callable[[Record], float]], ...] = (
    (
        Channel("lateral_velocity_measured", "m/s", "this frame's measured lateral velocity, else NaN"),
        lambda r: _num(r.estimate.v_meas_mps) if r.estimate else _NAN,
    ),
    (
        Channel("sideslip_measured", "deg", "this frame's measured sideslip angle, else NaN"),
        lambda r: _deg(r.estimate.sideslip_meas_rad) if r.estimate else _NAN,
    ),
)

# Decoded roles: role -> (channel, factor from SI to the channel's unit).
DECODED: Mapping[str, tuple[Channel, float]] = {
    "vx": (Channel("vx", "m/s", "optical longitudinal velocity (decoded)"), 1.0),
    "vy": (Channel("vy", "m/s", "optical lateral velocity (decoded)"), 1.0),
    "beta": (Channel("beta", "deg", "optical sideslip angle (decoded)"), _DEG),
    "speed": (Channel("vehicle_speed", "m/s", "vehicle speed (decoded)"), 1.0),
    "yaw_rate": (Channel("yaw_rate_measured", "deg/s", "yaw rate (decoded)"), _DEG),
    "ay": (Channel("ay_measured", "m/s²", "lateral acceleration (decoded)"), 1.0),
    "steer": (Channel("steer", "deg", "steering-wheel angle (decoded)"), _DEG),
    "roll_rate": (Channel("roll_rate_measured", "deg/s", "roll rate (decoded, + leaning right)"), _DEG),
}

TIME = Channel("time", "s", "time since the first frame", 6)  # frame times are µs-resolved


def _num(x: float | None) -> float:
    return _NAN if x is None else x


def _deg(x: float | None) -> float:
    return _NAN if x is None else x * _DEG


@dataclass(frozen=True)
class Trace:
    """Columns of equal length, in ``channels`` order; ``t0`` is the first frame's timestamp."""

    t0: float
    channels: tuple[Channel, ...]
    columns: Mapping[str, np.ndarray]

    def __len__(self) -> int:
        return len(self.columns[TIME.name])

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]


class TraceRecorder(Sink):
    """A sink of every Record; ``trace()`` gives the columns so far."""

    def __init__(self, roles: Iterable[str]) -> None:
        self._decoded = [(role, *DECODED[role]) for role in DECODED if role in set(roles)]
        self.channels = (
            TIME,
            *(channel for channel, _ in _FILTERED),
            *(channel for channel, _ in _MEASURED),
            *(channel for _, channel, _ in self._decoded),
        )
        self._columns = {channel.name: array("d") for channel in self.channels}
        self._held = {role: _NAN for role, _, _ in self._decoded}
        self._filtered = [_NAN] * len(_FILTERED)

    def on_record(self, record: Record) -> None:
        for role, _, _ in self._decoded:
            value = record.signals.get(role)
            if value is not None:
                self._held[role] = value
        if record.estimate is not None:
            self._filtered = [value(record) for _, value in _FILTERED]
        columns = self._columns
        columns[TIME.name].append(record.t)
        for (channel, _), value in zip(_FILTERED, self._filtered, strict=True):
            columns[channel.name].append(value)
        for channel, measured in _MEASURED:
            columns[channel.name].append(measured(record))
        for role, channel, factor in self._decoded:
            columns[channel.name].append(self._held[role] * factor)

    def trace(self, t0: float) -> Trace:
        """The columns so far, with time counted from ``t0`` (the session's first frame)."""
        columns = {
            name: np.frombuffer(column, dtype=np.float64).copy() for name, column in self._columns.items()
        }
        columns[TIME.name] = np.round(columns[TIME.name] - t0, 6)  # frame times are µs-resolved
        return Trace(t0, self.channels, columns)


# Estimate's fields (app/estimate/compiled.py's estimate_of): the column of each filtered channel
# and its factor, in _FILTERED's order up to "health"; "steady" and "direction" are the gate's.
_FILTERED_FIELDS = ((0, 1.0), (1, 1.0), (2, 1.0), (6, _DEG), (7, _DEG), (4, _DEG), (8, 1.0), (9, 1.0))
_MEASURED_FIELDS = ((10, 1.0), (11, _DEG))
_DIRECTION_VALUES = np.array([0.0, 1.0, -1.0])  # app/detect/steady_state.py's DIRECTIONS: None, left, right


def _held_from(values: np.ndarray, given: np.ndarray, before: float) -> np.ndarray:
    """``values`` where ``given``, else the last given value before (``before`` ahead of the first)."""
    index = np.where(given, np.arange(len(values)), -1)
    np.maximum.accumulate(index, out=index)
    return np.where(index >= 0, values[np.maximum(index, 0)], before)


class TraceBlocks:
    """TraceRecorder's columns from the blocks ``Pipeline.take_block`` takes (its ``on_block``
    hook): the same rows and values as TraceRecorder over the Records one by one
    (tests/test_trace_blocks.py), a block's rows at a time."""

    def __init__(self, roles: Iterable[str]) -> None:
        self._reference = TraceRecorder(roles)  # the channels, and the held values' start
        self._decoded = self._reference._decoded
        self.channels = self._reference.channels
        self._parts: dict[str, list[np.ndarray]] = {channel.name: [] for channel in self.channels}
        self._held = {role: _NAN for role, _, _ in self._decoded}
        self._filtered = [_NAN] * len(_FILTERED)

    def on_block(
        self, block: Any, rows: np.ndarray, out: np.ndarray, kinds: np.ndarray, directions: np.ndarray
    ) -> None:
        n, parts = len(block), self._parts
        parts[TIME.name].append(np.asarray(block.t, dtype=np.float64))
        given = np.zeros(n, bool)
        given[rows] = True
        from app.detect.steady_state import STEADY  # the detector's module: not at a sink's import

        filtered = [out[:, field] * factor for field, factor in _FILTERED_FIELDS]
        filtered.append(np.where(kinds == STEADY, 1.0, 0.0))
        filtered.append(_DIRECTION_VALUES[directions] if len(directions) else np.zeros(0))
        for k, ((channel, _), values) in enumerate(zip(_FILTERED, filtered, strict=True)):
            column = np.full(n, _NAN)
            column[rows] = values
            parts[channel.name].append(_held_from(column, given, self._filtered[k]))
            if len(rows):
                self._filtered[k] = float(values[-1])
        for (channel, _), (field, factor) in zip(_MEASURED, _MEASURED_FIELDS, strict=True):
            column = np.full(n, _NAN)
            column[rows] = out[:, field] * factor
            parts[channel.name].append(column)
        for role, channel, factor in self._decoded:
            values = block.values.get(role)
            if values is None:
                parts[channel.name].append(np.full(n, self._held[role] * factor))
                continue
            usable = ~np.isnan(values)
            parts[channel.name].append(_held_from(values, usable, self._held[role]) * factor)
            if usable.any():
                self._held[role] = float(values[np.flatnonzero(usable)[-1]])

    def trace(self, t0: float) -> Trace:
        """The columns so far, with time counted from ``t0`` (the session's first frame)."""
        columns = {
            name: np.concatenate(parts) if parts else np.zeros(0) for name, parts in self._parts.items()
        }
        columns[TIME.name] = np.round(columns[TIME.name] - t0, 6)  # frame times are µs-resolved
        return Trace(t0, self.channels, columns)
