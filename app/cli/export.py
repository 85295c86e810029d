"""``c2n export LOG_OR_SESSION``: decoded and filtered channels (CSV, Parquet, MF4), the events
table, the summary, plots and one self-contained HTML report."""

import argparse
import os
import stat
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console

from app.cli.common import INTERRUPTED, error_console, no_role_decoded, parts_disagree, path_argument
from app.cli.terminal import say
from app.config import DEFAULT_CONFIG, Config, load_config
from app.errors import NoResultError, OutputError, need, printable
from app.output.csv_dialects import CSV_DIALECT_HELP, CSV_DIALECTS
from app.output.files import folder_atomically
from app.output.paths import (
    HTML_REPORT,
    SUMMARY_JSON,
    Output,
    check,
    config_files,
    recorded_inputs,
    same_inputs,
)
from app.user_text import argument, shown

if TYPE_CHECKING:
    from app.sinks.summary import Summary
    from app.snapshot import Snapshot
    from app.sources.logs import LogReport

FORMATS = ("csv", "parquet", "mf4")  # app.sinks.channels.FORMATS; pyarrow and asammdf load only when used


def add_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "export", help="channels, events, plots and a report from a log or session", description=__doc__
    )
    parser.add_argument(
        "input",
        type=path_argument,
        metavar="LOG_OR_SESSION",
        help="a CAN log, or a session folder of c2n live",
    )
    parser.add_argument(
        "--config",
        type=path_argument,
        metavar="F",
        help="vehicle config (default: a session's own copy, else config/mondeo.toml)",
    )
    parser.add_argument(
        "--format",
        action="append",
        choices=FORMATS,
        help="channel file format; repeat for several (default: all of csv, parquet, mf4)",
    )
    parser.add_argument(
        "--csv-dialect",
        choices=tuple(CSV_DIALECTS),
        default="excel",
        help=CSV_DIALECT_HELP,
    )
    parser.add_argument(
        "--out",
        type=path_argument,
        metavar="DIR",
        help="output folder (default: SESSION/export or LOG-export)",
    )
    parser.add_argument("--no-plots", action="store_true", help="no PNG plots and no HTML report")
    parser.set_defaults(run=run)
    return parser


def _inputs(args: argparse.Namespace) -> tuple[list[Path], Config, Path]:
    """The logs (a session's: its own, then its parts'), the config and the output folder."""
    from app.sources.logs import status
    from app.sources.sessions import read_session

    path: Path = args.input
    if stat.S_ISDIR(status(path).st_mode):  # a name the system cannot look up is one line
        logs, copy = read_session(path)
        config = load_config(args.config) if args.config else load_config(copy, dbc_dir=copy.parent)
        return logs, config, args.out or path / "export"
    config = load_config(args.config or DEFAULT_CONFIG)
    return [path], config, args.out or path.with_name(f"{path.stem}-export")


def _notes_before_reading(path: Path) -> "list[LogReport]":
    """A note for a session folder without the summary c2n live writes when it ends
    (``sessions.unfinished``): the export is of the frames on disk so far — said in the warnings
    (and the exported summary), not taken for the whole drive; and one for a part of a session
    recorded in parts given alone (``sessions.parts_left_out``)."""
    from app.sources.logs import LogReport
    from app.sources.sessions import parts_left_out, unfinished

    parts = [LogReport(part, stopped=said, done=True) for part, said in parts_left_out([path])]
    why = unfinished(path)
    if why is None:
        return parts
    return [
        LogReport(path, stopped=f"{why} — this export covers the frames on disk so far", done=True),
        *parts,
    ]


def _nothing_to_export(snapshot: "Snapshot", config: Config, logs: list[Path], out: Path) -> str | None:
    """Why there is nothing to export: not one frame carried a role of the config (its DBCs or
    ids are not this log's: ``no_role_decoded``). Nothing is written then — an empty export would
    take the place of an older one at ``out``. A log with some roles (a vehicle bus, no optical
    sensor) is exported: analyze needs the sensor, export converts what there is."""
    nothing = no_role_decoded(snapshot, config, logs)
    return None if nothing is None else f"{nothing} (nothing written to {out})"


# Where the parts of one log between its optical sensor's pauses disagree, each alone
_WITHIN_FIX = "split the log at its pauses (c2n split {log}) and export each part alone"


def _say_result(console: Console, snapshot: "Snapshot", result: "Summary", line: bool = True) -> None:
    """The result line (unless not ``line``), and the summary's warnings on standard error."""
    from app.sinks.event_printer import print_result

    if line:
        print_result(console, snapshot)
    errors = error_console()
    for warning in result.warnings:
        errors.print(f"c2n: warning: {printable(warning)}", markup=False)


# the rows of data a spreadsheet's sheet holds below the header (Excel's and LibreOffice's 2²⁰)
SPREADSHEET_ROWS = 2**20 - 1

# The plots' names (app.sinks.plots.PLOTS; named here so that --no-plots does not import matplotlib)
PLOT_NAMES = ("sideslip_vs_speed.png", "vr_vs_u2.png", "c2n_per_crossing.png", "timeseries.png")


def _ours(name: str) -> bool:
    """A file c2n export writes (an older export in the folder may be replaced whole)."""
    return name.startswith("channels.") or name in ("events.csv", "summary.json", "report.html", *PLOT_NAMES)


# how each kind of file c2n export writes begins: its own header, or the format's magic bytes
_STARTS = {
    "channels.csv": (b'\xef\xbb\xbf"time [s]"',),
    "channels.parquet": (b"PAR1",),
    "channels.mf4": (b"MDF     ",),
    "events.csv": (b"t,event,", b"t;event;"),
    **{name: (b"\x89PNG\r\n\x1a\n",) for name in PLOT_NAMES},
}


def _ours_by_content(path: Path) -> bool:
    """An entry of an older export: named as c2n export names its files and beginning as it
    writes them — a user's own ``events.csv`` in the folder is not c2n's to replace."""
    if not _ours(path.name) or not path.is_file():
        return False
    if path.name == "summary.json":
        return SUMMARY_JSON(path)
    if path.name == "report.html":
        return HTML_REPORT(path)
    starts = _STARTS.get(path.name)
    if starts is None:
        return False
    try:
        with path.open("rb") as file:
            head = file.read(32)
    except OSError:
        return False
    return head.startswith(starts)


def _not_an_older_export(out: Path, logs: list[Path], default: bool) -> str | None:
    """Why the output folder (``--out``, or the default beside the log), which holds only files
    named and begun as an export's, is no older export of ``logs`` to replace: it lacks the
    summary and events every export writes (a `gap` report, an `analyze` summary, alone), or its
    summary names other logs (another drive's export; day.blf's beside day.log). Those were
    replaced, and lost, when names and contents were enough."""
    if not out.is_dir() or not any(out.iterdir()):
        return None
    lacking = [name for name in ("summary.json", "events.csv") if not (out / name).is_file()]
    if lacking:
        held = ", ".join(sorted(entry.name for entry in out.iterdir())[:3])
        return f"{out}: holds c2n's files but no export ({held}) — choose a new or empty folder (--out)"
    made_from = recorded_inputs(out / "summary.json") or []
    if not same_inputs(made_from, logs, out, by_name=default):
        return (
            f"{out}: holds the export of {', '.join(made_from) or 'another log'}, not of "
            f"{', '.join(os.path.abspath(log) for log in logs)} — choose another folder (--out), or remove "
            "that one to export there"
        )
    return None


def run(args: argparse.Namespace, console: Console) -> int:
    # loaded when the command runs, not at import: `c2n --help` needs none of them
    from app.pipeline import Pipeline
    from app.results.log_clock import clock_notes, sensor_messages
    from app.run_loop import run as run_pipeline
    from app.sinks import channels as export
    from app.sinks import events_csv as events
    from app.sinks import summary
    from app.sinks.event_printer import EventPrinter
    from app.sinks.progress import ReadProgress
    from app.sinks.trace import TraceRecorder
    from app.sources.logs import LogSource

    formats = tuple(dict.fromkeys(args.format or FORMATS))  # `--format csv --format csv`: one file
    export.need_writers(formats)  # before the drive is read: a missing extra is said at once
    if not args.no_plots:
        need("matplotlib", "drawing the plots", export.EXTRA, " (or --no-plots)")
    logs, config, out = _inputs(args)
    check([Output("--out", out, _ours_by_content, folder=True)], [*logs, *config_files(config)])
    # the default place too: day.blf's and day.log's are one folder
    refused = _not_an_older_export(out, logs, default=args.out is None)
    if refused is not None:
        raise OutputError(refused)
    noted = _notes_before_reading(args.input)  # before reading: the frames on disk when it began
    pipeline = Pipeline(config)
    source = LogSource(
        logs,
        triage=pipeline.decoder,
        spaced=frozenset(sensor_messages(config)),
        pause_s=config.filter.gap_reset_s,
    )
    trace_recorder = TraceRecorder(config.roles)
    progress = ReadProgress(source, logs[0].name)
    completed = run_pipeline(
        source,
        pipeline,
        [EventPrinter(console), trace_recorder],
        display=progress,
        console=console,
        transient=True,
    )
    if not completed:  # Ctrl-C, SIGTERM, a closed terminal: a part of the drive is no export of it
        say(f"c2n: interrupted — {shown(args.input)} not read to its end: nothing written to {shown(out)}")
        return INTERRUPTED
    clock = clock_notes(source.reports, config)
    if clock:  # every channel is on the wrong time: nothing is written
        raise NoResultError(f"{clock[0].path}: {clock[0].stopped} (nothing written to {out})")
    for read in source.reports:  # a file that paused: its parts alone, as c2n analyze reads them
        why = parts_disagree(read, config, console)
        if why is not None:  # the summary, events and plots would show one C2n between them
            from app.results.within_file import fix_for

            fix = fix_for(why, _WITHIN_FIX, argument(read.path))
            raise NoResultError(f"{why} — {fix} (nothing written to {out})")
    snapshot = pipeline.snapshot()
    t0 = snapshot.t0
    trace = trace_recorder.trace(t0)
    inputs = [os.path.realpath(p) for p in logs]  # which logs (a link's file): an export found again
    result = summary.build(snapshot, config, inputs, [*noted, *source.reports])
    nothing = _nothing_to_export(snapshot, config, logs, out)
    if nothing is not None:  # the warnings name each role's ids; a result line would blame the drive
        _say_result(console, snapshot, result, line=False)
        raise NoResultError(nothing)
    written: list[Path] = []
    writing = folder_atomically(out, _ours_by_content, "c2n export")
    with console.status("writing the exports…"), writing as staging:
        for fmt in formats:
            path = staging / f"channels.{fmt}"
            export.write(trace, fmt, path, args.csv_dialect)
            written.append(path)
        events.write(
            staging / "events.csv", [*snapshot.crossings, *snapshot.rejections], t0, args.csv_dialect
        )
        summary.write(staging / "summary.json", result)
        written += [staging / "events.csv", staging / "summary.json"]
        if not args.no_plots:
            from app.sinks.plots import write_plots
            from app.sinks.report import write_report

            plots = write_plots(trace, result, staging)
            report = staging / "report.html"
            write_report(result, plots, report, title=f"c2n — {logs[0].name}")
            written += [*plots, report]
    _say_result(console, snapshot, result)
    errors = error_console()
    if "csv" in formats and len(trace) > SPREADSHEET_ROWS:
        errors.print(
            f"c2n: warning: channels.csv holds {len(trace):,} rows: a spreadsheet opens the first "
            f"{SPREADSHEET_ROWS:,} (Excel's and LibreOffice's sheet) — read it with pandas or "
            "polars, or use channels.parquet or channels.mf4",
            markup=False,
        )
    console.print(f"{len(trace):,} rows × {len(trace.channels)} channels → {shown(out)}", style="dim")
    for path in written:
        console.print(f"  {shown(path.name)}", style="dim")
    return 0
