"""Offline speed: `c2n analyze`'s pipeline on a simulated BLF against a bare python-can read of
the same file, as the median (min, max) of several runs. Ratios hold on a noisy machine.

    python tools/bench_offline.py [--runs 5] [--minutes 5]
"""

import argparse
import statistics
import tempfile
import time
from pathlib import Path

import can

from app.config import load_config
from app.live import run
from app.pipeline import Pipeline
from app.sim.session import DriveOptions, SimulatedDrive, simulate_drive, write_drive
from app.sources import LogSource


def bare(log: Path) -> int:
    return sum(1 for _ in can.LogReader(log))


def pipeline(log: Path) -> int:
    p = Pipeline(load_config())
    run(LogSource([log]), p, printer=lambda events: None)
    return p.decoder.counts.total


def timed(fn: object, log: Path, runs: int) -> tuple[list[float], int]:
    rates = []
    frames = 0
    for _ in range(runs):
        start = time.perf_counter()
        frames = fn(log)  # type: ignore[operator]
        rates.append(frames / (time.perf_counter() - start))
    return rates, frames


def describe(rates: list[float]) -> str:
    return f"{statistics.median(rates):>10,.0f} frames/s (min {min(rates):,.0f}, max {max(rates):,.0f})"


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--minutes", type=float, default=2.5, help="length of the simulated drive")
    args = parser.parse_args()
    config = load_config()
    drive = simulate_drive(config, DriveOptions(seed=1))
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "drive.blf"
        repeats = max(1, round(args.minutes * 60 / drive.truth["duration_s"]))
        period = drive.truth["duration_s"] + 1.0
        messages = [
            can.Message(
                timestamp=m.timestamp + k * period,
                arbitration_id=m.arbitration_id,
                is_extended_id=m.is_extended_id,
                data=m.data,
                channel=m.channel,
            )
            for k in range(repeats)
            for m in drive.messages
        ]
        write_drive(SimulatedDrive(messages, drive.truth), log)
        bare_rates, frames = timed(bare, log, args.runs)
        pipe_rates, _ = timed(pipeline, log, args.runs)
    print(f"{frames:,} frames, BLF, median (min, max) of {args.runs} runs")
    print(f"bare python-can read  {describe(bare_rates)}")
    print(f"c2n analyze pipeline  {describe(pipe_rates)}")
    print(f"pipeline / bare read  {statistics.median(pipe_rates) / statistics.median(bare_rates):.2f}×")


if __name__ == "__main__":
    main()
