"""A campaign's manifest: one row per test drive, a ``log`` column and any tags.

    log,tyre_set,pressure_kPa,day
    day1/run1.blf,A,220,1
    sessions/2026-11-24_101500,B,240,1

``log`` is a log file or a session folder of ``c2n live``, relative to the manifest. Tags are
kept as text; a tag whose every value is a number is numeric (``numeric_tags``), for trends.
"""

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

from app.errors import C2nError

LOG = "log"


@dataclass(frozen=True)
class Entry:
    line: int  # in the manifest, for messages
    log: Path
    tags: dict[str, str]


@dataclass(frozen=True)
class Manifest:
    path: Path
    tag_names: tuple[str, ...]
    entries: tuple[Entry, ...]

    def numeric_tags(self) -> list[str]:
        """The tags whose every value is a finite number (pressure, load, temperature …)."""
        return [name for name in self.tag_names if all(_number(e.tags[name]) for e in self.entries)]


def _number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


_DELIMITERS = ",;\t"  # Excel writes ';' where the decimal mark is a comma


def _delimiter(text: str) -> str:
    """The manifest's separator: the one of ``,``, ``;``, tab that makes a '{LOG}' column of the
    header (a comma when none does, or a one-column manifest)."""
    header = text.partition("\n")[0]
    for delimiter in _DELIMITERS:
        if LOG in (name.strip() for name in next(csv.reader([header], delimiter=delimiter), [])):
            return delimiter
    return ","


def read_manifest(path: Path) -> Manifest:
    try:
        with path.open(newline="", encoding="utf-8-sig") as file:  # a BOM from Excel is no column
            text = file.read()
        rows = list(csv.reader(io.StringIO(text, newline=""), delimiter=_delimiter(text)))
    except FileNotFoundError:
        raise C2nError(f"{path}: no such manifest — give a CSV with a '{LOG}' column") from None
    except (UnicodeDecodeError, csv.Error) as error:
        raise C2nError(f"{path}: not a readable CSV ({error}) — save it as UTF-8 CSV") from None
    except OSError as error:
        raise C2nError(f"{path}: cannot be read ({error.strerror})") from None
    if not rows:
        raise C2nError(f"{path}: empty — the first line names the columns, one of them '{LOG}'")
    header = [name.strip() for name in rows[0]]
    if LOG not in header:
        raise C2nError(
            f"{path}: no '{LOG}' column (columns: {', '.join(header)}) — name the log column '{LOG}'"
        )
    if len(set(header)) != len(header) or "" in header:
        raise C2nError(f"{path}: column names must be distinct and not empty ({', '.join(header)})")
    where = header.index(LOG)
    entries: list[Entry] = []
    seen: dict[Path, int] = {}
    for line, row in enumerate(rows[1:], start=2):
        if not any(cell.strip() for cell in row):
            continue
        if len(row) != len(header):
            raise C2nError(f"{path}: line {line} has {len(row)} fields, the header {len(header)}")
        cells = [cell.strip() for cell in row]
        if not cells[where]:
            raise C2nError(f"{path}: line {line} names no log")
        log = (path.parent / cells[where]).resolve()
        if log.exists() and not (log.is_file() or log.is_dir()):
            raise C2nError(
                f"{path}: line {line} names {cells[where]}, which is no file (a device or a pipe) — "
                "name a log file or a session folder"
            )
        if log in seen:
            raise C2nError(f"{path}: line {line} names {cells[where]} again (line {seen[log]}) — once each")
        seen[log] = line
        tags = {name: cell for name, cell in zip(header, cells, strict=True) if name != LOG}
        entries.append(Entry(line, log, tags))
    if not entries:
        raise C2nError(f"{path}: no logs listed under the header")
    return Manifest(path, tuple(name for name in header if name != LOG), tuple(entries))
