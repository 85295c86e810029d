"""A session folder as c2n live leaves it, read: its raw log, its config copy, whether its run
ended, and the parts it went on in where its disk's largest file was reached (``<first>-part2``…,
named in the first folder's ``parts.json``). ``app.sinks.recorder`` writes these folders.
"""

import json
import os
import re
from collections.abc import Sequence
from pathlib import Path

from app.errors import C2nError
from app.output.paths import SESSION_CONFIG, SESSION_SUMMARY

RAW_FORMATS = (".log", ".asc", ".blf")
PARTS_FILE = "parts.json"  # in a session's first folder: the parts it went on in, in order


def _parts_named(folder: Path) -> list[str]:
    """The names of the parts ``folder``'s session went on in (none: it went on in none)."""
    try:
        listed = json.loads((folder / PARTS_FILE).read_text(encoding="utf-8")).get("parts")
    except FileNotFoundError:
        return []
    except (OSError, ValueError, AttributeError) as error:
        raise C2nError(
            f"{folder / PARTS_FILE}: cannot be read ({error}) — give the parts' logs to c2n analyze"
        ) from error
    if not isinstance(listed, list) or not all(_folder_name(n) for n in listed):
        raise C2nError(
            f"{folder / PARTS_FILE}: not a list of part folders — give the parts' logs to c2n analyze"
        )
    again = next((n for i, n in enumerate(listed) if n in listed[:i] or n == folder.name), None)
    if again is not None:  # a part read twice is the drive counted twice: an interval too narrow
        raise C2nError(
            f"{folder / PARTS_FILE}: lists {again} twice (damaged: c2n lists each part once) — "
            f"give the parts' logs to c2n analyze, each once"
        )
    return listed


def _folder_name(name: object) -> bool:
    """A folder's own name, beside the session's: no path, no `.` or `..`, not longer than a file
    system holds (a damaged parts.json's 300 characters ended in a traceback)."""
    return (
        isinstance(name, str)
        and name not in ("", ".", "..")
        and Path(name).name == name
        and "\\" not in name
        and len(os.fsencode(name)) <= _NAME_MAX
    )


_NAME_MAX = 255  # bytes in a folder's name (ext4, NTFS, exFAT)


def _raw_log(folder: Path) -> Path | None:
    return next((folder / f"frames{s}" for s in RAW_FORMATS if (folder / f"frames{s}").is_file()), None)


def unfinished(folder: Path) -> str | None:
    """Why a session folder's frames may not be its whole drive: no summary, which c2n live
    writes when it ends — the session is still being recorded, or its run was killed. None for a
    log file, or a session that ended."""
    if not folder.is_dir() or (folder / SESSION_SUMMARY).exists():
        return None
    return f"no {SESSION_SUMMARY}: the session is still being recorded, or its c2n live was killed"


def read_session(folder: Path) -> tuple[list[Path], Path]:
    """A recorded session folder's raw logs — its own, then those of the parts it went on in
    (``<folder>-part2``…, a disk's largest file reached), in order — and its config copy (whose
    DBCs lie beside it)."""
    first = _raw_log(folder)
    configs = sorted((folder / SESSION_CONFIG).glob("*.toml"))
    if first is None:
        raise C2nError(
            f"{folder}: not a c2n session folder (no frames.log/.asc/.blf) — give a session folder or a log"
        )
    if len(configs) != 1:
        raise C2nError(
            f"{folder / SESSION_CONFIG}: expected one config copy, found {len(configs)} — pass --config F"
        )
    beside = Path(os.path.realpath(folder)).parent  # a link's parts are beside where it leads
    logs = [first]
    names = _parts_named(folder)
    for k, name in enumerate(names, 1):
        if not (beside / name).is_dir():
            raise C2nError(
                f"{folder}: its session went on in {name}, which is not beside it (moved, renamed or "
                f"deleted) — put the parts beside it, or give the logs you have to c2n analyze"
            )
        log = _raw_log(beside / name)
        if log is not None:
            logs.append(log)
            continue
        # none: the run was killed as its last part was made, before that part's first frame; a
        # part before it, or one of a session that ended, had frames (a drive read without them)
        ended = any((f / SESSION_SUMMARY).exists() for f in (folder, beside / name))
        if k < len(names) or ended:
            raise C2nError(
                f"{folder}: its session went on in {name}, whose log (frames.log/.asc/.blf) is not there "
                f"(moved or deleted) — put it back, or give the logs you have to c2n analyze"
            )
    return logs, configs[0]


_PART_FOLDER = re.compile(r"(?P<first>.+)-part(?P<n>[0-9]+)")


def session_of_part(path: Path) -> tuple[Path, list[Path]] | None:
    """The session ``path`` (a session folder, or its raw log) is one part of, where the session
    went on in parts (a disk's largest file reached): its first folder and every part's log, in
    order. None for a log, a session of one part, or a session's first folder (read whole)."""
    path = Path(os.path.realpath(path))  # `frames.log` in a part's folder, a link to one
    folder = path if path.is_dir() else path.parent
    if path.is_dir() and (path / PARTS_FILE).is_file():
        return None  # the first folder: the session is read whole (``read_session``)
    if not path.is_dir() and _raw_log(folder) != path:
        return None
    first = folder
    if not (folder / PARTS_FILE).is_file():
        found = _first_folder_of(folder)
        if found is None:
            return None
        first = found
    try:
        logs, _ = read_session(first)
    except (C2nError, OSError):  # a part moved away, a damaged parts.json: said where it is read whole
        return None
    return (first, logs) if len(logs) > 1 else None


def _first_folder_of(part: Path) -> Path | None:
    """The first folder of the session ``part`` (a folder named ``<first>-partN``) is a part of:
    the one its name gives, or, that renamed since (the parts keep their names), the folder beside
    it whose parts.json lists it. None: not a part of a session."""
    match = _PART_FOLDER.fullmatch(part.name)
    if not match:
        return None
    named = part.parent / match["first"]
    try:
        beside = sorted(p for p in part.parent.iterdir() if p != named and (p / PARTS_FILE).is_file())
    except OSError:
        beside = []
    for first in (named, *beside):
        try:
            if (first / PARTS_FILE).is_file() and part.name in _parts_named(first):
                return first
        except (C2nError, OSError):
            continue
    return None


def parts_left_out(given: Sequence[Path], command: str = "analyze") -> list[tuple[Path, str]]:
    """For each of ``given`` that is one part of a session recorded in parts, the others not
    among ``given``: what it says (``path``, why) — its result is of that part alone, and every
    part's log to c2n ``command`` reads them all."""
    read = {os.path.realpath(p) for p in given}
    said = []
    for path in given:
        found = session_of_part(path)
        if found is None:
            continue
        first, logs = found
        if all(os.path.realpath(log) in read for log in logs):
            continue
        own = path if path.is_file() else _raw_log(path)
        k = next(
            (
                i
                for i, log in enumerate(logs, 1)
                if own is not None and os.path.realpath(log) == os.path.realpath(own)
            ),
            0,
        )
        which = f"part {k} of {len(logs)}" if k else f"one of {len(logs)} parts"
        said.append(
            (
                path,
                f"{which} of the session {first}, which went on in parts ({PARTS_FILE}): the result is of "
                f"this part alone — give the session folder {first} to c2n export or a campaign, or every "
                f"part's log to c2n {command} ({' '.join(str(log) for log in logs)})",
            )
        )
    return said
