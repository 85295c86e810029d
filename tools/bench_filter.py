"""Filter quality against the simulated truth, and which sideslip signal to trust.

For each optical-noise level: the RMS error of the raw sideslip from the sensor's Angle signal
(0.01° per bit) and from atan2(VelY, VelX) (0.01 m/s per bit), of the Kalman-filtered and of the
RTS-smoothed sideslip; then the C2n error (regression and paired crossings) with the filter fed
the Angle or VelY. Errors are against the bicycle model's own sideslip at the sensor, on steady
cornering (|r| > 0.05 rad/s).

    python tools/bench_filter.py [--sessions 6]
"""

import argparse
import dataclasses
import statistics
from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np

from app.config import Config, load_config
from app.estimate.smoother import smooth
from app.pipeline import Pipeline
from app.sim.sensors import LOG_START
from app.sim.simulated_drive import DriveOptions, simulate_drive


def with_source(config: Config, source: str) -> Config:
    return dataclasses.replace(config, filter=dataclasses.replace(config.filter, sideslip_source=source))  # type: ignore[arg-type]


def session(job: tuple[float, int]) -> dict[str, Any]:
    noise, seed = job
    truth_c2n = float(np.random.default_rng(20_000 + seed).uniform(11.0, 18.0))
    config = load_config()
    drive = simulate_drive(
        config, DriveOptions(scenario="radii", seed=seed, c2n=truth_c2n, sensor={"sigma_velocity_mps": noise})
    )
    trace = drive.trace
    assert trace is not None
    x_s = config.d_m - trace.params.b_m
    true_beta = np.arctan2(trace.lateral_velocity_at(x_s), trace.u)
    kistler = config.dbcs[0].database.get_message_by_name("Correvit")
    t, angle, atan = [], [], []
    for message in drive.messages:
        if message.arbitration_id == kistler.frame_id:
            values = kistler.decode(message.data)
            t.append(message.timestamp - LOG_START)
            angle.append(np.radians(values["Angle_cor"]))
            atan.append(np.arctan2(values["VelY_cor"], values["VelX_cor"]))
    t_arr = np.array(t)
    turning = np.abs(np.interp(t_arr, trace.t, trace.r)) > 0.05
    truth = np.interp(t_arr, trace.t, true_beta)

    def rms(values: np.ndarray, mask: np.ndarray, reference: np.ndarray) -> float:
        return float(np.degrees(np.sqrt(np.mean((values[mask] - reference[mask]) ** 2))))

    result: dict[str, Any] = {
        "noise": noise,
        "raw angle": rms(np.array(angle), turning, truth),
        "raw atan2": rms(np.array(atan), turning, truth),
    }
    for track in smooth(config, drive.messages):
        mask = np.abs(np.interp(track.t - LOG_START, trace.t, trace.r)) > 0.05
        reference = np.interp(track.t - LOG_START, trace.t, true_beta)
        result.setdefault("filtered", []).append(rms(track.sideslip(False), mask, reference))
        result.setdefault("smoothed", []).append(rms(track.sideslip(True), mask, reference))
    result["filtered"] = statistics.mean(result["filtered"])
    result["smoothed"] = statistics.mean(result["smoothed"])
    for source in ("beta", "vy"):
        pipeline = Pipeline(with_source(config, source))
        for message in drive.messages:
            pipeline.process(message)
        pipeline.finish()
        fit, paired = pipeline.state.regression, pipeline.state.paired
        result[f"regression {source}"] = abs(100 * (fit.c2n / truth_c2n - 1)) if fit else float("nan")
        result[f"paired {source}"] = abs(100 * (paired.c2n / truth_c2n - 1)) if paired else float("nan")
    return result


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sessions", type=int, default=6)
    parser.add_argument("--noise", default="0.005,0.02", help="optical velocity noise levels σ [m/s]")
    args = parser.parse_args()
    levels = [float(n) for n in args.noise.split(",")]
    jobs = [(noise, seed) for noise in levels for seed in range(args.sessions)]
    with ProcessPoolExecutor(2) as pool:
        results = list(pool.map(session, jobs))
    print(
        f"{args.sessions} two-radius sessions per noise level; sideslip RMS error [deg] on steady cornering,"
    )
    print("C2n |error| [%] median with the filter fed the Angle or VelY")
    keys = [
        "raw angle",
        "raw atan2",
        "filtered",
        "smoothed",
        "regression beta",
        "regression vy",
        "paired beta",
        "paired vy",
    ]
    print(f"{'σ [m/s]':>8} " + " ".join(f"{k:>16}" for k in keys))
    for noise in levels:
        rows = [r for r in results if r["noise"] == noise]
        print(f"{noise:8.3f} " + " ".join(f"{statistics.median(r[k] for r in rows):16.4f}" for k in keys))


if __name__ == "__main__":
    main()
