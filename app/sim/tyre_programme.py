"""A simulated tyre programme to try ``c2n campaign`` on: N drives of a few tyre sets.

Each tyre set has a true C2n and a pressure; each drive is on a day, and a day moves each set's
C2n a little (temperature, wear: ``DAY_SCATTER``), so the sessions of one set disagree by more
than their own intervals — what a random-effects comparison is for. The drives are speed sweeps
on two circles in both directions (``c2n simulate --scenario radii``: two radii let the fit tell
tyre softening from the sensor position), written as BLF logs beside a ``manifest.csv``; the
truth is sealed in ``sealed/truth.json``.
"""

import csv
import io
import os
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from app.config import DEFAULT_CONFIG, load_config
from app.errors import C2nError, OutputError
from app.output.files import folder_atomically, write_json, write_text
from app.sim.pack import write_log
from app.sim.simulated_drive import DriveOptions, simulate_drive
from app.sim.workers import ends_with_parent

# tyre set -> (true C2n [1/rad], pressure [kPa]): stiffer with pressure, as tyres are
TYRE_SETS: dict[str, tuple[float, float]] = {"A": (13.8, 200.0), "B": (14.9, 230.0), "C": (16.1, 260.0)}
DAY_SCATTER = 0.012  # σ of a session's C2n about its set's, relative
DAYS = 4


@dataclass(frozen=True)
class SessionSpec:
    name: str
    tyre_set: str
    pressure_kpa: float
    day: int
    seed: int
    c2n: float


def plan_campaign(n: int, seed: int) -> list[SessionSpec]:
    rng = np.random.default_rng(seed)
    sets = list(TYRE_SETS)
    specs = []
    for i in range(n):
        tyre_set = sets[i % len(sets)]
        nominal, pressure = TYRE_SETS[tyre_set]
        day = 1 + (i // len(sets)) % DAYS
        c2n = nominal * (1 + DAY_SCATTER * float(rng.standard_normal()))
        specs.append(SessionSpec(f"s{i + 1:03d}", tyre_set, pressure, day, seed * 1000 + i, c2n))
    return specs


def write_campaign(
    out: Path,
    n: int,
    seed: int,
    config_path: Path = DEFAULT_CONFIG,
    workers: int | None = None,
    on_session: Callable[[SessionSpec, float], None] | None = None,
    sensor: dict[str, Any] | None = None,
) -> Path:
    """Write the drives, ``manifest.csv`` and ``sealed/truth.json`` into ``out`` (new or empty);
    returns the manifest's path."""
    if n < 1:
        raise C2nError(f"a campaign needs at least one session, not {n}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise OutputError(f"{out}: exists and is not an empty folder — choose a new one")
    load_config(config_path)  # a bad config fails here, once
    specs = plan_campaign(n, seed)
    # written in a hidden folder beside ``out``, renamed to it when whole: a Ctrl-C, a kill or a
    # full disk leaves no half campaign under its name
    with folder_atomically(out, lambda path: False, "c2n simulate", replace=False) as staging:
        _write_sessions(staging, specs, config_path, workers, on_session, sensor or {})
        text = io.StringIO()
        writer = csv.writer(text, lineterminator="\n")
        writer.writerow(["log", "tyre_set", "pressure_kPa", "day"])
        for spec in specs:
            writer.writerow([f"logs/{spec.name}.blf", spec.tyre_set, f"{spec.pressure_kpa:g}", spec.day])
        write_text(staging / "manifest.csv", text.getvalue(), "the manifest")
        truth = {
            "seed": seed,
            "tyre_sets": {name: {"c2n": c2n, "pressure_kPa": p} for name, (c2n, p) in TYRE_SETS.items()},
            "day_scatter": DAY_SCATTER,
            "sessions": {
                f"logs/{s.name}.blf": {"tyre_set": s.tyre_set, "day": s.day, "c2n": s.c2n} for s in specs
            },
        }
        write_json(staging / "sealed" / "truth.json", truth, "the sealed truth")
    manifest = out / "manifest.csv"
    return manifest


def _write_sessions(
    out: Path,
    specs: list[SessionSpec],
    config_path: Path,
    workers: int | None,
    on_session: Callable[[SessionSpec, float], None] | None,
    sensor: dict[str, Any],
) -> None:
    (out / "logs").mkdir(parents=True, exist_ok=True)
    jobs = [(Path(config_path), out / "logs" / f"{spec.name}.blf", spec, sensor) for spec in specs]
    workers = max(1, min(workers or os.cpu_count() or 1, len(specs)))
    pool = ProcessPoolExecutor(max_workers=workers, initializer=ends_with_parent)
    try:
        futures = {pool.submit(_write_session, *job): job[2] for job in jobs}
        for future in as_completed(futures):
            elapsed = future.result()
            if on_session:
                on_session(futures[future], elapsed)
    finally:  # a Ctrl-C: the drives not begun are not simulated
        pool.shutdown(wait=True, cancel_futures=True)


def _write_session(config_path: Path, log: Path, spec: SessionSpec, sensor: dict[str, Any]) -> float:
    start = time.perf_counter()
    options = DriveOptions(scenario="radii", seed=spec.seed, c2n=spec.c2n, sensor=sensor)
    drive = simulate_drive(load_config(config_path), options)
    write_log(drive.messages, log)  # the truth goes under sealed/, not beside the log
    return time.perf_counter() - start
