"""Accuracy of C2n on seeded simulated sessions, printed as medians and worst cases.

Each session: a bicycle-model drive with a random true C2n (10–19 1/rad), S-Motion-like sensor
noise (σ = 0.02 m/s per axis) and the DBCs' resolution (0.01 m/s, 0.01°), written as CAN frames
and run through the same pipeline as `c2n analyze`.

    python tools/accuracy.py [--sessions 20] [--scenarios constant_radius,constant_steer,step_steer]
"""

import argparse
import statistics
import time
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from app.config import load_config
from app.pipeline import Pipeline
from app.sim.session import DriveOptions, simulate_drive


def session(job: tuple[str, int, float]) -> dict[str, object]:
    scenario, seed, optical_hz = job
    truth = float(np.random.default_rng(10_000 + seed).uniform(10.0, 19.0))
    config = load_config()
    drive = simulate_drive(config, DriveOptions(scenario=scenario, seed=seed, c2n=truth, sensor={"optical_hz": optical_hz}))
    pipeline = Pipeline(config)
    started = time.perf_counter()
    for message in drive.messages:
        pipeline.process(message)
    pipeline.finish()
    elapsed = time.perf_counter() - started
    combined = pipeline.state.combined
    return {
        "scenario": scenario,
        "error": None if combined is None else 100 * (combined.c2n / truth - 1),
        "covered": None if combined is None else combined.ci95[0] <= truth <= combined.ci95[1],
        "crossing_errors": [100 * (c.c2n / truth - 1) for c in pipeline.state.crossings],
        "crossing_covered": [c.ci95[0] <= truth <= c.ci95[1] for c in pipeline.state.crossings],
        "frames_per_s": len(drive.messages) / elapsed,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--sessions", type=int, default=20)
    parser.add_argument("--scenarios", default="constant_radius,constant_steer,step_steer")
    parser.add_argument("--optical-hz", type=float, default=100.0)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    scenarios = args.scenarios.split(",")
    jobs = [(s, seed, args.optical_hz) for s in scenarios for seed in range(args.sessions)]
    with ProcessPoolExecutor(args.workers) as pool:
        results = list(pool.map(session, jobs))
    print(f"{args.sessions} seeded sessions per manoeuvre, optical sensor at {args.optical_hz:g} Hz, σ 0.02 m/s")
    print(f"{'manoeuvre':<16} {'combined |err| %':>26} {'95 % CI':>8} {'single crossings |err| %':>30} {'CI':>6}")
    print(f"{'':<16} {'median':>8} {'worst':>8} {'n':>8} {'cover':>8} {'median':>10} {'worst':>9} {'n':>9} {'cover':>6}")
    for scenario in scenarios:
        rows = [r for r in results if r["scenario"] == scenario]
        errors = [abs(r["error"]) for r in rows if r["error"] is not None]  # type: ignore[arg-type]
        covered = [r["covered"] for r in rows if r["covered"] is not None]
        singles = [abs(e) for r in rows for e in r["crossing_errors"]]  # type: ignore[attr-defined]
        single_cover = [c for r in rows for c in r["crossing_covered"]]  # type: ignore[attr-defined]
        print(
            f"{scenario:<16} {statistics.median(errors):8.3f} {max(errors):8.3f} {len(errors):>5}/{len(rows):<2} "
            f"{sum(covered) / len(covered):8.2f} {statistics.median(singles):10.3f} {max(singles):9.3f} "
            f"{len(singles):9d} {sum(single_cover) / len(single_cover):6.2f}"
        )
    speed = statistics.median(r["frames_per_s"] for r in results)  # type: ignore[misc]
    print(f"pipeline throughput (median over sessions): {speed:,.0f} frames/s")


if __name__ == "__main__":
    main()
