"""``c2n simulate``: a bicycle-model test drive written as a CAN log, with its truth beside it."""

import argparse
from pathlib import Path

from rich.console import Console

from app.cli.common import add_config
from app.config import load_config
from app.sim.scenarios import SCENARIOS
from app.sim.session import DriveOptions, describe, simulate_drive, write_drive


def add_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "simulate", help="write a simulated test drive as a CAN log", description=__doc__
    )
    parser.add_argument("--scenario", choices=sorted(SCENARIOS), default="constant_radius")
    parser.add_argument(
        "--out", type=Path, metavar="LOG", help="log to write (.blf, .asc, .log, .csv, .mf4, .trc)"
    )
    parser.add_argument("--seed", type=int, default=0, metavar="N")
    add_config(parser)
    parser.add_argument(
        "--c2n", type=float, metavar="X", help="true C2n [1/rad] (default: the config's [tyres])"
    )
    parser.add_argument(
        "--tyre", choices=("linear", "magic"), default="linear", help="linear or saturating tyres"
    )
    parser.add_argument("--mu", type=float, default=1.0, help="peak friction of the saturating tyre")
    parser.add_argument("--sweep-rate", type=float, default=0.3, metavar="MPS2", help="speed sweep rate")
    parser.add_argument(
        "--ay-max", type=float, default=3.5, metavar="MPS2", help="lateral acceleration at the top speed"
    )
    parser.add_argument("--optical-hz", type=float, default=100.0, help="optical sensor rate (50–250)")
    parser.add_argument("--noise", type=float, default=0.02, metavar="MPS", help="optical velocity noise (σ)")
    parser.add_argument(
        "--sensor-lateral", type=float, metavar="M", help="true sensor offset left of the centre line"
    )
    parser.add_argument(
        "--misalignment", type=float, default=0.0, metavar="DEG", help="sensor head yawed left by DEG"
    )
    parser.add_argument("--speed-scale", type=float, default=1.0, help="vehicle speed scale error")
    parser.add_argument("--speed-latency", type=float, default=0.0, metavar="S", help="vehicle speed delay")
    parser.add_argument(
        "--single-channel", action="store_true", help="sensor and vehicle frames on one channel"
    )
    parser.set_defaults(run=run)
    return parser


def run(args: argparse.Namespace, console: Console) -> int:
    config = load_config(args.config)
    sensor: dict[str, object] = {
        "optical_hz": args.optical_hz,
        "sigma_velocity_mps": args.noise,
        "yaw_misalignment_deg": args.misalignment,
        "speed_scale": args.speed_scale,
        "speed_latency_s": args.speed_latency,
    }
    if args.sensor_lateral is not None:
        sensor["lateral_m"] = args.sensor_lateral
    if args.single_channel:
        sensor["sensor_channel"] = 0
    options = DriveOptions(
        scenario=args.scenario,
        seed=args.seed,
        c2n=args.c2n,
        tyre=args.tyre,
        mu=args.mu,
        sweep_mps2=args.sweep_rate,
        ay_max_mps2=args.ay_max,
        sensor=sensor,
    )
    out = args.out or Path(f"sim-{args.scenario}-seed{args.seed}.blf")
    drive = simulate_drive(config, options)
    truth = write_drive(drive, out)
    console.print(f"wrote {out} and {truth.name}: {describe(drive.truth)}")
    return 0
