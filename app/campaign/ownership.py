"""Whose results a campaign's --out holds: the files c2n wrote there (``FILES``), known by the
digests it recorded (``cache/written.json``) and by the manifest they are of, so that a run never
replaces a user's file, an edited one, or another manifest's results."""

import csv
import hashlib
import io
import json
import os
from pathlib import Path
from typing import Any

from app.campaign.manifest import Manifest
from app.campaign.tables import log_name
from app.errors import OutputError
from app.output.files import write_json
from app.output.paths import HTML_REPORT, json_with

FILES = ("results.csv", "results.parquet", "comparison.json", "report.html")  # written together


def ours(entry: Path) -> bool:
    """What a campaign leaves in its folder: its results, each as the record in its cache says
    it wrote them (``record_written``), its cache folder, a killed run's temporary folder. A
    results.csv edited by hand since, or a user's own that begins as c2n's does, is not ours: a
    later run would have replaced it, unread."""
    from app.campaign.work import CACHE, is_cache

    if entry.name == CACHE:
        return entry.is_dir() and is_cache(entry)
    if entry.name.startswith(".partial-"):
        return entry.is_dir()
    if entry.name not in FILES or not entry.is_file():
        return False
    record = _written(entry.parent)
    if record is not None:
        return _digest(entry) in record.get(entry.name, ())
    cache = entry.parent / CACHE
    return cache.is_dir() and is_cache(cache) and _begins_as_ours(entry)  # an older c2n's campaign


def _begins_as_ours(entry: Path) -> bool:
    """A campaign's file by its content, for a campaign of a c2n that kept no record."""
    starts = {"results.csv": (b"\xef\xbb\xbflog,", b"\xef\xbb\xbflog;"), "results.parquet": (b"PAR1",)}
    if entry.name in starts:
        try:
            with entry.open("rb") as file:
                return file.read(len(starts[entry.name][0])) in starts[entry.name]
        except OSError:
            return False
    if entry.name == "comparison.json":
        return json_with("groups", "differences", "trends", "method")(entry)
    return entry.name == "report.html" and HTML_REPORT(entry)


def _digest(path: Path) -> str | None:
    try:
        with path.open("rb") as file:
            return hashlib.file_digest(file, "blake2b").hexdigest()
    except OSError:
        return None


_MANIFEST = "manifest"  # the record's key for the manifest the results are of


def results_of(folder: Path) -> Path | None:
    """The manifest whose results are in ``folder`` now (None: none are, or a c2n that kept
    no record of it wrote them)."""
    from app.campaign.work import CACHE, WRITTEN

    try:
        record = json.loads((folder / CACHE / WRITTEN).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    named = record.get(_MANIFEST) if isinstance(record, dict) else None
    if not isinstance(named, str) or not any(ours(folder / name) for name in FILES):
        return None
    return Path(named)


def check_results_of(folder: Path, manifest: Manifest) -> None:
    """Refused: ``folder`` holds another manifest's results, which this run would replace (the
    analyses in its cache are kept and shared either way, keyed by the logs' content). A
    manifest is known by where it is, as its logs are (a link to it is another manifest, whose
    logs lie beside the link); the results of a c2n that kept no record of their manifest, by
    the logs their results.csv lists."""
    fix = f"choose another --out, or remove {', '.join(FILES)} there to replace them (its cache is reused)"
    other = results_of(folder)
    if other is not None and other != _where(manifest.path):
        raise OutputError(
            f"{folder}: holds the results of the campaign {other}, not of {manifest.path} — {fix}"
        )
    listed = _listed_logs(folder) if other is None else None
    if listed is not None and listed != {log_name(manifest, entry) for entry in manifest.entries}:
        raise OutputError(
            f"{folder}: holds the results of a campaign of other logs than {manifest.path}'s (results.csv "
            f"lists {len(listed)}, not as the manifest does) — {fix}"
        )


def _where(manifest: Path) -> Path:
    """The manifest as its place, not its content's: absolute, its own name kept (a link)."""
    return Path(os.path.abspath(manifest))


def _listed_logs(folder: Path) -> set[str] | None:
    """The logs results.csv lists, where it is the campaign's own (``ours``); else None."""
    results = folder / "results.csv"
    if not ours(results):
        return None
    try:
        text = results.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError):
        return None
    rows = list(csv.reader(io.StringIO(text), delimiter=text[3:4] if text.startswith("log") else ","))
    return {row[0] for row in rows[1:] if row}


def _written(folder: Path) -> dict[str, list[str]] | None:
    """The campaign's record of the results it put in ``folder`` (None: it kept none)."""
    from app.campaign.work import CACHE, WRITTEN

    try:
        record = json.loads((folder / CACHE / WRITTEN).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict):
        return None
    return {
        name: [d for d in digests if isinstance(d, str)]
        for name, digests in record.items()
        if isinstance(digests, list)
    }


def record_written(folder: Path, staging: Path, manifest: Path) -> None:
    """Before the results in ``staging`` take their places in ``folder``: their digests in the
    cache's record, beside those of the ones in place now — a kill between the two leaves
    either set known as the campaign's — and the manifest they are the results of."""
    from app.campaign.work import CACHE, WRITTEN

    before = _written(folder) or {}
    record: dict[str, Any] = {name: [_digest(staging / name), *before.get(name, [])[:1]] for name in FILES}
    record[_MANIFEST] = str(_where(manifest))
    (folder / CACHE).mkdir(exist_ok=True)
    write_json(folder / CACHE / WRITTEN, record, "the campaign's record of its results")
