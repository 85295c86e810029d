"""One drive of a campaign, analysed as ``c2n analyze`` would, into one small row.

``analyse`` runs wherever the work is sent (a local worker process or a Dask worker): it reads
the log there and returns only the row — tags and hashes are added by the caller — so nothing
large crosses a process boundary or the network. A log that cannot be analysed is a row with its
error, never an exception: one damaged file must not end a campaign of hundreds.
"""

import hashlib
import logging
import os
import resource
import stat
import time
from collections.abc import Callable
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

from app import __version__
from app.campaign.meta_analysis import Estimate, Fits
from app.campaign.row import SessionResult, SessionRow, finite_numbers
from app.config import DEFAULT_CONFIG, Config, load_config
from app.errors import C2nError, printable
from app.results.headline import Method
from app.sources.sessions import parts_left_out, read_session, unfinished
from app.user_text import argument

if TYPE_CHECKING:  # the analysis's own modules load where a drive is analysed
    from app.results.regression import RegressionFit
    from app.sinks.summary import RegressionRow, Summary
    from app.snapshot import Snapshot

log = logging.getLogger(__name__)

_CHUNK = 1 << 20
# Where the parts of one log between its optical sensor's pauses disagree, each alone
WITHIN_FIX = (
    "split the log at its pauses (c2n split {log}) and list each part in the manifest as a drive of its own"
)


@dataclass(frozen=True)
class Job:
    """What a worker needs: where the log is and which config to read it with."""

    log: Path  # a log file or a session folder
    config: Path | None  # --config; None: a session folder's own copy, else the default


def where(job: Job) -> tuple[list[Path], Path, Path | None]:
    """The log files (a session's: its own, then its parts'), the config file and the folder its
    DBCs are taken from (a session's copy)."""
    if job.log.is_dir():
        raws, copy = read_session(job.log)
        if job.config is not None:
            return raws, job.config, None
        return raws, copy, copy.parent
    return [job.log], job.config or DEFAULT_CONFIG, None


def logs_hash(given: Path, raws: list[Path], hash_one: Callable[[Path], str]) -> str:
    """A drive's logs' hash: its one log's, or a session's parts' in order, each hashed alone (a
    part's hash is remembered as a log's is), then together. A session folder without its summary
    (still being recorded, or killed) is keyed apart from the same frames with it: its row says
    the frames may not be the whole drive, and once the summary is written that is not true."""
    hashes = [hash_one(raw) for raw in raws]
    if unfinished(given) is not None:
        hashes.append("unfinished")
    if len(hashes) == 1:
        return hashes[0]
    # one hash of the 32-digit width, whatever the parts: a key is a file's name (at most 255 bytes)
    return hashlib.blake2b("+".join(hashes).encode(), digest_size=16).hexdigest()


def content_hash(paths: list[Path]) -> str:
    """BLAKE2b over the files' bytes, in order (a log, or a config and its DBCs). Only regular
    files, and only the bytes they held when opened: a device (``/dev/zero``) or a pipe would
    never end, a log still being written would never be the same twice. Opened without waiting
    (O_NONBLOCK): opening a pipe to read waits for a writer, which would never come."""
    digest = hashlib.blake2b(digest_size=16)
    for path in paths:
        with os.fdopen(os.open(path, os.O_RDONLY | os.O_NONBLOCK), "rb") as file:
            status = os.fstat(file.fileno())
            if not stat.S_ISREG(status.st_mode):
                raise C2nError(f"{path}: not a regular file (a device or a pipe) — name a log file")
            left = status.st_size
            while left > 0 and (chunk := file.read(min(_CHUNK, left))):
                digest.update(chunk)
                left -= len(chunk)
        digest.update(b"\0")
    return digest.hexdigest()


def config_hash(config_path: Path, dbc_dir: Path | None, file_hash: Callable[[Path], str]) -> str:
    """The hash of a config and the DBCs it loads (each file's ``file_hash``, hashed together),
    and of c2n's version: another version may analyse the same drive differently."""
    config = load_config(config_path, dbc_dir=dbc_dir)
    parts = [__version__, *(file_hash(path) for path in (config_path, *(dbc.path for dbc in config.dbcs)))]
    return hashlib.blake2b("/".join(parts).encode(), digest_size=16).hexdigest()


def analyse(job: Job) -> SessionRow:
    """The row of one drive: its result or its error (never an exception), the ``frames`` read,
    the ``seconds`` it took and the worker's peak memory."""
    started = time.perf_counter()
    try:
        raws, config_path, dbc_dir = where(job)
        config = load_config(config_path, dbc_dir=dbc_dir)
        row = _analysed(raws, config, job.log)
    except C2nError as error:
        row = SessionRow(error=printable(str(error)))
    except Exception as error:  # a worker's boundary: the row carries it, the campaign goes on
        log.exception("%s: analysis failed", job.log)
        row = SessionRow(error=printable(f"{job.log}: the analysis failed ({type(error).__name__}: {error})"))
    # the worker's peak memory so far: flat over a campaign when nothing accumulates
    peak = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)
    return replace(row, seconds=round(time.perf_counter() - started, 3), worker_peak_mib=peak)


def _analysed(raws: list[Path], config: Config, given: Path) -> SessionRow:
    from app.pipeline import Pipeline  # the filter's compiled code: only where a drive is analysed
    from app.results.log_clock import clock_notes, sensor_messages
    from app.results.within_file import fix_for, parts_disagree
    from app.run_loop import run as run_pipeline
    from app.sinks import summary
    from app.sources.logs import LogReport, LogSource, drive_identity
    from app.sources.overlap import sample

    pipeline = Pipeline(config)
    raw = raws[0]  # the drive's name in its errors: the log, or a session's first part
    source = LogSource(
        raws,
        triage=pipeline.decoder,
        spaced=frozenset(sensor_messages(config)),
        pause_s=config.filter.gap_reset_s,
        prints=True,
    )
    run_pipeline(source.items(blocks=True), pipeline, [], blocks=True)
    snapshot = pipeline.snapshot()
    identity = drive_identity(raw).text  # a copy of this drive elsewhere counts once
    runs = sample(r.prints for r in source.reports if r.prints is not None)  # a near-copy too
    clock = clock_notes(source.reports, config)
    if clock:  # every figure on the wrong time, and the refusal would blame the drive: as analyze says
        said = printable(f"{clock[0].path}: {clock[0].stopped}")
        return SessionRow(error=said, drive=identity, runs=runs, frames=snapshot.frames.total)
    for report in source.reports:  # a file that paused: its parts alone, as c2n analyze reads them
        why = parts_disagree(report, config, Pipeline)
        if why is not None:  # no summary, as analyze writes none: its C2n lies between the parts'
            fix = fix_for(why, WITHIN_FIX, argument(report.path))
            said = printable(f"{raw}: no C2n — {why} — {fix}")
            return SessionRow(error=said, drive=identity, runs=runs, frames=snapshot.frames.total)
    notes = [
        LogReport(part, stopped=said, done=True) for part, said in parts_left_out([given])
    ] + source.notes
    cut_short = unfinished(given)  # a session killed, or still recording: the frames so far
    if cut_short is not None:
        said = f"{cut_short} — this row covers the frames on disk so far"
        notes = [LogReport(given, stopped=said, done=True), *notes]
    written = summary.build(snapshot, config, [str(r) for r in raws], notes)
    missing = summary.missing_required(snapshot, config)
    error = printable(f"{raw}: {missing}") if missing else None
    if not missing and written.c2n is None:
        error = printable(f"{raw}: no C2n — {snapshot.refusal}")
    return SessionRow(
        summary=written.to_json(),
        result=None if error else session_result(snapshot, written),
        error=error,
        drive=identity,
        runs=runs,
        frames=snapshot.frames.total,
    )


def session_result(snapshot: "Snapshot", written: "Summary") -> SessionResult | None:
    """What the comparison takes of a drive: its headline as the summary writes it (C2n and its
    interval rounded as there, so the results' columns and the comparison read the same numbers),
    with the data's own interval beside it, and the headline's fit's evidence on the tyres."""
    headline = snapshot.headline
    if headline is None or written.c2n is None or written.c2n_ci95 is None:
        return None
    low, high = written.c2n_ci95
    if low is None or high is None or not finite_numbers(written.c2n, low, high):  # open at one end: no C2n
        return None
    scale = (written.c2n_scale_se_pct or 0.0) / 100.0
    own = Estimate.of(written.c2n, (low, high), _rounded(headline.data_only_ci95))
    fit, row = {
        Method.REGRESSION: (snapshot.regression, written.regression),
        Method.QUASI_STEADY: (snapshot.quasi, written.quasi_steady),
    }.get(headline.method, (None, None))
    if fit is None or row is None or not row.softening_resolved or not finite_numbers(row.softening_t):
        return SessionResult(own, scale, None, None)
    return SessionResult(own, scale, row.softening_t, _fits(fit, row))


def _fits(fit: "RegressionFit", row: "RegressionRow") -> Fits | None:
    """The fit's two models, where it chose between them by a test (the cascade) and could take
    either. A marginal fit has one C2n, the softening's prior in its interval: there is nothing
    to choose, and it is pooled as it is."""
    if fit.estimator == "marginal" or row.softening_t is None:
        return None
    linear = _model(row.c2n_linear_model, row.c2n_linear_ci95, fit.models.linear.data_ci95)
    if linear is None:
        return None
    cubic = fit.models.softening
    softening = _model(row.c2n_softening_model, row.c2n_softening_ci95, cubic.data_ci95 if cubic else None)
    return Fits(row.softening_t, linear, softening, "softening" if row.model == "softening" else "linear")


def _model(
    c2n: float | None, ci95: tuple[float | None, float | None] | None, data_ci95: tuple[float, float] | None
) -> Estimate | None:
    low, high = ci95 or (None, None)
    if c2n is None or low is None or high is None or not finite_numbers(c2n, low, high):
        return None
    return Estimate.of(c2n, (low, high), _rounded(data_ci95) if data_ci95 else (low, high))


def _rounded(ci95: tuple[float, float]) -> tuple[float, float]:
    """An interval rounded as the summary rounds its own (where the sensors' scales are not
    counted, the two are then the same numbers)."""
    return (round(ci95[0], 4), round(ci95[1], 4))
