"""c2n campaign MANIFEST.csv: every drive of a test programme analysed as c2n analyze does, on
local worker processes or a Dask cluster, resumably; then C2n per tyre set (or any tag) with
intervals that count the spread between sessions, the differences between groups, and trends
against numeric tags."""

import argparse
import logging
import os
import time
from concurrent.futures import Executor
from contextlib import AbstractContextManager
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn

from app.cli.common import ENDING, error_console, interrupted_by, number, path_argument
from app.config import load_config
from app.errors import UsageError, need, printable
from app.output.csv_dialects import CSV_DIALECT_HELP, CSV_DIALECTS, dialect_of
from app.output.files import files_together
from app.output.paths import Output, check
from app.user_text import shown

if TYPE_CHECKING:
    from app.campaign.comparison import Comparison
    from app.campaign.manifest import Manifest
    from app.campaign.row import SessionRow


def add_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "campaign", help="analyse and compare many drives (tyre sets, pressures, days)", description=__doc__
    )
    parser.add_argument(
        "manifest",
        type=path_argument,
        metavar="MANIFEST.csv",
        help="a 'log' column (relative to it) and tag columns",
    )
    parser.add_argument(
        "--out",
        type=path_argument,
        metavar="DIR",
        help="results go here (default: MANIFEST-campaign beside it)",
    )
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=number(1, 1024, integer=True),
        metavar="N",
        help=f"local worker processes (default: the CPU count, {os.cpu_count()})",
    )
    where.add_argument(
        "--scheduler",
        type=_scheduler,
        metavar="ADDRESS",
        help="a Dask distributed scheduler, e.g. tcp://10.0.0.5:8786; 'local': a LocalCluster of one "
        "worker process per CPU, started for the run",
    )
    parser.add_argument(
        "--by", metavar="COLUMN", help="the tag to group by (e.g. tyre_set); default: one group"
    )
    parser.add_argument(
        "--config",
        type=path_argument,
        metavar="F",
        help="vehicle config for every log (default: a session's own copy, else config/mondeo.toml)",
    )
    parser.add_argument(
        "--csv-dialect",
        choices=tuple(CSV_DIALECTS),
        help=f"results.csv's: {CSV_DIALECT_HELP} (default: the manifest's own — excel-semicolon where its "
        "fields are separated by ';', else excel)",
    )
    parser.set_defaults(run=run)
    return parser


_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")  # the transports a Dask scheduler listens on


def _scheduler(text: str) -> str:
    """An argparse ``type``: 'local' or SCHEME://HOST:PORT with a transport Dask has (a bare
    HOST:PORT is tcp://, as for distributed.Client); anything else is a usage error."""
    if text == "local":
        return text
    scheme, sep, rest = text.rpartition("://")
    scheme = scheme if sep else "tcp"
    host, colon, port = rest.rpartition(":")
    if scheme not in _SCHEMES or not colon or not host or not port.isdigit():
        raise argparse.ArgumentTypeError(
            f"{printable(text)!r} is no scheduler address: want 'local' or "
            f"{'|'.join(_SCHEMES)}://HOST:PORT, e.g. tcp://10.0.0.5:8786"
        )
    return f"{scheme}://{rest}"


def print_comparison(console: Console, comparison: "Comparison", by: str | None) -> None:
    """The groups (a group none of whose sessions gave a C2n too, with why), their differences
    and the sessions compared on their group's model, one line each; every tag and log name
    printed as the user wrote it (``shown``)."""
    from app.campaign.comparison import sessions

    for name in sorted({*comparison.groups, *comparison.no_c2n}):
        group = f"{shown(by)} {shown(name)}" if by else "all sessions"
        if name not in comparison.groups:
            console.print(f"  {group}: {shown(comparison.no_c2n[name].said)}")
            continue
        pooled = comparison.groups[name]
        low, high = pooled.ci95
        tyres = comparison.softening.get(name)
        soften = f", tyres {tyres.shown}" if tyres else ""
        console.print(
            f"  {group}: C2n = {pooled.c2n:.3f} 1/rad [{low:.3f}, {high:.3f}] "
            f"(95 %, {sessions(pooled.n_sessions)}, τ {pooled.tau:.3f}{soften})"
        )
    for d in comparison.differences:
        console.print(
            f"  {shown(d.a)} − {shown(d.b)}: {d.c2n:+.3f} [{d.ci95[0]:+.3f}, {d.ci95[1]:+.3f}] 1/rad"
        )
    for log, c in comparison.switched.items():
        console.print(
            f"  {shown(log)}: compared on its {c.model} fit, {c.c2n:.3f} 1/rad "
            f"[{c.ci95[0]:.3f}, {c.ci95[1]:.3f}] — "
            f"its own fit chose the {c.own_model} one (t = {c.softening_t:+.1f}), its group's sessions "
            f"together the {c.model} one"
        )


def quiet_dask(debug: bool) -> None:
    """Dask's own bookkeeping kept out of the terminal: importing distributed sets its loggers
    to INFO, and ours prints what reaches it, ~40 lines a run of a LocalCluster ('Start Nanny
    at', 'Register worker', 'Scheduler closing all comms' …). Its warnings and errors stay;
    ``--debug`` keeps it all."""
    if not debug:
        logging.getLogger("distributed").setLevel(logging.WARNING)


def _analysed(
    args: argparse.Namespace, manifest: "Manifest", config: Path | None, out: Path, console: Console
) -> tuple[list["SessionRow"], int, float]:
    """Every entry's row (``work.run_campaign``) with a progress bar; the frames analysed (not
    known from an earlier run) and the seconds it took."""
    from app.campaign import work

    started = time.perf_counter()
    frames = 0
    with Progress(
        TextColumn("campaign"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("sessions  {task.fields[rate]}"),
        TimeRemainingColumn(),
        console=console,
        transient=True,
    ) as progress:
        task = progress.add_task("", total=len(manifest.entries), rate="")

        def arrived(index: int, row: "SessionRow") -> None:
            nonlocal frames
            if not row.cached:
                frames += row.frames
            elapsed = max(time.perf_counter() - started, 1e-9)
            progress.update(task, advance=1, rate=f"{frames / elapsed:,.0f} frames/s")

        def workers() -> AbstractContextManager[Executor]:
            if args.scheduler is not None:
                return work.dask_workers(args.scheduler)
            return work.local_workers(args.workers or os.cpu_count() or 1)

        with interrupted_by(*ENDING):  # each stops it, keeping what is done
            rows = work.run_campaign(manifest, config, out, workers, arrived)
    return rows, frames, time.perf_counter() - started


def run(args: argparse.Namespace, console: Console) -> int:
    from app.campaign import ownership, tables, work
    from app.campaign.comparison import compare, sessions, with_compared, write_comparison
    from app.campaign.manifest import read_manifest
    from app.campaign.repeats import counted_once
    from app.campaign.report import write_report

    need("pyarrow", "c2n campaign (results.parquet)", "export")
    need("matplotlib", "c2n campaign (report.html's plots)", "export")
    if args.scheduler is not None:
        need("distributed", "c2n campaign --scheduler", "dask")
        quiet_dask(args.debug)

    manifest = read_manifest(args.manifest)
    if args.config is not None:  # a missing or broken config fails once, before any work
        load_config(args.config)
    if args.by is not None and args.by not in manifest.tag_names:
        tags = ", ".join(manifest.tag_names) or "none"
        raise UsageError(f"--by {args.by}: not a column of {args.manifest} (tags: {tags})")
    clashing = tables.clashing_tags(manifest)
    if clashing:
        raise UsageError(
            f"{args.manifest}: the tag column '{clashing[0]}' has the name of a column c2n writes in "
            f"results.csv — rename it (e.g. 'tag_{clashing[0]}')"
        )
    named_all = next((e.line for e in manifest.entries if args.by and e.tags[args.by] == "all"), None)
    if named_all is not None:  # the trends key the fit over every group "all"
        raise UsageError(
            f"{args.manifest}, line {named_all}: the --by {args.by} group 'all' has the name of the trend "
            f"over all sessions in comparison.json and the report — rename it (e.g. '{args.by} all')"
        )
    errors = error_console()
    empty = [manifest.empty_cells_warning(tag) for tag in manifest.empty_cells() if tag != args.by]
    for warning in [*manifest.warnings, *filter(None, empty)]:  # said before the work, not after hours of it
        errors.print(f"c2n: warning: {printable(warning)}", markup=False)
    out = args.out or args.manifest.with_name(f"{args.manifest.stem}-campaign")
    inputs = [args.manifest, *(entry.log for entry in manifest.entries)]
    inputs += [args.config] if args.config else []
    check([Output("--out", out, ownership.ours, folder=True)], inputs)
    config = args.config.resolve() if args.config else None
    with work.claimed(out):  # alone on --out until its results are in place
        ownership.check_results_of(out, manifest)  # before the work, not after hours of it
        rows, frames, elapsed = _analysed(args, manifest, config, out, console)
        rows, repeats = counted_once(manifest, rows)
        columns, table = tables.table_rows(manifest, rows)
        comparison = compare(manifest, rows, args.by)
        with files_together(out, ownership.FILES) as staging:  # an interrupt: the old set or the new
            dialect = args.csv_dialect or dialect_of(manifest.delimiter)
            compared = with_compared(columns, table, comparison)
            tables.write_tables(staging, *compared, dialect, numeric=manifest.numeric_tags())
            write_comparison(staging, comparison)
            write_report(staging, comparison, f"c2n campaign — {args.manifest.name}")
            ownership.record_written(out, staging, args.manifest)
    cached = sum(1 for row in rows if row.cached)
    console.print(
        f"{sessions(len(rows))} in {elapsed:.1f} s ({cached} known from an earlier run, "
        f"{frames:,} frames analysed); results in {shown(out)}"
    )
    print_comparison(console, comparison, args.by)
    for entry, row in zip(manifest.entries, rows, strict=True):
        for warning in row.warnings_about(entry.log):
            errors.print(f"c2n: warning: {printable(warning)}", markup=False)
    for log, error in comparison.failed:
        errors.print(f"c2n: warning: {printable(error if log in error else f'{log}: {error}')}", markup=False)
    failed = len(comparison.failed) - len(repeats)  # a repeat is said above, not a failure
    if failed:
        errors.print(f"c2n: {failed} of {sessions(len(rows))} failed (see report.html)", markup=False)
    return 0
