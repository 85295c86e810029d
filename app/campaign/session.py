"""One drive of a campaign, analysed as ``c2n analyze`` would, into one small row.

``analyse`` runs wherever the work is sent (a local worker process or a Dask worker): it reads
the log there and returns only the row — tags and hashes are added by the caller — so nothing
large crosses a process boundary or the network. A log that cannot be analysed is a row with its
error, never an exception: one damaged file must not end a campaign of hundreds.
"""

import hashlib
import json
import logging
import os
import resource
import stat
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app import __version__
from app.config import DEFAULT_CONFIG, Config, load_config
from app.errors import C2nError, printable
from app.sinks.recorder import read_session

log = logging.getLogger(__name__)

_CHUNK = 1 << 20


@dataclass(frozen=True)
class Job:
    """What a worker needs: where the log is and which config to read it with."""

    log: Path  # a log file or a session folder
    config: Path | None  # --config; None: a session folder's own copy, else the default


def where(job: Job) -> tuple[Path, Path, Path | None]:
    """The log file, the config file and the folder its DBCs are taken from (a session's copy)."""
    if job.log.is_dir():
        raw, copy = read_session(job.log)
        if job.config is not None:
            return raw, job.config, None
        return raw, copy, copy.parent
    return job.log, job.config or DEFAULT_CONFIG, None


def content_hash(paths: list[Path]) -> str:
    """BLAKE2b over the files' bytes, in order (a log, or a config and its DBCs). Only regular
    files, and only the bytes they held when opened: a device (``/dev/zero``) or a pipe would
    never end, a log still being written would never be the same twice."""
    digest = hashlib.blake2b(digest_size=16)
    for path in paths:
        with path.open("rb") as file:
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


def analyse(job: Job) -> dict[str, Any]:
    """The row of one drive: every key of the analyze summary, flattened, with ``error`` (None
    when there is a result), ``frames``, the ``seconds`` it took and ``worker_peak_mib``."""
    started = time.perf_counter()
    frames = 0
    try:
        raw, config_path, dbc_dir = where(job)
        config = load_config(config_path, dbc_dir=dbc_dir)
        row, frames = _analysed(raw, config)
    except C2nError as error:
        row = {"error": printable(str(error))}
    except Exception as error:  # a worker's boundary: the row carries it, the campaign goes on
        log.exception("%s: analysis failed", job.log)
        row = {"error": printable(f"{job.log}: the analysis failed ({type(error).__name__}: {error})")}
    row["frames"] = frames
    row["seconds"] = round(time.perf_counter() - started, 3)
    # the worker's peak memory so far: flat over a campaign when nothing accumulates
    row["worker_peak_mib"] = round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1)
    return row


def _analysed(raw: Path, config: Config) -> tuple[dict[str, Any], int]:
    from app.pipeline import Pipeline  # the filter's compiled code: only where a drive is analysed
    from app.run_loop import run as run_pipeline
    from app.sinks import summary
    from app.sources.logs import LogSource, drive_identity

    pipeline = Pipeline(config)
    source = LogSource([raw], triage=pipeline.decoder)
    run_pipeline(source.items(blocks=True), pipeline, [], blocks=True)
    snapshot = pipeline.snapshot()
    result = summary.build(snapshot, config, [str(raw)], source.notes)
    missing = summary.missing_required(snapshot, config)
    row = flatten(result.to_json())
    row["drive"] = drive_identity(raw).text  # a copy of this drive elsewhere counts once
    row["error"] = printable(f"{raw}: {missing}") if missing else None
    if not missing and result.c2n is None:
        why = snapshot.refusal
        row["error"] = printable(f"{raw}: no C2n — {why}")
    return row, snapshot.frames.total


def flatten(value: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested keys joined with dots; an interval [low, high] as ``.low``/``.high``; other lists
    (crossings, warnings …) as JSON text, so every value fits a CSV cell or a Parquet column."""
    out: dict[str, Any] = {}
    for key, item in value.items():
        name = f"{prefix}{key}"
        if isinstance(item, dict):
            out.update(flatten(item, f"{name}."))
        elif isinstance(item, list) and len(item) == 2 and all(_scalar_number(x) for x in item):
            out[f"{name}.low"], out[f"{name}.high"] = item
        elif isinstance(item, list):
            out[name] = json.dumps(item, ensure_ascii=False)
        else:
            out[name] = item
    return out


def _scalar_number(value: object) -> bool:
    return value is None or (isinstance(value, int | float) and not isinstance(value, bool))


def file_warnings(log: Path, row: dict[str, Any]) -> list[str]:
    """The warnings of a session's row about its file itself (damage that ended the reading, a
    recording given twice): what the terminal says beside results.csv's column."""
    try:
        said = json.loads(row.get("warnings") or "[]")
    except (TypeError, json.JSONDecodeError):
        return []
    return [w for w in said if isinstance(w, str) and (str(log) in w or f"{log.name}:" in w)]
