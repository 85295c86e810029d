"""A campaign's ``results.csv`` and ``results.parquet``: a row per drive — the log as the
manifest names it, its tags, every key of the analyze summary flattened, the bookkeeping last."""

import csv
import io
import os
import re
from collections.abc import Collection, Sequence
from pathlib import Path
from typing import Any

from app.campaign.manifest import Entry, Manifest
from app.campaign.row import OWN_COLUMNS, SessionRow
from app.output.csv_dialects import CSV_DIALECTS
from app.output.files import as_text, write_atomically

FIRST_COLUMNS = ("log", "error", "c2n", "c2n_ci95.low", "c2n_ci95.high", "c2n_method", "u0_mps")
# what the comparison took of each session (``Compared``), after the first columns
COMPARED_COLUMNS = ("compared.c2n", "compared.c2n_ci95.low", "compared.c2n_ci95.high", "compared.model")
LAST_COLUMNS = ("frames", "seconds", "worker_peak_mib", "cached", "key")


def clashing_tags(manifest: Manifest) -> list[str]:
    """The manifest's tags named like a column c2n writes into results (``c2n``, ``error``,
    ``frames``, ``regression.…``): the file could not hold both, so the manifest is refused."""
    from dataclasses import fields as summary_fields

    from app.sinks.summary import Summary

    ours = (*FIRST_COLUMNS, *COMPARED_COLUMNS, *LAST_COLUMNS, *OWN_COLUMNS)
    written = {*ours, *(f.name for f in summary_fields(Summary))}
    return [tag for tag in manifest.tag_names if tag in written or tag.split(".", 1)[0] in written]


def log_name(manifest: Manifest, entry: Entry) -> str:
    """The log as the manifest names it (relative to the manifest's folder)."""
    return Path(os.path.relpath(entry.log, manifest.path.parent.resolve())).as_posix()


def table_rows(manifest: Manifest, rows: Sequence[SessionRow]) -> tuple[list[str], list[dict[str, Any]]]:
    """The columns and the rows of ``results``: the log as the manifest names it, its tags, then
    every key of the analysis, the bookkeeping last."""
    out = [
        {"log": log_name(manifest, entry), **entry.tags, **row.columns()}
        for entry, row in zip(manifest.entries, rows, strict=True)
    ]
    names: dict[str, None] = dict.fromkeys([*FIRST_COLUMNS[:1], *manifest.tag_names, *FIRST_COLUMNS[1:]])
    for columns in out:
        names.update(dict.fromkeys(k for k in columns if k not in LAST_COLUMNS))
    names.update(dict.fromkeys(LAST_COLUMNS))
    return list(names), out


def write_tables(
    folder: Path,
    columns: list[str],
    rows: list[dict[str, Any]],
    dialect: str = "excel",
    numeric: Collection[str] = (),
) -> None:
    """results.csv in ``dialect`` (``CSV_DIALECTS``: its numbers, and the ``numeric`` tags' values,
    with that decimal mark; its text as it is) and results.parquet."""
    delimiter, decimal = CSV_DIALECTS[dialect]
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, delimiter=delimiter, lineterminator="\r\n")
    writer.writeheader()
    for row in rows:
        cells = {k: _cell(row.get(k), decimal) for k in columns}
        writer.writerow(cells | {k: cells[k].replace(".", decimal) for k in numeric if k in cells})
    # a byte-order mark: a spreadsheet then reads the units (m/s², 1/rad) as UTF-8
    write_atomically(
        folder / "results.csv", lambda tmp: tmp.write_text(buffer.getvalue(), "utf-8-sig"), "results.csv"
    )
    import pyarrow as pa
    import pyarrow.parquet as pq

    read = {k: _numbers([row.get(k) for row in rows]) for k in numeric if k in columns}
    numbers = {k: column for k, column in read.items() if column is not None}
    table = pa.Table.from_pylist(
        [
            {k: numbers[k][i] if k in numbers else _text(row.get(k)) for k in columns}
            for i, row in enumerate(rows)
        ]
    )

    def parquet(tmp: Path) -> None:
        with tmp.open("wb") as file:  # a file, not its name: pyarrow cannot encode undecodable bytes
            pq.write_table(table, file)

    write_atomically(folder / "results.parquet", parquet, "results.parquet")


def _numbers(values: Sequence[Any]) -> list[int | float | None] | None:
    """A numeric tag's values as numbers for results.parquet (a reader's column of numbers, not of
    text): whole numbers, read exactly, where every value is one that fits 64 bits, else floats;
    an empty cell None. None (the column stays text) where a value begins with a zero that a
    number would drop (`007`: an id, not a count)."""
    texts = [v.strip() if isinstance(v, str) and v.strip() else None for v in values]
    if any(t is not None and _LEADING_ZERO.match(t) for t in texts):
        return None
    if all(t is None or _WHOLE.fullmatch(t) for t in texts):
        whole: list[int | float | None] = [None if t is None else int(t) for t in texts]
        if all(x is None or -(2**63) <= x < 2**63 for x in whole):  # int64
            return whole
    return [None if t is None else float(t) for t in texts]


_LEADING_ZERO = re.compile(r"[+-]?0[0-9]")
_WHOLE = re.compile(r"[+-]?[0-9]+")


def _text(value: Any) -> Any:
    return as_text(value) if isinstance(value, str) else value


def _cell(value: Any, decimal: str = ".") -> Any:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.10g}".replace(".", decimal)
    return _text(value)
