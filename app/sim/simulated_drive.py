"""A simulated test drive: manoeuvre → bicycle model → sensor frames → CAN log + truth."""

from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import can
import numpy as np

from app import paper
from app.config import Config
from app.dbc import load_dbc
from app.errors import C2nError, LogFileError, need
from app.output.files import json_text, text_file, write_together
from app.sim.drive import DriveTrace, simulate
from app.sim.scenarios import SCENARIOS, SweepPlan
from app.sim.sensors import SensorSetup, frames
from app.sim.vehicle_model import BicycleParams, TyreModel

DBC_DIR = Path(__file__).resolve().parents[2] / "dbc"
LOG_SUFFIXES = (".asc", ".blf", ".log", ".csv", ".mf4", ".trc")


@dataclass(frozen=True)
class DriveOptions:
    scenario: str = "constant_radius"
    seed: int = 0
    c2n: float | None = None  # truth; None: the config's [tyres] c2n_per_rad
    tyre: TyreModel = "linear"
    mu: float = 1.0
    sweep_mps2: float = 0.3
    ay_max_mps2: float = 3.5
    speed_lo_factor: float = 0.65  # of the nominal crossing speed
    speed_hi_factor: float = 1.35
    sensor: dict[str, Any] = field(default_factory=dict)  # SensorSetup overrides


@dataclass(frozen=True)
class SimulatedDrive:
    messages: list[can.Message]
    truth: dict[str, Any]
    trace: DriveTrace | None = None  # the motion itself, for checking estimates against it


def simulate_drive(config: Config, options: DriveOptions = DriveOptions()) -> SimulatedDrive:
    if options.scenario not in SCENARIOS:
        raise C2nError(f"unknown scenario '{options.scenario}' — use one of {', '.join(SCENARIOS)}")
    params = BicycleParams.from_config(config, options.c2n, tyre=options.tyre, mu=options.mu)
    ratio = config.vehicle.steering_ratio or 15.0
    nominal_c2n = config.tyres.c2n_per_rad or params.c2n
    u0_nominal = paper.crossing_speed(nominal_c2n, config.d_m, config.vehicle.gravity_mps2)
    plan = SweepPlan(
        params,
        ratio,
        options.speed_lo_factor * u0_nominal,
        options.speed_hi_factor * u0_nominal,
        options.sweep_mps2,
        options.ay_max_mps2,
    )
    scenario = SCENARIOS[options.scenario](plan)
    trace = simulate(params, scenario, ratio)
    setup = SensorSetup.from_config(config, **options.sensor)
    kistler = load_dbc(DBC_DIR / "kistler_smotion.dbc").database
    ford = load_dbc(DBC_DIR / "vehicle_ford.dbc").database
    rng = np.random.default_rng(options.seed)
    messages = frames(trace, setup, kistler, ford, rng)
    g = config.vehicle.gravity_mps2
    truth = {
        "c2n": params.c2n,
        "d_m": setup.d_m,
        "u0_mps": paper.crossing_speed(params.c2n, setup.d_m, g),
        "g_mps2": g,
        "c1n": params.c1n,
        "scenario": options.scenario,
        "seed": options.seed,
        "tyre": options.tyre,
        "duration_s": float(trace.t[-1]),
        "frames": len(messages),
        "max_ay_mps2": float(np.max(np.abs(trace.ay))),
        "sensor": asdict(setup),
        "vehicle": {
            "mass_kg": params.mass_kg,
            "yaw_inertia_kgm2": params.yaw_inertia_kgm2,
            "a_m": params.a_m,
            "b_m": params.b_m,
            "c1_n_per_rad": params.c1_n_per_rad,
            "c2_n_per_rad": params.c2_n_per_rad,
        },
    }
    return SimulatedDrive(messages, truth, trace)


def truth_path(log: Path) -> Path:
    return log.with_name(log.name + ".truth.json")


def write_drive(drive: SimulatedDrive, log: Path) -> Path:
    """Write the frames to ``log`` (format by suffix) and the truth beside it; returns the truth path."""
    if log.suffix.lower() not in LOG_SUFFIXES:
        raise LogFileError(f"{log}: unknown log format '{log.suffix}' — use one of {', '.join(LOG_SUFFIXES)}")
    if log.suffix.lower() == ".mf4":
        need("asammdf", "writing .mf4 logs", "mf4")  # python-can's MF4Writer

    def write(tmp: Path) -> None:
        with can.Logger(tmp) as writer:
            for message in drive.messages:
                writer.on_message_received(message)

    path = truth_path(log)  # both written, then both put in place: never a log beside another's truth
    write_together([(log, write, "the log"), (path, text_file(json_text(drive.truth)), "the truth")])
    return path


def describe(truth: dict[str, Any]) -> str:
    return (
        f"C2n {truth['c2n']:.3f} 1/rad, d {truth['d_m']:.3f} m, u0 {truth['u0_mps']:.3f} m/s "
        f"({truth['u0_mps'] * 3.6:.2f} km/h), {truth['duration_s']:.0f} s, {truth['frames']} frames"
    )
