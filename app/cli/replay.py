"""``c2n replay LOG``: play a log onto a bus with its recorded timing, like canplayer."""

import argparse
import logging
import re
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console
from rich.progress import BarColumn, Progress, TaskProgressColumn, TextColumn, TimeRemainingColumn

from app.cli.common import INTERRUPTED, add_bus, bus_kwargs, channels, number, path_argument
from app.cli.terminal import say
from app.errors import BusError, C2nError, UsageError, printable
from app.user_text import shown

if TYPE_CHECKING:
    import can

log = logging.getLogger(__name__)


def add_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "replay", help="play a CAN log onto a bus in recorded time", description=__doc__
    )
    parser.add_argument("log", type=path_argument, metavar="LOG")
    add_bus(parser)
    parser.add_argument(
        "--rate",
        type=number(0.01, 1e6),  # as slow as `c2n live --rate` takes it
        default=1.0,
        metavar="X",
        help="play X times faster than recorded (0.01: a hundred times slower)",
    )
    parser.add_argument(
        "--loop",
        type=number(1, 1e9, integer=True),
        nargs="?",
        const=None,
        default=1,
        metavar="N",
        help="play N times, N ≥ 1 (--loop alone: until Ctrl-C)",
    )
    parser.add_argument(
        "--map",
        action="append",
        default=[],
        metavar="LOG=BUS",
        help="send the log's channel LOG to the bus channel BUS (repeatable); "
        "default: in order of appearance",
    )
    parser.add_argument(
        "--real-bus",
        action="store_true",
        help="send onto a bus that is not virtual (a car's, a bench's): every node on it gets the "
        "drive's frames, the vehicle speed's among them; without it a replay goes only onto "
        "-i virtual or a SocketCAN vcan",
    )
    parser.set_defaults(run=run)
    return parser


class Router:
    """Which bus each of the log's channels goes to: as ``--map`` says, the others in order of
    appearance onto the buses no map names (the last of them taking any further channels)."""

    def __init__(
        self,
        buses: list["can.BusABC"],
        names: list[str | int | None],
        mapping: list[str],
        log_channels: list[str] | None = None,
    ) -> None:
        self.by_name = {str(name): bus for name, bus in zip(names, buses, strict=True)}
        self.routes: dict[str, can.BusABC] = {}
        for item in mapping:
            source, sep, target = item.partition("=")
            if not sep or not source or target not in self.by_name:
                named = [name for name in self.by_name if name != "None"]  # a bus opened without -c
                listed = f"one of the -c channels {', '.join(named)}" if named else "a channel given with -c"
                raise UsageError(f"--map {printable(item)}: want LOG=BUS with BUS {listed}")
            if log_channels is not None:
                source = log_channel(source, log_channels, item)
            self.routes[source] = self.by_name[target]
        taken = {id(bus) for bus in self.routes.values()}
        self.free = [bus for bus in buses if id(bus) not in taken] or buses
        self.unmapped = 0

    def bus_for(self, msg: "can.Message") -> "can.BusABC":
        key = str(msg.channel)
        bus = self.routes.get(key)
        if bus is None:
            bus = self.free[min(self.unmapped, len(self.free) - 1)]
            self.unmapped += 1
            self.routes[key] = bus
            log.info("log channel %s → %s", key, bus.channel_info)
        return bus


def log_channel(given: str, log_channels: list[str], item: str) -> str:
    """The log's channel a ``--map`` names: itself, or for a bare number N the one channel whose
    name is letters and N (``1`` is a candump log's ``can1``, a BLF's channel 1 is ``1``)."""
    if given in log_channels:
        return given
    if given.isdigit():
        named = [c for c in log_channels if (m := _NUMBERED.fullmatch(c)) and int(m[1]) == int(given)]
        if len(named) == 1:
            return named[0]
    kept = [c for c in log_channels if c not in ("", "None")]  # a frame without one: python-can's None
    if not kept:  # a python-can CSV has no channel column
        raise C2nError(
            f"--map {printable(item)}: the log keeps no channel of its frames, so none can be mapped — "
            "replay it without --map (every frame to the first -c bus)"
        )
    raise C2nError(
        f"--map {printable(item)}: the log has no channel {printable(given)} (its channels: "
        f"{printable(', '.join(kept))})"
    )


_NUMBERED = re.compile(r"[A-Za-z_]+(\d+)")  # can1, vcan1, slcan_1


def _virtual_only(interface: str | None, channel: str | int | None) -> None:
    """Refuse a bus that is not virtual (``bus_kind``): a replay's frames, with the recorded ids
    of the car's own, would reach every node on it."""
    from app.sources import bus_kind

    interface, channel = bus_kind.resolved(interface, channel)
    found = bus_kind.kind(interface, channel)
    if found in ("virtual", "missing"):  # a missing bus: opening it says why
        return
    if channel in (None, ""):
        where, why = f"{interface}", "with no channel each frame goes to the device its log names (can0…)"
    elif found == "real":
        where, why = f"{interface} {channel}", "is not a virtual bus"
    else:
        where, why = f"{interface} {channel}", f"is not known to be virtual (ip -details link show {channel})"
    raise UsageError(
        f"{printable(where)}: {why} — a replay sends the drive's frames, the vehicle speed's among "
        "them, to every node on the bus (a car's ECUs): replay onto -i socketcan -c vcan0 (a virtual "
        "SocketCAN bus), or add --real-bus to send there"
    )


def _in_process_only(interface: str | None) -> bool:
    """Is the bus python-can's ``virtual``, which carries frames between buses of one process?"""
    from app.sources import bus_kind

    return bus_kind.resolved(interface, None)[0] == "virtual"


def channels_of(path: Path) -> list[str]:
    """The log's channels in order of appearance (one pass over the file)."""
    from app.sources.logs import LogReport, read_log

    seen: dict[str, None] = {}
    for msg in read_log(path, LogReport(path)):
        seen.setdefault(str(msg.channel), None)
    return list(seen)


def run(args: argparse.Namespace, console: Console) -> int:
    # loaded when the command runs, not at import: `c2n --help` needs none of them
    import can

    from app.sources.buses import open_buses
    from app.sources.logs import LogReport, check_readable, read_log
    from app.sources.playback import looped, paced

    check_readable(args.log)  # a missing, unknown or damaged file fails before the bus opens
    names = channels(args)
    options = bus_kwargs(args)
    if not args.real_bus:
        for name in names:
            _virtual_only(args.interface, name)
    log_channels = channels_of(args.log) if args.map else None  # a map must name the log's channels
    buses = open_buses(args.interface, names, args.bitrate, **options)
    try:
        router = Router(buses, names, args.map, log_channels)
    except C2nError:
        for bus in buses:
            bus.shutdown()
        raise
    report = LogReport(args.log)
    sent = 0
    progress = Progress(
        TextColumn("replaying {task.fields[name]}"),
        BarColumn(),
        TaskProgressColumn(),
        TextColumn("{task.fields[sent]:,} frames sent"),
        TimeRemainingColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    )
    task = progress.add_task("", total=args.log.stat().st_size or None, name=args.log.name, sent=0)
    try:
        messages = looped(lambda: read_log(args.log, report), None if args.loop is None else int(args.loop))
        with progress:
            for msg in paced(messages, args.rate):
                try:
                    router.bus_for(msg).send(msg)
                except can.CanError as error:
                    raise BusError(f"sending frame {sent + 1} failed: {error}") from error
                sent += 1
                if not sent % 512:  # where the reader is in the file (a loop starts it again)
                    progress.update(task, completed=report.bytes_read() or 0, sent=sent)
    except KeyboardInterrupt:
        interrupted = True
    else:
        interrupted = False
    finally:
        for bus in buses:
            bus.shutdown()
    console.print(f"sent {sent} frames from {shown(args.log)}", style="dim")
    if interrupted and args.loop is not None:  # --loop alone ends so, as meant; N plays did not
        say(f"c2n: interrupted — {sent:,} frames sent, not the whole of {shown(args.log)}")
        return INTERRUPTED
    if _in_process_only(args.interface):
        console.print(
            "c2n: note: python-can's -i virtual reaches only buses in this process: no other program "
            "heard these frames — to feed c2n live, replay onto a SocketCAN vcan (sudo ip link add dev "
            "vcan0 type vcan && sudo ip link set up vcan0), or run c2n demo",
            style="yellow",
            markup=False,
        )
    if report.stopped:
        console.print(
            f"c2n: warning: {printable(f'{args.log}: {report.stopped}')}", style="yellow", markup=False
        )
    return 0
