"""The paper's Tables 1 and 2 rebuilt: paper value, our value and the truth side by side.

Table 1 — the paper's simulated car: tyre-model C2n = 11.37 1/rad (C2 = 46 494 N/rad, W2 = 4090 N,
eqs. 8–9) and a sensor d2 = 1.265 m ahead of the rear axle (so that eq. 10 gives u0 = 11.88 m/s).
The paper does not give the rest of the car; we assume a 2.5 m wheelbase, a front axle load of
5500 N, C1n = 12.5 1/rad and Magic-Formula tyres (μ = 1, shape 1.3), which soften with slip as the
paper's Fig. 3 shows. Constant steering sweeps the speed up and down through u0 at fixed
road-wheel angles, left and right (Fig. 2); step steers hold a steering angle at speeds from 4 to
16 m/s (Figs. 5–6). Optical sensor noise σ = 0.02 m/s at 100 Hz.

Table 2 — the Ford Mondeo: the estimate from u0 = 46 km/h and d = 1.11 m (eq. 10), and our
estimate from a simulated two-radius drive whose truth is the tyre-rig value.

    python tools/paper_tables.py
"""

import dataclasses
import math
from concurrent.futures import ProcessPoolExecutor

import numpy as np

from app import paper
from app.config import Config, load_config
from app.dbc import load_dbc
from app.pipeline import Pipeline
from app.sim.drive import simulate
from app.sim.scenarios import Scenario, Segment, Steer, SweepPlan, step_steer
from app.sim.sensors import SensorSetup, frames
from app.sim.simulated_drive import DBC_DIR, DriveOptions, simulate_drive
from app.snapshot import Snapshot

C2N_TRUTH = paper.normalised_stiffness(46494, 4090)  # eq. 9: 11.37
D2 = 11.88**2 / (C2N_TRUTH * paper.G)  # eq. 10 backwards: 1.265 m
WHEELBASE, W1, C1N = 2.5, 5500.0, 12.5


def paper_car_config() -> Config:
    config = load_config()
    vehicle = dataclasses.replace(
        config.vehicle,
        sensor_ahead_of_rear_axle_m=D2,
        wheelbase_m=WHEELBASE,
        front_axle_load_N=W1,
        rear_axle_load_N=4090.0,
    )
    return dataclasses.replace(config, vehicle=vehicle)


def constant_steer_sweep(road_wheel_deg: tuple[float, ...], plan: SweepPlan) -> Scenario:
    """Fixed road-wheel angles one after another (Fig. 2), the speed swept up and down through u0
    at each, left then right."""
    lo, hi = plan.speed_lo_mps, plan.speed_hi_mps
    sweep_s = (hi - lo) / plan.sweep_mps2
    segments = [Segment(3.0, lo, Steer("straight"))]
    for angle in road_wheel_deg:
        for sign in (1, -1):
            turn = Steer("wheel", sign * math.radians(angle) * plan.steering_ratio)
            segments += [
                Segment(6.0, lo, turn),
                Segment(sweep_s, hi, turn),
                Segment(2.0, hi, turn),
                Segment(sweep_s, lo, turn),
                Segment(2.0, lo, turn),
                Segment(4.0, lo, Steer("straight")),
            ]
    return Scenario("constant_steer", lo, tuple(segments))


def run_paper_car(job: tuple[str, tuple[float, ...], int]) -> tuple[str, tuple[float, ...], Snapshot]:
    kind, angles, seed = job
    from app.sim.vehicle_model import BicycleParams

    config = paper_car_config()
    params = BicycleParams.from_axle_loads(WHEELBASE, W1, 4090.0, C1N, C2N_TRUTH, tyre="magic", mu=1.0)
    u0 = paper.crossing_speed(C2N_TRUTH, D2)
    plan = SweepPlan(params, 15.0, 0.55 * u0, 1.45 * u0, sweep_mps2=0.3)
    if kind == "constant steering":
        scenario = constant_steer_sweep(angles, plan)
    else:
        speeds = tuple(float(s) for s in np.arange(4.0, 16.01, 1.0))
        scenario = step_steer(plan, speeds_mps=speeds, wheel_deg=angles[0] * plan.steering_ratio)
    trace = simulate(params, scenario, 15.0)
    setup = SensorSetup(d_m=D2)
    kistler = load_dbc(DBC_DIR / "kistler_smotion.dbc").database
    ford = load_dbc(DBC_DIR / "vehicle_ford.dbc").database
    pipeline = Pipeline(config)
    for message in frames(trace, setup, kistler, ford, np.random.default_rng(seed)):
        pipeline.process(message)
    pipeline.finish()
    return kind, angles, _portable(pipeline.snapshot())


def run_mondeo(job: tuple[float, int]) -> tuple[float, Snapshot]:
    c2n, seed = job
    config = load_config()
    drive = simulate_drive(config, DriveOptions(scenario="radii", seed=seed, c2n=c2n))
    pipeline = Pipeline(config)
    for message in drive.messages:
        pipeline.process(message)
    pipeline.finish()
    return c2n, _portable(pipeline.snapshot())


def _portable(state: Snapshot) -> Snapshot:
    """The snapshot with its read-only views as dicts: a worker process can send it back."""
    noise = dataclasses.replace(state.filter, noise_sigma=dict(state.filter.noise_sigma))
    return dataclasses.replace(
        state,
        latest=dict(state.latest),
        status=dict(state.status),
        message_names=dict(state.message_names),
        filter=noise,
    )


def describe(state: Snapshot) -> str:
    parts = []
    crossings = state.paired or state.combined
    if crossings is not None:
        parts.append(f"crossings {crossings.c2n:6.2f} ({100 * (crossings.c2n / C2N_TRUTH - 1):+5.1f} %)")
    else:
        parts.append(f"crossings {'—':>6} {'':9}")
    if state.regression is not None:
        fit = state.regression
        parts.append(
            f"regression {fit.c2n:6.2f} ({100 * (fit.c2n / C2N_TRUTH - 1):+5.1f} %, {fit.models.chosen})"
        )
    return "  ".join(parts)


def main() -> None:
    angles = (1.0, 2.0, 3.0, 5.0)
    jobs = [("constant steering", angles, 1), ("step steer", (2.0,), 2)]
    jobs += [("constant steering", (a,), 10 + i) for i, a in enumerate(angles)]  # each angle alone
    with ProcessPoolExecutor(2) as pool:
        table1 = list(pool.map(run_paper_car, jobs))
        table2 = list(pool.map(run_mondeo, [(14.87, 3), (15.63, 4)]))

    print(f"Table 1 — simulated car, tyre model C2n = {C2N_TRUTH:.2f} 1/rad (truth), d2 = {D2:.3f} m")
    print(f"{'':<40}{'paper':>8}   ours: session headline, and the crossings (error against the truth)")
    print(f"{'tyre model (eqs. 8–9)':<40}{11.37:>8.2f}   {C2N_TRUTH:.2f}")
    for kind, used, state in table1:
        paper_value = 10.97 if kind == "constant steering" else 11.60
        if len(used) > 1 or kind == "step steer":
            label = f"{kind}, {'/'.join(f'{a:g}' for a in used)}° road wheel"
            head = state.headline
            if head is None:
                print(f"{label:<40}{paper_value:>8.2f}   no result")
                continue
            error, paper_error = 100 * (head.c2n / C2N_TRUTH - 1), 100 * (paper_value / C2N_TRUTH - 1)
            verdict = (
                "closer to the truth"
                if abs(head.c2n - C2N_TRUTH) < abs(paper_value - C2N_TRUTH)
                else "NOT closer"
            )
            comparison = f"({error:+.1f} % vs the paper's {paper_error:+.1f} %: {verdict})"
            print(f"{label:<40}{paper_value:>8.2f}   {head.c2n:6.2f} {comparison}")
            print(f"{'':<48}   {describe(state)}")
        else:
            alone = f"  at {used[0]:g}° alone (crossings at its a_y)"
            print(f"{alone:<40}{'':>8}   {describe(state)}")
    print()
    print("Table 2 — Ford Mondeo, d = 1.11 m")
    columns = f"{'tyre':<10}{'paper estimated':>16}{'eq. 10 here':>13}{'test rig':>10}{'paper error':>13}"
    print(columns + "   ours on a simulated drive")
    for name, estimated, rig, u0_kmh in (("tyre 1", 14.99, 14.87, 46.0), ("tyre 2", 15.99, 15.63, None)):
        if u0_kmh is None:
            u0_kmh = paper.crossing_speed(estimated, 1.11) * 3.6
        here = paper.c2n_from_crossing(u0_kmh / 3.6, 1.11)
        state = next(s for c, s in table2 if c == rig)
        head = state.headline
        ours = f"{head.c2n:.2f} ({100 * (head.c2n / rig - 1):+.2f} % against the rig)" if head else "—"
        error = 100 * (estimated / rig - 1)
        print(
            f"{name:<10}{estimated:>16.2f}{here:>13.2f}{rig:>10.2f}{error:>12.2f}%   "
            f"{ours}   (u0 {u0_kmh:.1f} km/h)"
        )
    for name, value in (("tyre 3 (ice)", 7.95), ("tyre 2 (ice)", 9.35)):
        print(f"{name:<14}{value:>12.2f}{'':>13}{'—':>10}   no rig value on ice")


if __name__ == "__main__":
    main()
