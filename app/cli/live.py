"""``c2n live``: the in-car run — dashboard, a line per crossing, every frame recorded."""

import argparse
import contextlib
import datetime
import shutil
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console
from rich.text import Text

from app.cli.common import (
    ENDING,
    add_bus,
    add_config,
    add_force,
    bus_kwargs,
    channels,
    error_console,
    number,
    path_argument,
    stopping,
    take_over,
)
from app.config import load_config
from app.errors import C2nError, OutputError, printable
from app.output.files import new_folder
from app.output.paths import SUMMARY_JSON, Output, check, config_files, result_of
from app.sources.sessions import RAW_FORMATS
from app.user_text import shown

if TYPE_CHECKING:
    import can

    from app.config import Config
    from app.sinks.recorder import SessionRecorder
    from app.sources.buses import Backoff


_NEVER_THIS_DRIVE = result_of([], "summary", now="this bus")  # a live run's drive is its own


def add_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    parser = subparsers.add_parser("live", help="live dashboard and C2n on a CAN bus", description=__doc__)
    add_bus(parser)
    add_config(parser)
    add_force(parser)
    parser.add_argument(
        "--record",
        type=path_argument,
        default=Path("c2n-sessions"),
        metavar="DIR",
        help="session folders go here (default: c2n-sessions)",
    )
    parser.add_argument("--no-record", action="store_true", help="do not record the session")
    parser.add_argument(
        "--raw-format",
        choices=RAW_FORMATS,
        default=".log",
        help="raw frame log format (default .log, candump)",
    )
    parser.add_argument(
        "--json",
        type=path_argument,
        metavar="OUT",
        help="also write the summary JSON here (- : standard output)",
    )
    parser.add_argument(
        "--duration", type=number(0.0, 1e7, low_allowed=False), metavar="S", help="stop after S seconds"
    )
    parser.add_argument(
        "--rate",
        type=number(0.01, 1000.0, low_allowed=False),
        default=1.0,
        metavar="X",
        help="the bus carries a replay X times faster than the drive (c2n replay --rate X): frame "
        "times are stretched X times, so sweeps are measured as driven and recorded so (default: 1)",
    )
    parser.set_defaults(run=run)
    return parser


@contextlib.contextmanager
def _hidden(module: str) -> Iterator[None]:
    """``module`` unimportable inside the block (as if not installed), importable after it."""
    if module in sys.modules:
        yield
        return
    sys.modules[module] = None  # type: ignore[assignment]  # the import system's "not there"
    try:
        yield
    finally:
        del sys.modules[module]


def import_python_can() -> None:
    """python-can imports asammdf (and pandas with it: 0.4 s, half the start) for its MF4 writer
    and reader, which a live session never uses (it records .log, .asc or .blf): imported without
    it, python-can's MF4 classes say asammdf is missing if asked, and asammdf is still there for
    whatever imports it later."""
    with _hidden("asammdf"):
        import can  # noqa: F401


_MOST_IN_ONE_SECOND = 10_000  # sessions begun in one second: more is a folder c2n cannot write


def session_folder(parent: Path, now: Callable[[], datetime.datetime] = datetime.datetime.now) -> Path:
    """A new, empty folder for the session, named after the second it begins (``-2``, ``-3`` …
    after it when that one is taken), claimed by creating it: two sessions begun in the same
    second get a folder each, and a folder or file already there is never entered."""
    stamp = now().strftime("%Y-%m-%d_%H%M%S")
    try:
        parent.mkdir(parents=True, exist_ok=True)
        names = (stamp if n == 1 else f"{stamp}-{n}" for n in range(1, _MOST_IN_ONE_SECOND + 1))
        folder = new_folder(parent / name for name in names)
        if folder is not None:
            return folder
    except OSError as error:
        raise OutputError(
            f"{parent}: cannot record the session ({error.strerror}) — use --record DIR"
        ) from error
    raise OutputError(f"{parent}: {_MOST_IN_ONE_SECOND} sessions began at {stamp} — use --record DIR")


def _recorder(parent: Path, config: "Config", raw_format: str) -> "SessionRecorder":
    from app.sinks.recorder import SessionRecorder

    folder = session_folder(parent)
    try:
        return SessionRecorder(folder, config, raw_format, claimed=True)
    except C2nError:
        shutil.rmtree(folder, ignore_errors=True)  # claimed by this run: all in it is c2n's
        raise


def _console_lost(console: Console) -> list[str]:
    """A warning for the summary where the console went away during the session (a closed
    terminal, a dropped ssh session): the words were lost, the recording went on."""
    why = getattr(console.file, "why", "")
    return [f"the console went away during the session ({why}): recorded to the end unseen"] if why else []


OpenBuses = Callable[..., list["can.BusABC"]]


def run(
    args: argparse.Namespace,
    console: Console,
    open_bus: OpenBuses | None = None,
    backoff: "Backoff | None" = None,
    clock: Callable[[], float] = time.monotonic,
) -> int:
    """The session. A bus that goes away is reopened with ``open_bus`` (default
    ``app.sources.buses.open_buses``) after ``backoff`` delays (default 0.5 s doubling to 5 s, on
    ``clock``) while the recording and the pipeline carry on."""
    # loaded when the command runs, not at import: `c2n --help` needs none of them
    import_python_can()  # first: the config's DBCs (cantools) import it too
    from app.pipeline import PartedPipeline
    from app.run_loop import run as run_pipeline
    from app.sinks import summary
    from app.sinks.dashboard import Dashboard
    from app.sinks.event_printer import EventPrinter, print_result
    from app.sinks.sink import Sink
    from app.sources.buses import Backoff, BusSource, open_buses
    from app.sources.playback import drive_time

    opener: OpenBuses = open_bus or open_buses
    config = load_config(args.config)
    check(
        [
            # never the drive of a summary there: an export's or a session's own is not replaced
            Output("--json", args.json, SUMMARY_JSON, stdout=True, whose=_NEVER_THIS_DRIVE)
            if args.json
            else None,
            # a session gets a new folder of its own in --record: any folder there will do
            None if args.no_record else Output("--record", args.record, lambda path: False, parent=True),
        ],
        config_files(config),
        args.force,
    )
    wanted: Sequence[str | int | None] = channels(args)
    options: dict[str, Any] = bus_kwargs(args)
    buses = opener(args.interface, wanted, args.bitrate, **options)
    title = ", ".join(str(bus.channel_info) for bus in buses)
    pipeline = PartedPipeline(config)  # a tyre change while the sensor was off: no one C2n
    recorder = None if args.no_record else _recorder(args.record, config, args.raw_format)
    stop, hurry = threading.Event(), threading.Event()
    timer = threading.Timer(args.duration, stop.set) if args.duration else None
    # Ctrl-C, SIGTERM and a closed terminal (SIGHUP, unless run under nohup) end the session cleanly,
    # once what arrived before is read; a second one without what still waits. Held until the
    # summary is written: a signal then, at the default, ended the process before it was
    previous = take_over(ENDING, stopping(stop, hurry))
    console.print(f"c2n live on {shown(title)} — Ctrl-C ends the session", style="dim")
    if args.rate != 1.0:
        console.print(
            f"frame times stretched ×{args.rate:g}: the bus carries a replay at that rate", style="dim"
        )

    def reopen(index: int) -> "can.BusABC":
        return opener(args.interface, [wanted[index]], args.bitrate, **options)[0]

    def bus_changed(text: str) -> None:
        console.print(Text(f"c2n: {printable(text)}", style="bold yellow"), soft_wrap=True)

    source = BusSource(
        buses,
        stop,
        reopen=reopen,
        backoff=backoff or Backoff(),
        clock=clock,
        on_change=bus_changed,
        hurry=hurry,
    )
    dashboard = Dashboard(title, bus_problem=lambda: source.problem)
    sinks: list[Sink] = [EventPrinter(console)]
    if recorder is not None:
        recorder.on_problem = lambda text: console.print(
            Text(f"c2n: {printable(text)}", style="bold red"), soft_wrap=True
        )
        recorder.on_note = bus_changed
        sinks.append(recorder)
    try:
        try:
            if timer is not None:
                timer.start()
            frames = source if args.rate == 1.0 else drive_time(source, args.rate)
            run_pipeline(frames, pipeline, sinks, display=dashboard, console=console)
        finally:  # the recording is finished (the run loop closed it); the summary goes beside it
            if timer is not None:
                timer.cancel()
            for bus in source.buses:  # the ones open now (a lost bus was closed already)
                bus.shutdown()
            snapshot = pipeline.snapshot()
            stopped = [recorder.problem] if recorder is not None and recorder.problem else []
            parts = recorder.notes if recorder is not None else []
            unseen = _console_lost(console)
            result = summary.build(snapshot, config, [title]).warned(
                [*stopped, *parts, *source.losses, *unseen]
            )
            unwritten = []  # a full disk: the numbers are still shown
            for write, where in (
                (recorder.write_summary if recorder is not None else None, "the session's summary"),
                ((lambda r: summary.write(args.json, r)) if args.json else None, "--json"),
            ):
                if write is not None:
                    try:
                        write(result)
                    except OutputError as error:
                        unwritten.append(f"{where} was not written: {error}")
    finally:  # only now: a signal at the default while the summary was written ended the process
        for sig, handler in previous.items():
            signal.signal(sig, handler)
    print_result(console, snapshot)
    errors = error_console()
    for warning in [*result.warnings, *unwritten]:
        errors.print(f"c2n: warning: {printable(warning)}", markup=False)
    kept = [folder for folder in recorder.folders if folder.is_dir()] if recorder is not None else []
    if kept:
        console.print(f"session saved in {', '.join(shown(folder) for folder in kept)}", style="dim")
    return 1 if stopped or unwritten else 0
