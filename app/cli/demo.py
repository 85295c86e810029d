"""``c2n demo``: a simulated drive replayed time-compressed over a python-can virtual bus into the
live dashboard; the crossings print as they happen, then C2n beside the simulated truth."""

import argparse
import os
import tempfile
import threading
import uuid
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console
from rich.text import Text

from app.cli.common import ENDING, INTERRUPTED, SEED, add_config, interrupted_by, number
from app.cli.terminal import say
from app.config import Config, load_config
from app.errors import C2nError
from app.output import files
from app.sim.scenarios import SCENARIOS
from app.user_text import shown

if TYPE_CHECKING:
    import can

    from app.sim.simulated_drive import SimulatedDrive


def add_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "demo", help="simulated drive → virtual CAN bus → live dashboard", description=__doc__
    )
    parser.add_argument(
        "--speedup",
        type=number(0.0, 1e6, low_allowed=False),
        default=10.0,
        metavar="X",
        help="replay X times faster than driven",
    )
    parser.add_argument("--seed", type=SEED, default=2026, metavar="N", help="seed of the simulated drive")
    parser.add_argument("--scenario", choices=sorted(SCENARIOS), default="constant_radius")
    add_config(parser)
    parser.set_defaults(run=run)
    return parser


class Player(threading.Thread):
    """Sends a log onto a bus in compressed recorded time; sets ``finished`` when done."""

    def __init__(self, log: Path, bus: "can.BusABC", rate: float, stop: threading.Event) -> None:
        super().__init__(name="c2n-player", daemon=True)
        self.log, self.bus, self.rate, self.stop = log, bus, rate, stop
        self.finished = threading.Event()
        self.error: BaseException | None = None
        self.sent = 0
        self.whole = False  # every frame of the log sent: not stopped first

    def run(self) -> None:
        from app.sources.logs import LogReport, read_log
        from app.sources.playback import paced

        try:
            for msg in paced(read_log(self.log, LogReport(self.log)), self.rate):
                if self.stop.is_set():
                    break
                self.bus.send(msg)
                self.sent += 1
            else:
                self.whole = True
        except Exception as error:
            self.error = error
        finally:
            self.finished.set()


def run(args: argparse.Namespace, console: Console) -> int:
    # loaded when the command runs, not at import: `c2n --help` needs none of them
    from app.sim.simulated_drive import DriveOptions, describe, simulate_drive

    config = load_config(args.config)
    console.print(f"c2n demo: simulating a {args.scenario} drive (seed {args.seed})…", style="dim")
    drive = simulate_drive(config, DriveOptions(scenario=args.scenario, seed=args.seed))
    console.print(f"the drive: {describe(drive.truth)}", style="dim")
    channel = f"c2n-demo-{uuid.uuid4().hex[:8]}"
    remove_stale()
    with interrupted_by(*ENDING):  # unwinds: the temporary folder goes too
        return _replay(args, console, config, drive, channel)


TEMP_PREFIX = "c2n-demo-"


def remove_stale(root: Path | None = None) -> list[Path]:
    """Remove the temporary folders of demos that were killed (SIGKILL leaves them): each is
    named after its process, and one whose process is gone is stale. Returns what it removed."""
    return files.remove_stale(root or Path(tempfile.gettempdir()), TEMP_PREFIX)


def _replay(
    args: argparse.Namespace, console: Console, config: Config, drive: "SimulatedDrive", channel: str
) -> int:
    import can

    from app.pipeline import PartedPipeline
    from app.run_loop import run as run_pipeline
    from app.sim.simulated_drive import write_drive
    from app.sinks.dashboard import Dashboard
    from app.sinks.event_printer import EventPrinter, print_result
    from app.sources.buses import BusSource

    truth = drive.truth
    with tempfile.TemporaryDirectory(prefix=f"{TEMP_PREFIX}{os.getpid()}-") as tmp:
        log = Path(tmp) / "demo-drive.blf"
        write_drive(drive, log)
        stop = threading.Event()
        with (
            can.Bus(interface="virtual", channel=channel, preserve_timestamps=True) as tx,
            can.Bus(interface="virtual", channel=channel) as rx,
        ):
            player = Player(log, tx, args.speedup, stop)
            pipeline = PartedPipeline(config)
            console.print(
                f"replaying {shown(log.name)} ×{args.speedup:g} over virtual bus {channel}", style="dim"
            )
            player.start()
            try:
                run_pipeline(
                    BusSource([rx], stop, finished=player.finished),
                    pipeline,
                    [EventPrinter(console)],
                    display=Dashboard(f"virtual bus {channel}, replay ×{args.speedup:g}"),
                    console=console,
                )
            finally:
                stop.set()
                player.join(timeout=5.0)
    if player.error is not None:
        raise C2nError(f"the replay failed: {player.error}")
    snapshot = pipeline.snapshot()
    headline = snapshot.headline
    print_result(console, snapshot)
    if not player.whole:  # Ctrl-C, SIGTERM: no word of the truth, which is the whole drive's
        say(
            f"c2n: interrupted — {player.sent:,} of the drive's {truth['frames']:,} frames replayed: "
            "the result above is theirs"
        )
        return INTERRUPTED
    if headline is not None:
        error = 100.0 * (headline.c2n / truth["c2n"] - 1.0)
        console.print(
            Text(
                f"simulated truth C2n = {truth['c2n']:.3f} 1/rad (u0 = {truth['u0_mps']:.3f} m/s): "
                f"error {error:+.2f} %",
                style="bold",
            )
        )
    return 0
