"""Options and helpers several commands share."""

import argparse
import math
import signal
import sys
import threading
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any

from rich.console import Console

from app.cli.terminal import console_stream
from app.config import DEFAULT_CONFIG, Config
from app.errors import UsageError, printable

if TYPE_CHECKING:
    from app.snapshot import Snapshot
    from app.sources.logs import LogReport


def add_config(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--config",
        type=path_argument,
        default=DEFAULT_CONFIG,
        metavar="F",
        help="vehicle config (default: config/mondeo.toml)",
    )


def add_bus(parser: argparse.ArgumentParser) -> None:
    """python-can's -i/-c/-b; unset values come from its config file and CAN_* variables."""
    parser.add_argument(
        "-i",
        "--interface",
        metavar="IFACE",
        help="python-can interface: socketcan, pcan, kvaser, vector, virtual…",
    )
    parser.add_argument(
        "-c",
        "--channel",
        action="append",
        metavar="CHANNEL",
        help="channel; repeat for several (-c can0 -c can1)",
    )
    parser.add_argument("-b", "--bitrate", type=int, metavar="BITRATE", help="bit rate, e.g. 1000000")
    parser.add_argument("--fd", action="store_true", help="CAN FD")
    parser.add_argument(
        "--bus-arg",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="extra python-can bus argument (repeatable)",
    )


def channels(args: argparse.Namespace) -> list[str | int | None]:
    """Channel names as given; bare numbers become ints (Vector, Kvaser, … count from 0)."""
    given: list[str] = args.channel or []
    named: list[str | int | None] = [int(c) if c.isdigit() else c for c in given]
    twice = next((c for i, c in enumerate(named) if c in named[:i]), None)
    if twice is not None:  # read twice, every frame would be recorded and decoded twice
        raise UsageError(f"-c {printable(str(twice))} is given twice — name each channel once")
    return named or [None]


# python-can arguments that have their own option: a --bus-arg naming one would be given twice
_OWN_OPTION = {"interface": "-i", "bustype": "-i", "channel": "-c", "bitrate": "-b", "fd": "--fd"}


def bus_kwargs(args: argparse.Namespace) -> dict[str, object]:
    options: dict[str, object] = {}
    if args.fd:
        options["fd"] = True
    for item in args.bus_arg:
        key, sep, value = item.partition("=")
        if not sep or not key:
            raise UsageError(f"--bus-arg wants KEY=VALUE, got {item!r}")
        if key in _OWN_OPTION:
            raise UsageError(f"--bus-arg {printable(item)}: {key} has its own option, use {_OWN_OPTION[key]}")
        options[key] = int(value) if value.isdigit() else value
    return options


def _seed(text: str) -> int:
    """An argparse ``type``: a seed numpy accepts, 0 to 2³²−1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if not 0 <= value < 2**32:
        raise argparse.ArgumentTypeError(f"{text} is out of range: a seed is 0 to {2**32 - 1}")
    return value


SEED = _seed


def error_console() -> Console:
    return Console(file=console_stream(sys.stderr), highlight=False, soft_wrap=True)


def no_role_decoded(snapshot: "Snapshot", config: Config, logs: Sequence[Path]) -> str | None:
    """Why a run has nothing to show at all: not one frame carried a role of the config — its
    DBCs or ids are not this log's (another car's, or the wrong config). Said before anything
    the run found: a result line would blame the drive ("no cornering") for what the log lacks."""
    if any(snapshot.frames.role_frames[role] for role in config.roles):
        return None
    logs_said = ", ".join(str(p) for p in logs)
    elsewhere = snapshot.frames.other_channel
    if elsewhere:  # the ids are there, on channels the config's [channels] does not name for them
        channels = sorted({str(spec.channel) for spec in config.roles.values() if spec.channel is not None})
        return (
            f"{logs_said}: no frames for any role of {config.path} on the channels it names for them "
            f"({', '.join(channels)}), though {elsewhere:,} frames of their ids came on others — set "
            "[channels] to the channels this log carries them on, or leave it out (a CSV log keeps none)"
        )
    return (
        f"{logs_said}: no frames for any role of {config.path} — wrong DBC or config for this log? give "
        "the car's with --config"
    )


def parts_disagree(report: "LogReport", config: Config, console: Console) -> str | None:
    """Where the optical sensor's frames paused in ``report``'s file, its parts between the
    pauses each analysed alone (``app.results.within_file``, under a spinner): one line naming
    each part's result where they disagree; None where they agree or the file did not pause."""
    if not (report.spacing.pauses or report.spacing.rewinds):
        return None
    from app.pipeline import Pipeline
    from app.results.within_file import Parting
    from app.results.within_file import parts_disagree as disagree

    parts = Parting(report.spacing)
    with console.status(
        f"the {parts.count} parts of {report.path.name} between its {parts.between}, each alone…"
    ):
        return disagree(report, config, Pipeline)


def number(
    low: float, high: float, *, low_allowed: bool = True, integer: bool = False
) -> Callable[[str], float]:
    """An argparse ``type``: a finite number from ``low`` (itself allowed or not) to ``high``;
    anything else is a usage error (exit 2) naming the range."""

    def parse(text: str) -> float:
        try:
            value = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"{text!r} is not {'an integer' if integer else 'a number'}"
            ) from None
        inside = math.isfinite(value) and (low <= value if low_allowed else low < value) and value <= high
        if not inside:
            lowest = f"{low:g} to" if low_allowed else f"above {low:g} up to"
            raise argparse.ArgumentTypeError(f"{text} is out of range: use {lowest} {high:g}")
        return value

    return parse


def add_force(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--force",
        action="store_true",
        help="replace an existing output file that c2n did not write (never an input of the command)",
    )


def path_argument(text: str) -> Path:
    """A path's value on the command line; ``''`` (an unset shell variable: ``--out "$DIR"``) is a
    usage error — ``Path('')`` is ``.``, and a command went on in a folder never named."""
    if not text:
        raise argparse.ArgumentTypeError("an empty name ('') — an unset shell variable? give a path")
    return Path(text)


INTERRUPTED = 130  # the exit code of a command ended by Ctrl-C, SIGTERM or SIGHUP (128 + SIGINT)

# The signals that end a command as Ctrl-C does: Ctrl-C, a shutdown's or `kill`'s SIGTERM, and the
# terminal closed or an ssh session dropped (SIGHUP, POSIX only).
ENDING: tuple[signal.Signals, ...] = tuple(
    sig for sig in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None)) if sig is not None
)


def interrupt(signum: int, frame: FrameType | None) -> None:
    """A signal handler: the signal ends the command as Ctrl-C does."""
    raise KeyboardInterrupt


def take_over(
    signals: Iterable[signal.Signals], handler: Callable[[int, FrameType | None], None] = interrupt
) -> dict[signal.Signals, Any]:
    """Make each of ``signals`` call ``handler`` (by default raise KeyboardInterrupt, Ctrl-C's way
    out); returns the handlers they had. SIGINT is taken also where it was inherited ignored (a
    shell starts background jobs so, and Python then leaves it ignored); SIGHUP is not: ignored,
    it is `nohup`'s, a user's word that the command outlives its terminal."""
    hangup = getattr(signal, "SIGHUP", None)
    return {
        sig: signal.signal(sig, handler)
        for sig in signals
        if not (sig == hangup and signal.getsignal(sig) == signal.SIG_IGN)
    }


def stopping(stop: threading.Event, hurry: threading.Event) -> Callable[[int, FrameType | None], None]:
    """A signal handler for a live session: the first signal sets ``stop`` — the session ends at
    its next frame, having read what arrived before (a KeyboardInterrupt raised mid-read lost the
    frame being read and every frame waiting) — and the second ``hurry``: the frames still
    waiting are left unread, and said. Neither raises: a KeyboardInterrupt between a frame's
    recording and its count, or inside the recording's write, lost frames that the summary
    counted. A third raises KeyboardInterrupt, for a session that does not end."""
    presses = 0

    def handler(signum: int, frame: FrameType | None) -> None:
        nonlocal presses
        presses += 1
        if presses > 2:
            raise KeyboardInterrupt
        (hurry if stop.is_set() else stop).set()

    return handler


@contextmanager
def interrupted_by(*signals: signal.Signals) -> Iterator[None]:
    """While the body runs, each of ``signals`` raises KeyboardInterrupt (``take_over``): what the
    body holds is unwound (a temporary folder, a background process)."""
    previous = take_over(signals)
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
