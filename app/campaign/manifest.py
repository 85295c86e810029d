"""A campaign's manifest: one row per test drive, a ``log`` column and any tags.

    log,tyre_set,pressure_kPa,day
    day1/run1.blf,A,220,1
    sessions/2026-11-24_101500,B,240,1

``log`` is a log file or a session folder of ``c2n live``, relative to the manifest. Tags are
kept as text; a tag whose every value is a number, bar empty cells, is numeric (``numeric_tags``),
for trends, which leave its empty cells' rows out (``empty_cells`` says where). A
manifest not separated by commas may write its numbers with a decimal comma (Excel's ``;`` CSV
where that is the decimal mark): such a column's values are kept with a decimal point.
"""

import csv
import io
import math
from dataclasses import dataclass, replace
from pathlib import Path

from app.errors import C2nError
from app.sources.sessions import RAW_FORMATS

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
    warnings: tuple[str, ...] = ()  # a column not read as its values suggest, one line each
    delimiter: str = ","  # what separates its fields: Excel's ';' where the decimal mark is a comma
    text_tags: frozenset[str] = frozenset()  # numbers whose reading the manifest leaves open

    def numeric_tags(self) -> list[str]:
        """The tags whose every value is a finite number (pressure, load, temperature …), bar
        empty cells (a value not noted): a trend against such a tag leaves their rows out."""
        return [
            name
            for name in self.tag_names
            if name not in self.text_tags
            and any(e.tags[name] for e in self.entries)
            and all(_number(e.tags[name]) for e in self.entries if e.tags[name])
        ]

    def empty_cells(self) -> dict[str, list[int]]:
        """The numeric tags with empty cells, and the lines they are on."""
        lines = {name: [e.line for e in self.entries if not e.tags[name]] for name in self.numeric_tags()}
        return {name: on for name, on in lines.items() if on}

    def empty_cells_warning(self, tag: str) -> str | None:
        """One line on ``tag``'s empty cells, where it has any: how many, on which lines, and
        that the trends against it leave those rows out."""
        lines = self.empty_cells().get(tag)
        if not lines:
            return None
        n, shown = len(lines), ", ".join(str(line) for line in lines[:_LINES_NAMED])
        more = f" and {n - _LINES_NAMED} more" if n > _LINES_NAMED else ""
        cells, rows = ("1 empty cell", "that row") if n == 1 else (f"{n} empty cells", "those rows")
        return (
            f"{self.path}: column '{tag}' has {cells} of {len(self.entries)} "
            f"(line{'s' if n > 1 else ''} {shown}{more}) — the trends against it leave {rows} out"
        )


_LINES_NAMED = 5  # an empty cell's line named up to this many; the rest counted


def _number(text: str) -> bool:
    """A finite number as a spreadsheet writes one: Python's ``float`` also reads '1_000' and
    '2_3' (23), a code's spelling, not a value's."""
    if "_" in text:
        return False
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
        delimiter = _delimiter(text)
        rows = list(csv.reader(io.StringIO(text, newline=""), delimiter=delimiter))
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
            quote = any("\n" in cell for cell in row)  # a quote opened and not closed: the rest is one cell
            raise C2nError(
                f"{path}: line {line} has {len(row)} field{'s' if len(row) != 1 else ''}, the header "
                f"{len(header)}" + (" (a quote opened there is not closed)" if quote else "")
            )
        cells = [cell.strip() for cell in row]
        if not cells[where]:
            raise C2nError(f"{path}: line {line} names no log")
        log = _log(path, line, cells[where])
        if log in seen:
            raise C2nError(f"{path}: line {line} names {cells[where]} again (line {seen[log]}) — once each")
        seen[log] = line
        tags = {name: cell for name, cell in zip(header, cells, strict=True) if name != LOG}
        entries.append(Entry(line, log, tags))
    if not entries:
        raise C2nError(f"{path}: no logs listed under the header")
    tag_names = tuple(name for name in header if name != LOG)
    warnings: list[str] = []
    text_tags: set[str] = set()
    if delimiter != ",":  # a comma in a cell may then be a decimal mark, and a point group thousands
        for name in tag_names:
            pointed = _pointed(entries, name)
            if pointed is not None:
                text_tags.add(name)
                warnings.append(f"{path}: {pointed}")
                continue
            entries, unread = _decimal_commas(entries, name)
            warnings += [f"{path}: {said}" for said in unread]
    else:  # a number column with a word in it ('n/a', '2.1 bar') would lose its trend unsaid
        warnings += [f"{path}: {said}" for name in tag_names if (said := _not_numbers(entries, name))]
    return Manifest(path, tag_names, tuple(entries), tuple(warnings), delimiter, frozenset(text_tags))


def _not_numbers(entries: list[Entry], name: str) -> str | None:
    """Where most of a column's values are numbers but not all: a line naming the first that is
    not, and that the column is kept as text, with no trend against it; else None."""
    values = [(entry.line, entry.tags[name]) for entry in entries if entry.tags[name]]
    words = [(line, value) for line, value in values if not _number(value)]
    if not words or 2 * len(words) >= len(values):
        return None
    line, value = words[0]
    return (
        f"line {line}, column '{name}': '{value}' is not a number, where {len(values) - len(words)} of the "
        f"column's {len(values)} values are — the column is kept as text, with no trend against it; "
        "write a number (no unit), or leave the cell empty"
    )


def _pointed(entries: list[Entry], name: str) -> str | None:
    """Where the manifest's fields are separated by ';' — the decimal mark a comma, a point
    grouping thousands — a column of numbers written with points or no mark, one with a point
    ('1.200': 1200 there, 1.2 elsewhere), cannot be read for sure: a line saying so (the column
    is then text), else None."""
    values = [(entry.line, entry.tags[name]) for entry in entries if entry.tags[name]]
    if not all(_number(value) for _, value in values):  # decimal commas among them: said apart
        return None
    line, value = next(((line, value) for line, value in values if "." in value), (0, ""))
    if not value:
        return None
    return (
        f"line {line}, column '{name}': '{value}' has a point, in a manifest separated by ';' (where "
        f"the decimal mark is a comma, a point groups thousands: '1.200' is 1200, not 1.2) — the "
        f"column is kept as text, with no trend against it; write its numbers with a decimal comma "
        f"('2,5') and no thousands mark, or save the manifest with ','"
    )


def _log(path: Path, line: int, named: str) -> Path:
    """The log a line names, resolved; a C2nError where it, or a session folder's frames file, is
    no file (a device, a pipe): opening a pipe to hash it would wait for a writer never to come."""
    if "\0" in named:  # no file system holds one: the path functions raise ValueError
        raise C2nError(f"{path}: line {line} names a log whose name holds a NUL byte — check the name")
    try:
        return _checked_log(path, line, named)
    except OSError as error:  # a name the system cannot look up (over 255 bytes): the user's to fix
        shown = named if len(named) <= 60 else f"{named[:40]}…"
        raise C2nError(
            f"{path}: line {line} names {shown}, which cannot be looked up ({error.strerror or error}) "
            "— check the name"
        ) from error


def _checked_log(path: Path, line: int, named: str) -> Path:
    log = (path.parent / named).resolve()
    if log.exists() and not (log.is_file() or log.is_dir()):
        raise C2nError(
            f"{path}: line {line} names {named}, which is no file (a device or a pipe) — "
            "name a log file or a session folder"
        )
    frames = (log / f"frames{suffix}" for suffix in RAW_FORMATS) if log.is_dir() else ()
    no_file = next((f for f in frames if f.exists() and not f.is_file()), None)
    if no_file is not None:
        raise C2nError(
            f"{path}: line {line} names {named}, whose {no_file.name} is no file (a device or a pipe) — "
            "name a session folder whose frames are a file"
        )
    return log


def _decimal_comma(text: str) -> str | None:
    """``text`` with its decimal comma made a point, where it is a finite number written so or
    without any mark ('2,5', '-0,5', '1,5E+03', '20'); None where a point or a second comma
    makes it something else ('1.234,5', '2,0,1') or it is no number."""
    if "." in text or text.count(",") > 1:
        return None
    pointed = text.replace(",", ".")
    return pointed if _number(pointed) else None


def _decimal_commas(entries: list[Entry], name: str) -> tuple[list[Entry], list[str]]:
    """The entries with the tag ``name`` written with decimal points, where each of its non-empty
    values is a number and one at least has a decimal comma; else as they were, and a line naming
    the value that could not be read where the others are such numbers."""
    values = [(entry.line, entry.tags[name]) for entry in entries if entry.tags[name]]
    read = {line: _decimal_comma(value) for line, value in values}
    example = next((value for line, value in values if "," in value and read[line] is not None), None)
    if example is None:  # no decimal comma: nothing to translate
        return entries, []
    unread = next(((line, value) for line, value in values if read[line] is None), None)
    if unread is not None:
        line, value = unread
        return entries, [
            f"line {line}, column '{name}': '{value}' is no number with a decimal comma, as the "
            f"column's other values are — the column is kept as text, with no trend against it; "
            f"write it like '{example}'"
        ]
    return [replace(e, tags=e.tags | {name: read.get(e.line) or ""}) for e in entries], []
