"""``c2n analyze LOG...``: the live pipeline over log files, as fast as it can."""

import argparse
import itertools
import os
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

from rich.console import Console

from app.cli.common import (
    INTERRUPTED,
    add_config,
    add_force,
    error_console,
    no_role_decoded,
    parts_disagree,
    path_argument,
)
from app.cli.terminal import say
from app.config import load_config
from app.errors import NoResultError, printable
from app.output.paths import SUMMARY_JSON, Output, check, config_files, result_of
from app.results.headline import Method
from app.user_text import argument, shown

if TYPE_CHECKING:
    from app.config import Config
    from app.sources.logs import LogReport

_POOL_GAP_S = 10.0  # between drives pooled: no filter, gate or regression run spans it


def add_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    parser = subparsers.add_parser("analyze", help="C2n from recorded CAN logs", description=__doc__)
    parser.add_argument(
        "logs", nargs="+", type=path_argument, metavar="LOG", help="ASC, BLF, candump .log, CSV, TRC or MF4"
    )
    add_config(parser)
    parser.add_argument(
        "--json", type=path_argument, metavar="OUT", help="write the summary JSON here (- : standard output)"
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


# What to do where logs given together disagree, each alone, by how they were given
_FIX = {
    "pool": "pool one set of tyres",
    "merge": "merge the channels of one drive, pool drives that agree",
    "one": "analyse each alone, or --pool drives of one set of tyres",
    "gap": "diagnose each drive alone (the logs of one gap are one drive's channels, merged)",
    "within": "split the log at its pauses (c2n split {log}) and analyse each part alone, or --pool the "
    "parts of one set of tyres",
}


def each_alone(
    logs: list[Path], config: "Config", how: Literal["pool", "merge", "one", "gap"], console: Console
) -> None:
    """Each log analysed alone first: drives pooled, or given as one, must agree
    (``app.results.agreement``), files merged must be channels of one drive, not whole drives
    of their own, and no two may hold one stretch of driving (``app.sources.overlap``: it would
    count twice)."""
    from app.pipeline import Pipeline
    from app.results.agreement import DriveResult, disagreement
    from app.results.log_clock import sensor_messages
    from app.run_loop import run as run_pipeline
    from app.sources.logs import LogSource
    from app.sources.overlap import SensorPrints, overlapping

    alone = []
    recordings: list[tuple[str, SensorPrints]] = []
    quasi_only = True
    sensor = frozenset(sensor_messages(config))
    with console.status("each log alone first…"):
        for log in logs:
            pipeline = Pipeline(config)
            source = LogSource([log], triage=pipeline.decoder, spaced=sensor, prints=True)
            run_pipeline(source.items(blocks=True), pipeline, [], blocks=True)
            recordings += [(r.path.name, r.prints) for r in source.reports if r.prints is not None]
            headline = pipeline.snapshot().headline
            if headline is not None:
                alone.append(DriveResult(str(log), headline.c2n, headline.ci95))
                quasi_only = quasi_only and headline.method is Method.QUASI_STEADY
    twice = overlapping(recordings)
    if twice is not None:
        first, second, share = twice
        raise NoResultError(
            f"{printable(first)} and {printable(second)} hold the same driving (the optical sensor's "
            f"frames alike, run for run, over {100 * share:.0f} % of the shorter): one drive recorded "
            "twice — a second logger on the bus, a copy cut or thinned, or two simulations of one --seed "
            "— which would count twice; analyse one of them"
        )
    if how in ("merge", "gap") and len(alone) < 2:
        return
    if quasi_only and how == "pool":  # the pooled run fits each drive's quasi-steady samples alone
        return  # too and says, with each one's result in the summary, why there is no C2n
    why = disagreement(alone)
    if why is not None:
        raise NoResultError(f"{why} — {_FIX[how]}")
    if how == "merge":
        error_console().print(
            f"c2n: warning: {printable(', '.join(d.name for d in alone))}: each is a whole drive with "
            "its own C2n — --merge is for the channels of one drive; --pool takes drives",
            markup=False,
        )


def _one_drive(reports: "list[LogReport]", config: "Config", console: Console) -> "list[LogReport]":
    """Files given as one drive are read one after the other: a recording split in files (a
    session's parts, a logger's size limit) goes on where the last stopped. Where one does not —
    it begins before the last ended, or after a pause the filter does not bridge — they are
    separate recordings: each is analysed alone, and drives that disagree (two tyre sets, a day
    apart) have no one C2n (they read 15.40 [15.17, 15.64] for 14.89 and 15.91, each outside).
    Separate ones that agree are still run on as one (one ψ0 and yaw bias): said in a note."""
    from app.sources.logs import LogReport

    bridged = config.filter.gap_reset_s
    for report in reports:  # a file that paused: its parts alone (``app.results.within_file``)
        why = parts_disagree(report, config, console)
        if why is not None:
            from app.results.within_file import fix_for

            raise NoResultError(f"{why} — {fix_for(why, _FIX['within'], argument(report.path))}")
    for before, after in itertools.pairwise(r for r in reports if r.span_s is not None):
        assert before.span_s is not None and after.span_s is not None
        gap = after.span_s[0] - before.span_s[1]
        if 0.0 <= gap <= bridged:
            continue
        where = (
            f"begins {gap:.3g} s after {before.path.name} ends"
            if gap > 0
            else f"begins {-gap:.3g} s before {before.path.name} ends"
        )
        each_alone([r.path for r in reports], config, "one", console)
        note = (
            f"{where}: separate recordings, run on as one drive (one head offset ψ0 and yaw-rate bias "
            "for both) — --pool takes separate drives of one car, --merge the channels of one drive"
        )
        return [LogReport(after.path, stopped=note, done=True)]
    return []


def _side_by_side(reports: "list[LogReport]") -> "list[LogReport]":
    """Files merged are channels of one drive, recorded over the same time: one that does not
    overlap the first (a logger counting from 0, another on the calendar's clock) is said — the
    merge lays its frames beside no others."""
    from app.sources.logs import LogReport

    spans = [(r, r.span_s) for r in reports if r.span_s is not None]
    if len(spans) < 2:
        return []
    first, (first_start, first_end) = spans[0]
    notes = []
    for report, (start, end) in spans[1:]:
        if start > first_end or end < first_start:
            gap = start - first_end if start > first_end else first_start - end
            when = "after" if start > first_end else "before"
            notes.append(
                LogReport(
                    report.path,
                    stopped=(
                        f"its frames lie {gap:.3g} s {when} those of {first.path.name}, not beside them — "
                        "--merge takes channels of one drive recorded on one clock: is a logger's clock "
                        "off, or are these separate drives (--pool)?"
                    ),
                    done=True,
                )
            )
    return notes


def run(args: argparse.Namespace, console: Console) -> int:
    # loaded when the command runs, not at import: `c2n --help` needs none of them
    from app.pipeline import Pipeline
    from app.results.log_clock import clock_notes, sensor_messages
    from app.run_loop import run as run_pipeline
    from app.sinks import summary
    from app.sinks.event_printer import EventPrinter, print_result
    from app.sinks.progress import ReadProgress
    from app.sources.logs import LogReport, LogSource, check_readable, distinct, starting_at
    from app.sources.sessions import parts_left_out

    config = load_config(args.config)
    whose = result_of(args.logs, "summary")  # a session's own, an export's
    out = Output("--json", args.json, SUMMARY_JSON, stdout=True, whose=whose) if args.json else None
    check([out], [*args.logs, *config_files(config)], args.force)
    pipeline = Pipeline(config)
    drives: list[list[Path]] = [args.logs]
    notes: list[LogReport] = []
    read: list[LogReport] = []  # each file's report, for the spacing of its sensor's frames
    spaced = frozenset(sensor_messages(config))
    if args.pool:  # one drive at a time, each recording once
        for log in args.logs:  # fail before any work on a file that cannot be read
            check_readable(log)
        kept, notes = distinct(args.logs)
        drives = [[log] for log in kept]
    if (args.pool or args.merge) and len(drives[0] if args.merge else drives) > 1:
        if args.merge:
            each_alone(drives[0], config, "merge", console)
        else:
            each_alone([d[0] for d in drives], config, "pool", console)
    for number, logs in enumerate(drives):
        source = LogSource(
            logs, merge=args.merge, triage=pipeline.decoder, spaced=spaced, pause_s=config.filter.gap_reset_s
        )
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
        read += source.reports
        if not completed:  # Ctrl-C: the result of what was read
            break
        if args.merge:
            notes += _side_by_side(source.reports)
        elif not args.pool:
            notes += _one_drive(source.reports, config, console)
    snapshot = pipeline.snapshot()
    clock = clock_notes(read, config)
    parts = [LogReport(path, stopped=why, done=True) for path, why in parts_left_out(args.logs)]
    # the inputs named absolute, as an export's: a later run from elsewhere knows them (helper-34)
    inputs = [os.path.abspath(p) for p in args.logs]
    result = summary.build(snapshot, config, inputs, [*clock, *parts, *notes])
    missing = summary.missing_required(snapshot, config)
    refused = no_role_decoded(snapshot, config, args.logs) or (
        f"{', '.join(str(p) for p in args.logs)}: {missing}" if missing else None
    )
    if clock:  # the run's every figure is on the wrong time: its result and warnings would mislead
        refused = f"{clock[0].path}: {clock[0].stopped}"
    if refused is not None:  # the file's reason is the refusal's (it said "drive steady circles …", or none)
        result = replace(result, no_result=refused)
    if args.json and completed:  # an interrupted run's result is of part of the drive: the file stays
        summary.write(args.json, result)
    if clock:
        raise NoResultError(refused)
    if refused is None:  # else the result line would blame the drive ("no cornering") for the log
        print_result(console, snapshot)
    errors = error_console()
    for warning in result.warnings:
        errors.print(f"c2n: warning: {printable(warning)}", markup=False)
    if not completed:  # Ctrl-C, SIGTERM, a closed terminal: said, not taken for the whole drive's
        unwritten = f"; {shown(args.json)} not written" if args.json and str(args.json) != "-" else ""
        read_from = ", ".join(map(shown, args.logs))
        say(
            f"c2n: interrupted — the result above is of the first {snapshot.elapsed_s:,.0f} s read "
            f"({snapshot.frames.total:,} frames), not the whole of {read_from}{unwritten}"
        )
        return INTERRUPTED
    if refused is not None:
        raise NoResultError(refused)
    return 0
