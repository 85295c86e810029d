"""A measured drive in the project's CAN layouts: a real car's motion at a virtual optical sensor.

The source is the Stanford Revs race car at Thunderhill (``data/real/stanford-revs-thunderhill``:
15 text files, one number a line, 100 Hz): the measured vx, vy at the CG, yaw rate, road-wheel
steer and accelerations. Nobody simulated it. It becomes a ``DriveTrace`` (time from 0, the
measured values as they are) and goes through the same sensor model as a simulated drive
(``sensors.frames``: noise, the DBCs' resolution, the sensors' rates): the optical sensor sits
d ahead of the rear axle (the config's ``sensor_ahead_of_rear_axle_m``) and sees
v_P = vy + (d − b)·r, b the CG to the rear axle; both gyros carry the measured yaw rate, the
steering-wheel angle is the measured road-wheel angle times the config's steering ratio, the
vehicle speed is the measured vx.
"""

from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from pathlib import Path
from types import MappingProxyType
from typing import Any

import numpy as np

from app.config import Config
from app.dbc import load_dbc
from app.errors import C2nError, LogFileError
from app.sim.drive import DriveTrace
from app.sim.sensors import SensorSetup, frames
from app.sim.simulated_drive import DBC_DIR, SimulatedDrive
from app.sim.vehicle_model import BicycleParams

# The 15 files, by their stem; each is one column of the drive, one number a line.
SOURCE_FILES: tuple[str, ...] = (
    "t",  # s
    "vx",  # m/s at the CG
    "vy",  # m/s at the CG
    "beta_true",  # rad: atan2(vy, vx)
    "yawRate",  # rad/s
    "yawRateFilt",  # deg/s (not converted by the source's mat2txt.m)
    "yawAngAcc",  # rad/s²
    "yawAngAccFilt",  # rad/s²
    "axCG",  # m/s²
    "axCGFilt",  # m/s²
    "ayCG",  # m/s²
    "ayCGFilt",  # m/s²
    "delta",  # rad, road-wheel steer
    "deltaFL",  # rad
    "deltaFR",  # rad
)

SOURCE: Mapping[str, str] = MappingProxyType(
    {
        "dataset": "stanford-revs-thunderhill",
        "repository": "github.com/MBDS/sideslip-angle-vehicle-estimation",
        "path": "datasets/20140222_01_01_03_250lm/",
        "description": "Stanford Revs race car at Thunderhill, 100 Hz: measured vx, vy at the CG, "
        "yaw rate, road-wheel steer, accelerations (racing laps, 16-61 m/s)",
        "licence": "MIT, Copyright (c) 2021 Jose Luis Blanco-Claraco (the repository's LICENSE)",
        "paper": "Leanza, Reina, Blanco-Claraco, Sensors 21(16):5409, 2021",
    }
)

_STEP_TOLERANCE_S = 1e-6  # the source's time stamps are uniform to 1e-10 s


@dataclass(frozen=True)
class MeasuredChannels:
    """The source files as read: file stem → its values (the source's units; see SOURCE_FILES)."""

    folder: Path
    columns: Mapping[str, np.ndarray]

    def __getitem__(self, name: str) -> np.ndarray:
        return self.columns[name]

    @property
    def step_s(self) -> float:
        return float(self.columns["t"][1] - self.columns["t"][0])


@dataclass(frozen=True)
class MeasuredOptions:
    seed: int = 0  # the sensor model's noise
    start_s: float | None = None  # source time of the first sample used; None: the first
    duration_s: float | None = None  # None: to the end
    sensor: dict[str, Any] = field(default_factory=dict)  # SensorSetup overrides (e.g. rates)


def read_channels(folder: Path) -> MeasuredChannels:
    """Read the 15 files; a missing or malformed one is a LogFileError naming it."""
    folder = Path(folder)
    if not folder.is_dir():
        raise LogFileError(
            f"{folder}: no such folder — give the folder of the measured drive's text files "
            f"({', '.join(f'{n}.txt' for n in SOURCE_FILES[:3])}, …)"
        )
    columns = {name: _read_column(folder / f"{name}.txt") for name in SOURCE_FILES}
    n = len(columns["t"])
    for name, values in columns.items():
        if len(values) != n:
            raise LogFileError(
                f"{folder / f'{name}.txt'}: {len(values)} values but t.txt has {n} — the files must "
                "be the columns of one drive"
            )
    t = columns["t"]
    if n < 2:
        raise LogFileError(f"{folder / 't.txt'}: {n} sample — a drive needs at least two")
    steps = np.diff(t)
    uneven = np.flatnonzero((steps <= 0) | (np.abs(steps - steps[0]) >= _STEP_TOLERANCE_S))
    if uneven.size:
        k = int(uneven[0])
        raise LogFileError(
            f"{folder / 't.txt'}: line {k + 2} is {steps[k]:.6g} s after the one before, not "
            f"{steps[0]:.6g} s — the drive must be sampled at one rate, in time order"
        )
    return MeasuredChannels(folder, MappingProxyType(columns))


def _read_column(path: Path) -> np.ndarray:
    try:
        text = path.read_text(encoding="ascii")
    except FileNotFoundError as error:
        raise LogFileError(
            f"{path}: missing — the measured drive needs {len(SOURCE_FILES)} files: "
            f"{', '.join(f'{n}.txt' for n in SOURCE_FILES)}"
        ) from error
    except UnicodeDecodeError as error:
        raise LogFileError(f"{path}: not a text file of numbers (byte {error.start} is not ASCII)") from error
    except OSError as error:
        raise LogFileError(f"{path}: cannot read ({error.strerror})") from error
    tokens = text.split()
    if not tokens:
        raise LogFileError(f"{path}: empty — it should hold one number a line")
    try:
        values = np.array(tokens, dtype=float)
    except ValueError as error:
        k, row = next((k, row) for k, row in enumerate(text.splitlines(), 1) if not _is_numbers(row))
        raise LogFileError(
            f"{path}: line {k} is {row.strip()[:40]!r}, not a number — it should hold one number a line"
        ) from error
    if sum(1 for row in text.splitlines() if row.strip()) != len(tokens):
        k = next(k for k, row in enumerate(text.splitlines(), 1) if len(row.split()) > 1)
        raise LogFileError(f"{path}: line {k} holds several values — it should hold one number a line")
    bad = ~np.isfinite(values)
    if bad.any():
        k = int(np.argmax(bad))
        line = [i for i, row in enumerate(text.splitlines(), 1) if row.strip()][k]
        raise LogFileError(f"{path}: line {line} is {tokens[k]} — every value must be a finite number")
    return values


def _is_numbers(row: str) -> bool:
    try:
        [float(token) for token in row.split()]
    except ValueError:
        return False
    return True


def measured_trace(channels: MeasuredChannels, params: BicycleParams, options: MeasuredOptions) -> DriveTrace:
    """The measured motion as a DriveTrace, time from 0 at the first sample used."""
    t_source = channels["t"]
    first, last = float(t_source[0]), float(t_source[-1])
    start = first if options.start_s is None else options.start_s
    if not first <= start < last:
        raise C2nError(
            f"start {start:g} s is outside the drive ({first:g}–{last:g} s) — choose a time inside"
        )
    end = last if options.duration_s is None else start + options.duration_s
    if not end > start:
        raise C2nError(f"duration {options.duration_s:g} s — give a positive duration")
    half_step = 0.5 * channels.step_s
    used = (t_source >= start - half_step) & (t_source <= end + half_step)
    if used.sum() < 2:
        raise C2nError(f"{start:g}–{end:g} s holds fewer than two samples — give a longer duration")

    def column(name: str) -> np.ndarray:
        return np.asarray(channels[name][used], dtype=float)

    t = column("t")
    return DriveTrace(
        params=params,
        t=t - t[0],
        u=column("vx"),
        # the accelerometer reads axCG (sensors.py puts u_dot on the longitudinal acceleration)
        u_dot=column("axCG"),
        v=column("vy"),
        r=column("yawRate"),
        delta=column("delta"),
        ay=column("ayCG"),
    )


def measured_drive(
    config: Config, folder: Path, options: MeasuredOptions = MeasuredOptions()
) -> SimulatedDrive:
    """The measured drive as the frames of the config's sensor setup, with metadata as its truth."""
    channels = read_channels(folder)
    params = BicycleParams.from_config(config)
    trace = measured_trace(channels, params, options)
    setup = SensorSetup.from_config(config, **options.sensor)
    kistler = load_dbc(DBC_DIR / "kistler_smotion.dbc").database
    ford = load_dbc(DBC_DIR / "vehicle_ford.dbc").database
    messages = frames(trace, setup, kistler, ford, np.random.default_rng(options.seed))
    x_p = setup.d_m - params.b_m
    t0 = float(channels["t"][0]) if options.start_s is None else options.start_s
    ay = trace.u * trace.r
    truth = {
        "measured": True,
        "kind": "measured drive at a virtual sensor point (not a simulation)",
        "source": {**SOURCE, "folder": str(Path(folder).resolve())},
        "licence": SOURCE["licence"],
        "c2n": None,  # unknown: nobody simulated this drive
        "nominal": {"c1n": config.tyres.c1n_per_rad, "c2n": config.tyres.c2n_per_rad},
        "config": str(config.path),
        "d_m": setup.d_m,
        "sensor_point": {
            "d_m": setup.d_m,
            "ahead_of_cg_m": x_p,
            "lateral_m": setup.lateral_m,
            "height_m": setup.height_m,
            "lateral_velocity": f"vy + {x_p:.3f}·r (m/s, vy at the CG)",
        },
        "steering_ratio": setup.steering_ratio,
        "source_t_s": [t0, t0 + float(trace.t[-1])],
        "seed": options.seed,
        "duration_s": float(trace.t[-1]),
        "frames": len(messages),
        "speed_range_mps": [float(trace.u.min()), float(trace.u.max())],
        "max_ay_mps2": float(np.max(np.abs(ay))),
        "median_abs_ay_mps2": float(np.median(np.abs(ay))),
        "sensor": asdict(setup),
        "vehicle": {"a_m": params.a_m, "b_m": params.b_m, "mass_kg": params.mass_kg},
    }
    return SimulatedDrive(messages, truth, trace)


def sideslip_at(trace: DriveTrace, x_m: float) -> np.ndarray:
    """Sideslip [rad] at x metres ahead of the CG: atan2(v + x·r, u)."""
    return np.asarray(np.arctan2(trace.lateral_velocity_at(x_m), trace.u))


def describe(truth: Mapping[str, Any]) -> str:
    low, high = truth["speed_range_mps"]
    return (
        f"measured drive, {truth['duration_s']:.0f} s ({truth['source_t_s'][0]:.2f}–"
        f"{truth['source_t_s'][1]:.2f} s of the source), {truth['frames']} frames; sensor point "
        f"d {truth['d_m']:.3f} m ({truth['sensor_point']['ahead_of_cg_m']:+.3f} m from the CG); "
        f"speed {low:.1f}–{high:.1f} m/s, |a_y| median {truth['median_abs_ay_mps2']:.1f} m/s², "
        f"max {truth['max_ay_mps2']:.1f} m/s²; licence {truth['licence'].split(',')[0]}"
    )
