"""The one check every command runs on where it will write, before any work: an output is never
one of the command's inputs (a log, the manifest, the config, a DBC) nor a folder holding one,
never standard output twice or a folder on standard output, never two outputs in one file, never
a name too long for the file system, and never a file c2n did not write — a file is c2n's when
its content is what c2n writes for that kind (``json_with``, ``HTML_REPORT``), a folder when
every entry is (the command's ``ours``); a user's file is replaced only with ``--force``.
Writing itself goes through ``app.output.files`` (a temporary, swapped in whole)."""

import json
import os
import re
import stat
import tempfile
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.errors import OutputError, UsageError
from app.output.files import STDOUT, inside

GENERATOR = '<meta name="generator" content="c2n">'  # in the head of every HTML page c2n writes
PAGE_KIND = '<meta name="c2n-page" content="{kind}">'  # and which command's page it is
_OLDER_HTML = "default-src 'none'; img-src data:"  # the policy of pages written before the marker
# the longest a temporary adds to an output's name (``files.partial_path``, ``files.folder_atomically``)
_TEMPORARY_EXTRA = len(".partial-4194304-0123456789ab.")
# larger than any result file c2n writes (a summary of 8 hours' crossings is a few MB): a file
# above it is not read to find out, it is not c2n's
_LARGEST_RESULT = 64 * 2**20


@dataclass(frozen=True)
class Output:
    """One place a command writes: ``option`` as the user named it (``--json``), what is written
    there, and ``ours(path)``: whether an existing file (a folder: each of its entries) is c2n's
    to replace."""

    option: str
    path: Path
    ours: Callable[[Path], bool]
    folder: bool = False
    stdout: bool = False  # ``-`` means standard output
    parent: bool = False  # a folder c2n makes new entries in (``live --record``), never replaces
    # why a file of c2n's there is still not this run's to replace without --force (another
    # drive's summary: ``result_of``); None where it is
    whose: Callable[[Path], str | None] | None = None


def check(outputs: Sequence[Output | None], inputs: Iterable[Path], force: bool | None = None) -> None:
    """Raise a UsageError (exit 2) for outputs that clash with the inputs or each other, an
    OutputError (exit 1) for an existing file or folder c2n did not write. ``force``: the
    command's ``--force`` (None: it has none — folders are never forced, they are replaced whole)."""
    given = [out for out in outputs if out is not None]
    sources = [Path(p) for p in inputs]
    _stdout(given)
    files = [out for out in given if out.path != STDOUT]
    for out in files:
        _name_fits(out)
        for source in sources:
            if _same(out.path, source):
                raise UsageError(
                    f"{out.option} {out.path}: that is an input of this command — write elsewhere"
                )
            if out.folder and inside(source, out.path):
                raise UsageError(
                    f"{out.option} {out.path}: that folder holds an input ({source}) — choose another folder"
                )
    for i, a in enumerate(files):
        for b in files[i + 1 :]:
            if _same(a.path, b.path):
                raise UsageError(f"{a.option} and {b.option}: both name {a.path} — give each its own file")
    for out in files:
        _ours(out, force)
        _can_write(out)


def config_files(config: object) -> list[Path]:
    """The config file and its DBCs (a ``Config``): inputs every command reads."""
    path = getattr(config, "path", None)
    dbcs = [dbc.path for dbc in getattr(config, "dbcs", ())]
    return ([path] if isinstance(path, Path) else []) + dbcs


def json_with(*keys: str) -> Callable[[Path], bool]:
    """A JSON object holding ``keys``: the file c2n writes of that kind."""

    def ours(path: Path) -> bool:
        data = _json_object(path)
        return data is not None and all(key in data for key in keys)

    return ours


def _json_object(path: Path) -> dict[str, Any] | None:
    """The JSON object a result file holds; None for a file too large to be c2n's result, one
    that does not read, or not an object."""
    try:
        if path.stat().st_size > _LARGEST_RESULT:
            return None
        data = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    return data if isinstance(data, dict) else None


def recorded_inputs(path: Path) -> list[str] | None:
    """The inputs a result file of c2n's names (a summary's ``inputs``: logs, or a live run's
    bus); None where it names none (an older c2n's, or not such a file)."""
    data = _json_object(path)
    inputs = data.get("inputs") if data is not None else None
    if not isinstance(inputs, list) or not all(isinstance(i, str) for i in inputs):
        return None
    return inputs


def same_inputs(
    recorded: Sequence[str], given: Sequence[str | Path], beside: Path, by_name: bool = False
) -> bool:
    """Whether a result's ``recorded`` inputs are the ``given`` logs, each once, in any order: the
    same file (a hard link too). A path recorded relative (analyze's, as typed; an older export's)
    is the run's from where it stood, unknown: it is taken from the result's folder ``beside``
    and from that folder's parent (an export's or a session's place beside the log) — never from
    here, where a log of the same name may be another drive. ``by_name``: a folder beside the log
    that is its default export, where a log of the same name is this one moved or renamed with
    its export (its record then names the old place)."""
    left = list(recorded)
    for g in given:
        match = next(
            (r for r in left if _same_file(r, Path(g), beside) or (by_name and Path(r).name == Path(g).name)),
            None,
        )
        if match is None:
            return False
        left.remove(match)
    return not left


def _same_file(recorded: str, given: Path, beside: Path) -> bool:
    path = Path(recorded)
    for place in [path] if path.is_absolute() else [beside / path, beside.parent / path]:
        try:
            if os.path.samefile(place, given):
                return True
        except (OSError, ValueError):  # not there (moved, a live bus's name), or not a path at all
            continue
    return False


SESSION_SUMMARY = "summary.json"  # what c2n live writes in its session folder when it ends
SESSION_CONFIG = "config"  # and the config and DBCs it ran with, in a folder of this name, from its start
# what a result file sits beside in a folder it is one file of: an export's, a live session's
A_RUN_S_FILES = (
    "events.csv",
    "channels.csv",
    "channels.parquet",
    "channels.mf4",
    "frames.log",
    "frames.asc",
    "frames.blf",
)
# and what an HTML page sits beside there, or in a campaign's results
A_PAGE_S_FILES = ("summary.json", *A_RUN_S_FILES, "results.csv", "comparison.json")


def result_of(
    given: Sequence[str | Path], what: str, beside: Sequence[str] = A_RUN_S_FILES, now: str | None = None
) -> Callable[[Path], str | None]:
    """``Output.whose`` for a result file of ``given``'s: another drive's result that is one file
    of a folder's whole (an export's summary, a session's own: ``beside`` names the folder's other
    files) is named, not replaced without --force — the folder would look whole and not be. A
    result file alone is the user's to name again, as before. ``now``: what this run reads, where
    it is not files (a live bus: never the same drive as a result's)."""

    def whose(named: Path) -> str | None:
        path = Path(os.path.realpath(named))  # a link's target is what is replaced, beside its folder's files
        if not path.exists():
            return _a_session_s(path)
        recorded = recorded_inputs(path)
        folders = {path.parent, Path(os.path.abspath(named)).parent}  # a relative record: from either
        if recorded is None or (now is None and any(same_inputs(recorded, given, f) for f in folders)):
            return None
        others = _beside(path, beside)
        if not others:
            return None
        reads = now or ", ".join(os.path.abspath(g) for g in given)
        return (
            f"holds the {what} of {', '.join(recorded) or 'no log'}, not of {reads}, beside "
            f"that run's {others}"
        )

    return whose


def page_of(kind: str) -> Callable[[Path], str | None]:
    """``Output.whose`` for an HTML page ``kind`` writes (``c2n gap --report``): another command's
    page (an export's report.html, a campaign's) is named, not replaced without --force — its
    folder would look whole and not be. A page of this kind, or one alone, is the user's to name
    again."""

    def whose(path: Path) -> str | None:
        path = Path(os.path.realpath(path))  # a link's target is what is replaced, beside its folder's files
        if not path.exists():
            return None
        written_by = page_kind(path)
        if written_by == kind:
            return None
        others = _beside(path, A_PAGE_S_FILES)
        if written_by is not None:
            return f"is c2n {written_by}'s page" + (f", beside its {others}" if others else "")
        return f"is a page of c2n's beside another run's {others}" if others else None

    return whose


def _a_session_s(path: Path) -> str | None:
    """A new ``summary.json`` in a session folder that has none (its raw log beside it): it would
    make a killed session, or one still recording, read as one that ended (helper-33)."""
    frames = _beside(path, [name for name in A_RUN_S_FILES if name.startswith("frames.")])
    configs = path.parent / SESSION_CONFIG
    if path.name != SESSION_SUMMARY or not frames or not any(configs.glob("*.toml")):
        return None  # not a session: a log named frames.log in a folder of the user's (helper-34)
    return (
        f"is the place of the summary of the session beside it ({frames}), which has none: its c2n "
        "live was killed or still records, and a summary there would say it ended"
    )


def _beside(path: Path, names: Sequence[str]) -> str:
    """The first two of ``names`` beside ``path``, as words ("" for none)."""
    return ", ".join([name for name in names if (path.parent / name).exists()][:2])


def HTML_REPORT(path: Path) -> bool:
    """An HTML page c2n wrote: its head carries the marker (or, older, c2n's content policy)."""
    head = _page_head(path)
    return GENERATOR in head or _OLDER_HTML in head


def _page_head(path: Path) -> str:
    try:
        with path.open("rb") as file:
            return file.read(4096).decode("utf-8", "replace")
    except OSError:
        return ""


def page_kind(path: Path) -> str | None:
    """Which command wrote an HTML page of c2n's (``PAGE_KIND``); None for an older page, or none."""
    found = re.search(PAGE_KIND.format(kind="([a-z-]+)"), _page_head(path))
    return found[1] if found else None


def never(path: Path) -> bool:
    """No existing file is c2n's to replace (a log: only ``--force`` replaces one)."""
    return False


def _stdout(outputs: Sequence[Output]) -> None:
    dashes = [out for out in outputs if out.path == STDOUT]
    for out in dashes:
        if not out.stdout:
            kind = "a folder" if out.folder else "this output"
            raise UsageError(f"{out.option} -: {kind} cannot go to standard output — give a path")
    if len(dashes) > 1:
        named = " and ".join(f"{out.option} -" for out in dashes)
        raise UsageError(f"{named}: only one output can go to standard output — give the others a path")


def _name_fits(out: Output) -> None:
    name = os.fsencode(out.path.name)
    limit = _name_max(out.path.parent) - _TEMPORARY_EXTRA
    if len(name) > limit:
        raise UsageError(
            f"{out.option}: the name {out.path.name[:40]}… is {len(name)} bytes, too long for this file "
            f"system with c2n's temporary beside it (at most {limit}) — choose a shorter name"
        )


def fitted_stem(stem: str, tail: str, folder: Path) -> str:
    """``stem``, cut short and ended with '…' where ``stem + tail`` with c2n's temporary beside it
    would not fit a file name of ``folder``'s file system (NAME_MAX bytes): the names c2n makes
    of a log's (``c2n split``'s parts and their folder)."""
    room = _name_max(folder) - _TEMPORARY_EXTRA - len(os.fsencode(tail))
    if len(os.fsencode(stem)) <= room:
        return stem
    ellipsis = "…"
    return os.fsencode(stem)[: max(room - len(os.fsencode(ellipsis)), 1)].decode(errors="ignore") + ellipsis


def _name_max(folder: Path) -> int:
    for place in (folder, *folder.absolute().parents):
        try:
            return int(os.pathconf(place, "PC_NAME_MAX"))
        except (OSError, ValueError):
            continue
    return 255


def _ours(out: Output, force: bool | None) -> None:
    path = out.path
    if not os.path.lexists(path):
        _new_file(out, force)
        return
    if out.parent:
        if not path.is_dir():
            raise OutputError(f"{out.option} {path}: is a file, not a folder — give a folder (new or not)")
        return
    if out.folder:
        if os.path.ismount(os.path.realpath(path)):
            raise OutputError(
                f"{out.option} {path}: is a mount point, which c2n cannot put a folder in place of — "
                f"give a folder inside it (e.g. {path / 'c2n'})"
            )
        if not path.is_dir():
            raise OutputError(
                f"{out.option} {path}: is a file, not a folder c2n wrote — choose a new or empty folder"
            )
        foreign = sorted(entry.name for entry in path.iterdir() if not out.ours(entry))
        if foreign:
            shown = ", ".join(foreign[:3]) + (" …" if len(foreign) > 3 else "")
            what = "is not empty" if out.ours is never else "holds files c2n did not write"
            raise OutputError(f"{out.option} {path}: {what} ({shown}) — choose a new or empty folder")
        locked = _read_only(path)
        if locked:  # made so to keep them (root writes them all the same): folders are never forced
            raise OutputError(
                f"{out.option} {path}: {locked} — make it writable to replace it, or choose another folder"
            )
        return
    if not os.path.exists(path):  # a symlink to nothing: written where it points
        _new_file(out, force)
        return
    _a_plain_file(out, force)
    if force or (path.is_file() and path.stat().st_size == 0):
        return  # an empty file holds nothing to lose
    if out.ours(path):
        other = out.whose(path) if out.whose is not None else None
        if other is None:
            return
        raise OutputError(f"{out.option} {path}: {other} — choose another name, or add --force to replace it")
    how = " or add --force to replace it" if force is not None and not path.is_dir() else ""
    raise OutputError(
        f"{out.option} {path}: exists and is not a file c2n wrote of this kind — choose another name{how}"
    )


def _read_only(folder: Path) -> str | None:
    """What in a folder c2n would replace is read-only: the folder, or its files (named)."""
    if not os.stat(folder).st_mode & 0o222:
        return "is read-only"
    locked = sorted(
        str(entry.relative_to(folder))
        for entry in folder.rglob("*")
        if not entry.is_symlink() and not entry.lstat().st_mode & 0o222
    )
    if not locked:
        return None
    return f"holds read-only files ({', '.join(locked[:3])}{' …' if len(locked) > 3 else ''})"


def _new_file(out: Output, force: bool | None) -> None:
    """A file not there yet that would stand for another's (a session's summary: ``whose``) is
    written only with --force."""
    other = out.whose(out.path) if out.whose is not None and not force else None
    if other is not None:
        raise OutputError(f"{out.option} {out.path}: {other} — choose another name, or add --force")


def _a_plain_file(out: Output, force: bool | None) -> None:
    """An existing file output (through a symlink, where it points) that is a device, a pipe or
    this command's own standard output is refused whatever ``--force`` says — its name would be
    renamed over (``/dev/null``, ``/dev/stdout``), a pipe read to see whose file it is would wait
    for a writer forever; a read-only file is replaced only with ``--force``."""
    status = os.stat(out.path)
    dash = ", or - for standard output" if out.stdout else ""
    if _is_stdout(status):
        fix = "give - for it" if out.stdout else "give a file name"
        raise OutputError(f"{out.option} {out.path}: is this command's standard output — {fix}")
    if not (stat.S_ISREG(status.st_mode) or stat.S_ISDIR(status.st_mode)):
        raise OutputError(
            f"{out.option} {out.path}: is a device or a pipe, not a file — give a file name{dash}"
        )
    if stat.S_ISREG(status.st_mode) and not status.st_mode & 0o222 and not force:
        how = (
            "make it writable, choose another name, or add --force to replace it"
            if force is not None
            else "make it writable to replace it, or choose another name"
        )
        raise OutputError(f"{out.option} {out.path}: is read-only — {how}")


def _can_write(out: Output) -> None:
    """The folder c2n will write in (where a file's temporary, a folder's staging sibling goes;
    the nearest one there when it is to be made) takes a new file: tried, since permissions are
    not all (a read-only mount refuses root too) — else found only after the analysis."""
    folder = Path(os.path.realpath(out.path)).parent
    while not folder.is_dir() and folder != folder.parent:
        if folder.exists():  # a file where a folder would be made: found after the work, "File exists"
            raise OutputError(
                f"{out.option} {out.path}: {folder} is a file, not a folder — choose another place"
            )
        folder = folder.parent
    try:
        with tempfile.TemporaryFile(dir=folder):  # O_TMPFILE where it can: no name, nothing left
            pass
    except OSError as error:
        raise OutputError(
            f"{out.option} {out.path}: cannot write in {folder} ({error.strerror or error}) — "
            "choose another place"
        ) from None


def _is_stdout(status: os.stat_result) -> bool:
    try:
        own = os.fstat(1)
    except OSError:
        return False
    return (own.st_dev, own.st_ino) == (status.st_dev, status.st_ino)


def _same(a: Path, b: Path) -> bool:
    """One file however spelt: a symlink, a hard link, relative or absolute, ``./x``."""
    try:
        return os.path.samefile(a, b)
    except OSError:  # one of them does not exist (yet)
        return os.path.realpath(a) == os.path.realpath(b)


# the files c2n writes, each known by keys only it writes together
SUMMARY_JSON = json_with("c2n", "c2n_ci95", "c2n_method")  # analyze --json, live --json, summary.json
DIAGNOSIS_JSON = json_with("diagnosis", "verdict", "calibration")  # gap --json
SCORES_JSON = json_with("accuracy", "generators", "cases")  # gap-check --json
