"""A real measured drive as a CAN log in the project's layouts, ready for ``c2n analyze`` and ``c2n gap``.

Reads the 15 text files of the Stanford Revs Thunderhill drive (vx, vy at the CG, yaw rate,
road-wheel steer, accelerations at 100 Hz; ``data/real/stanford-revs-thunderhill``), puts a
virtual optical sensor d ahead of the rear axle (the config's ``sensor_ahead_of_rear_axle_m``),
and writes the frames a Kistler S-Motion and the Ford vehicle bus would carry (the project's
sensor model: noise, the DBCs' resolution, the sensors' rates) in any format ``c2n simulate``
writes, with ``<log>.truth.json`` beside it: where the data come from, their licence and the
sensor point.

    python tools/measured_drive.py DATA_DIR --out drive.blf [--config config/revs_250lm.toml]
    c2n analyze drive.blf --config config/revs_250lm.toml
    c2n gap drive.blf --config config/revs_250lm.toml --json gap.json
"""

import argparse
import sys
import time
from collections.abc import Sequence
from pathlib import Path

from app.config import load_config
from app.errors import C2nError
from app.sim.measured_drive import MeasuredOptions, describe, measured_drive
from app.sim.simulated_drive import write_drive

DEFAULT_CONFIG = Path(__file__).resolve().parents[1] / "config" / "revs_250lm.toml"


def main(argv: Sequence[str] | None = None) -> int:
    """Returns the exit code: 0 written, 1 a user error (one line on stderr), 2 bad usage."""
    parser = argparse.ArgumentParser(
        prog="measured_drive.py", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("data", type=Path, metavar="DATA_DIR", help="the folder of the 15 text files")
    parser.add_argument("--out", type=Path, required=True, metavar="LOG", help=".blf, .mf4, .log, .asc…")
    parser.add_argument("--config", type=Path, default=DEFAULT_CONFIG, metavar="F", help="vehicle config")
    parser.add_argument("--seed", type=int, default=0, help="the sensor noise's seed")
    parser.add_argument("--start", type=float, metavar="S", help="source time to start at [s]")
    parser.add_argument("--duration", type=float, metavar="S", help="seconds of the drive to keep")
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_:
        return int(exit_.code or 0)
    started = time.perf_counter()
    try:
        config = load_config(args.config)
        options = MeasuredOptions(seed=args.seed, start_s=args.start, duration_s=args.duration)
        drive = measured_drive(config, args.data, options)
        truth = write_drive(drive, args.out)
    except C2nError as error:
        print(f"measured_drive: error: {error}", file=sys.stderr)
        return 1
    seconds = time.perf_counter() - started
    print(f"wrote {args.out} and {truth.name} in {seconds:.1f} s: {describe(drive.truth)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
