"""``c2n analyze LOG...``: the live pipeline over log files, as fast as it can."""

import argparse
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from rich.console import Console

from app.cli.common import add_config, add_force, error_console
from app.config import load_config
from app.errors import NoResultError, printable
from app.output.paths import SUMMARY_JSON, Output, check, config_files
from app.results.headline import Method

if TYPE_CHECKING:
    from app.config import Config

_POOL_GAP_S = 10.0  # between drives pooled: no filter, gate or regression run spans it


def add_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    parser = subparsers.add_parser("analyze", help="C2n from recorded CAN logs", description=__doc__)
    parser.add_argument(
        "logs", nargs="+", type=Path, metavar="LOG", help="ASC, BLF, candump .log, CSV, TRC or MF4"
    )
    add_config(parser)
    parser.add_argument(
        "--json", type=Path, metavar="OUT", help="write the summary JSON here (- : standard output)"
    )
    add_force(parser)
    how = parser.add_mutually_exclusive_group()
    how.add_argument(
        "--merge", action="store_true", help="the logs are channels of one drive: merge them by timestamp"
    )
    how.add_argument(
        "--pool",
        action="store_true",
        help="the logs are separate drives of one car: one C2n from all, each drive its own sensor "
        "offset ψ0 (the head mounted again) and yaw-rate bias — e.g. track laps and circles on "
        "different days",
    )
    parser.set_defaults(run=run)
    return parser


def _each_alone(logs: list[Path], config: "Config", merge: bool, console: Console) -> None:
    """Each log analysed alone first: drives pooled must agree (``app.results.agreement``), and
    files merged must be channels of one drive, not whole drives of their own."""
    from app.pipeline import Pipeline
    from app.results.agreement import DriveResult, disagreement
    from app.run_loop import run as run_pipeline
    from app.sources.logs import LogSource

    alone = []
    quasi_only = True
    with console.status("each log alone first…"):
        for log in logs:
            pipeline = Pipeline(config)
            run_pipeline(
                LogSource([log], triage=pipeline.decoder).items(blocks=True), pipeline, [], blocks=True
            )
            headline = pipeline.snapshot().headline
            if headline is not None:
                alone.append(DriveResult(str(log), headline.c2n, headline.ci95))
                quasi_only = quasi_only and headline.method is Method.QUASI_STEADY
    if merge and len(alone) < 2:
        return
    if quasi_only and not merge:  # the pooled run fits each drive's quasi-steady samples alone too
        return  # and says, with each one's result in the summary, why there is no C2n
    why = disagreement(alone)
    if why is not None:
        fix = "merge the channels of one drive, pool drives that agree" if merge else "pool one set of tyres"
        raise NoResultError(f"{why} — {fix}")
    if merge:
        error_console().print(
            f"c2n: warning: {printable(', '.join(d.name for d in alone))}: each is a whole drive with "
            "its own C2n — --merge is for the channels of one drive; --pool takes drives",
            markup=False,
        )


def run(args: argparse.Namespace, console: Console) -> int:
    # loaded when the command runs, not at import: `c2n --help` needs none of them
    from app.pipeline import Pipeline
    from app.run_loop import run as run_pipeline
    from app.sinks import summary
    from app.sinks.event_printer import EventPrinter, print_result
    from app.sinks.progress import ReadProgress
    from app.sources.logs import LogReport, LogSource, check_readable, distinct, starting_at

    config = load_config(args.config)
    out = Output("--json", args.json, SUMMARY_JSON, stdout=True) if args.json else None
    check([out], [*args.logs, *config_files(config)], args.force)
    pipeline = Pipeline(config)
    drives: list[list[Path]] = [args.logs]
    notes: list[LogReport] = []
    if args.pool:  # one drive at a time, each recording once
        for log in args.logs:  # fail before any work on a file that cannot be read
            check_readable(log)
        kept, notes = distinct(args.logs)
        drives = [[log] for log in kept]
    if (args.pool or args.merge) and len(drives[0] if args.merge else drives) > 1:
        _each_alone(drives[0] if args.merge else [d[0] for d in drives], config, args.merge, console)
    for number, logs in enumerate(drives):
        source = LogSource(logs, merge=args.merge, triage=pipeline.decoder)
        progress = ReadProgress(source, ", ".join(p.name for p in logs))
        frames: Iterator[Any] = source.items(blocks=True)  # a BLF or MF4 in FrameBlocks: process_block
        end = pipeline.state.t_last
        if number and end is not None:  # the drives laid end to end, _POOL_GAP_S apart
            pipeline.new_log()
            frames = starting_at(frames, end + _POOL_GAP_S)
        completed = run_pipeline(
            frames,
            pipeline,
            [EventPrinter(console)],
            display=progress,
            console=console,
            transient=True,
            blocks=True,
        )
        notes += source.notes
        if not completed:  # Ctrl-C: the result of what was read
            break
    snapshot = pipeline.snapshot()
    result = summary.build(snapshot, config, [str(p) for p in args.logs], notes)
    if args.json:
        summary.write(args.json, result)
    print_result(console, snapshot)
    errors = error_console()
    for warning in result.warnings:
        errors.print(f"c2n: warning: {printable(warning)}", markup=False)
    missing = summary.missing_required(snapshot, config)
    if missing:
        raise NoResultError(f"{', '.join(str(p) for p in args.logs)}: {missing}")
    return 0
