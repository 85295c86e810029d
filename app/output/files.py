"""Every result file is written the same way: into a temporary file beside it, synced to the
disk, then renamed into place, so a crash, a kill, a power cut or a full disk leaves the old file
or the new one, never half of one (``durable.py``); an OS error becomes one OutputError naming
the file."""

import contextlib
import ctypes
import dataclasses
import errno
import functools
import glob
import json
import os
import shutil
import signal
import stat
import sys
import uuid
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from app.errors import OutputError
from app.output.durable import synced, synced_tree


def new_folder(candidates: Iterable[Path]) -> Path | None:
    """The first of ``candidates`` made new, claimed by making it (two runs never share one); a
    folder or file already there is never entered. None where every one is taken."""
    for folder in candidates:
        try:
            folder.mkdir()
            return folder
        except FileExistsError:
            continue
    return None


def partial_path(path: Path) -> Path:
    """The temporary name a file is written under: hidden, unique to this process, and with the
    file's own suffix (asammdf and matplotlib pick the format from it)."""
    return path.with_name(f".{path.stem}.{os.getpid()}.partial{path.suffix}")


def partial_pid(name: str, path: Path) -> int | None:
    """The process whose temporary of ``path`` (``partial_path``) ``name`` is; None: it is not one."""
    prefix, suffix = f".{path.stem}.", f".partial{path.suffix}"
    if not (name.startswith(prefix) and name.endswith(suffix)):
        return None
    pid = name[len(prefix) : -len(suffix)]
    return int(pid) if pid.isdigit() else None


def write_atomically(path: Path, write: Callable[[Path], object], what: str) -> None:
    """``write(tmp)`` writes the file's content to ``tmp``; it then replaces ``path`` — where a
    symlink points, the link kept. ``what`` names the file in the error ("the summary", "the
    report"). Whatever stops the write (an error, Ctrl-C) takes the temporary with it; one a
    killed run left (its process gone) goes at the next write of the same file. The content is
    on the disk before the rename, the rename before this returns: a power cut too leaves one."""
    write_together([(path, write, what)])


def write_together(files: Sequence[tuple[Path, Callable[[Path], object], str]]) -> None:
    """Files that belong together (a log and its truth, a diagnosis and its report), each
    ``(path, write, what)`` as ``write_atomically`` takes one: every one is written to its
    temporary beside it and put on the disk, and only then are they renamed into place, one
    after the other with Ctrl-C and SIGTERM held back — a full disk or an interrupt leaves the
    older set or the new, never a new log beside an older log's truth."""
    staged: list[tuple[Path, Path]] = []  # (temporary, target)
    try:
        for path, write, what in files:
            target = Path(os.path.realpath(path)) if os.path.islink(path) else path
            staged.append((partial_path(target), target))
            with _said_of(path, what):
                target.parent.mkdir(parents=True, exist_ok=True)
                if target.is_dir():  # refused before any file of the set is put in place
                    raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR))
                if target.exists() and not target.is_file():  # never renamed over
                    raise OutputError(
                        f"{path}: is a device or a pipe, not a file — cannot write {what} there"
                    )
                _remove_stale_partials(target)
                write(staged[-1][0])
                synced(staged[-1][0])
        with _held():  # a held Ctrl-C arrives after the last rename
            for (tmp, target), (path, _, what) in zip(staged, files, strict=True):
                with _said_of(path, what):
                    os.replace(tmp, target)
        folders: set[Path] = set()
        for (_, target), (path, _, what) in zip(staged, files, strict=True):
            if target.parent not in folders:
                folders.add(target.parent)
                with _said_of(path, what):
                    synced(target.parent)
    finally:
        for tmp, _ in staged:
            with contextlib.suppress(OSError):  # put in place: it is gone already
                tmp.unlink(missing_ok=True)


@contextlib.contextmanager
def _said_of(path: Path, what: str) -> Iterator[None]:
    """An OSError of the body as the OutputError that names the file: `PATH: cannot write WHAT (why)`."""
    try:
        yield
    except OSError as error:
        raise OutputError(f"{path}: cannot write {what} ({error.strerror or error})") from error


def _remove_stale_partials(path: Path) -> None:
    """The temporaries of ``path`` (``partial_path``) whose process is gone: a killed write's."""
    for stale in path.parent.glob(f"{glob.escape(f'.{path.stem}.')}*{glob.escape(f'.partial{path.suffix}')}"):
        pid = partial_pid(stale.name, path)
        if pid is not None and pid != os.getpid() and not _alive(pid, stale) and stale.is_file():
            with contextlib.suppress(OSError):
                stale.unlink()


def as_text(text: str) -> str:
    """``text`` with a file name's undecodable bytes (Python's surrogate escapes) as U+FFFD: what
    UTF-8, a CSV and Parquet can hold (a folder named in Latin-1 on a UTF-8 system)."""
    return text.encode("utf-8", "surrogateescape").decode("utf-8", "replace")


def json_ready(value: Any) -> Any:
    """A result dataclass as JSON's own types: dataclasses and mappings as dicts, tuples as lists
    (what ``json.loads`` gives back from the file)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: json_ready(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {key: json_ready(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(item) for item in value]
    return value


STDOUT = Path("-")  # a file name that means standard output, as for cat and tar


def write_text(path: Path, text: str, what: str) -> None:
    """``path`` ``-``: standard output (the command's own words then go to stderr)."""
    if path == STDOUT:
        if sys.stdout is None:  # closed before the command began (`1>&-`)
            raise OutputError(f"standard output is closed: cannot write {what} — give a file instead of -")
        try:
            sys.stdout.write(text)
            sys.stdout.flush()
        except OSError as error:  # a closed pipe
            raise OutputError(f"standard output: cannot write {what} ({error.strerror or error})") from error
        return
    write_atomically(path, text_file(text), what)


def write_json(path: Path, data: Any, what: str) -> None:
    write_text(path, json_text(data), what)


def json_text(data: Any) -> str:
    return json.dumps(data, indent=2) + "\n"


def text_file(text: str) -> Callable[[Path], object]:
    """What writes ``text`` (UTF-8) to a file, for ``write_atomically`` and ``write_together``."""
    return lambda tmp: tmp.write_text(as_text(text), encoding="utf-8")


@contextlib.contextmanager
def folder_atomically(
    out: Path, ours: Callable[[Path], bool], what: str, replace: bool = True
) -> Iterator[Path]:
    """A folder written as one unit: the ``with`` body writes into a hidden sibling unique to
    this run, which then takes ``out``'s place whole (an older ``out`` removed after), so a
    kill, a crash or a second run at the same time leaves one run's folder, never a mix. An
    ``out`` holding anything ``ours`` does not recognise is refused: it is not ours to replace.
    ``replace`` False: ``out`` must be new or empty, and still be when the folder is put in
    place — one rename, which the system refuses if anything was put there meanwhile (a folder
    that is there, empty, is filled instead: it may be a shell's working folder). ``out`` is where
    the system resolves it: through a symlink, and a ``..`` after one. A mount point (a USB stick)
    cannot be swapped whole: a folder inside it is asked for."""
    place = Path(os.path.realpath(out))  # `.` too
    if os.path.ismount(place):
        raise OutputError(
            f"{out}: is a mount point, which c2n cannot put a folder in place of — give a folder "
            f"inside it (e.g. {out / 'c2n'})"
        )
    recover_swapped_away(place, ours)
    if place.exists():
        foreign = [p.name for p in sorted(place.iterdir()) if not ours(p)] if place.is_dir() else [out.name]
        if not place.is_dir() or foreign:
            shown = _listed(foreign)
            raise OutputError(
                f"{out}: holds files {what} did not write ({shown}) — choose a new or empty --out"
            )
    if replace and place.is_dir() and inside(Path.cwd(), place):
        raise OutputError(  # swapped away, it would leave this shell in a folder that is gone
            f"{out}: is the folder c2n runs in (or holds it) — choose another --out"
        )
    remove_stale(place.parent, f".{place.name}.partial-")  # a killed run's
    staging = _staging(place.parent, f".{place.name}.partial-", out)
    if place.is_dir():
        _same_access(place, staging)
    kept = False
    try:
        try:
            yield staging
        except OutputError as error:  # a full disk: named as the user named the folder
            if str(staging) not in str(error):
                raise
            said = str(error).replace(str(staging), str(out))
            raise OutputError(f"{said} — {out} is left as it was") from error.__cause__
        _synced(staging, out, synced_tree)  # on the disk before it takes the older one's place
        if replace:
            _swap_in(staging, place, out, ours)
        else:
            _put_in(staging, place, out)
        for folder in (place, place.parent):  # the entries moved in; the folder's new name
            _synced(folder, out, synced)
    except _Kept:
        kept = True
        raise
    finally:
        if not kept:
            shutil.rmtree(staging, ignore_errors=True)  # gone already when it was swapped in


@contextlib.contextmanager
def files_together(folder: Path, names: Sequence[str]) -> Iterator[Path]:
    """Files of one run that belong together (a campaign's results beside its cache): the
    ``with`` body writes ``names`` into a hidden folder in ``folder``; only when every one is
    written are they renamed into place, one after the other with Ctrl-C and SIGTERM held back,
    so an interrupt or a full disk leaves the old set or the new one, never a mix."""
    prefix = ".partial-"
    remove_stale(folder, prefix)  # a killed run's
    staging = _staging(folder, prefix, folder)
    try:
        yield staging
        missing = [name for name in names if not (staging / name).is_file()]
        if missing:
            raise OutputError(f"{folder}: {', '.join(missing)} not written")
        _synced(staging, folder, synced_tree)
        try:
            with _held():  # a held Ctrl-C arrives after
                for name in names:
                    os.replace(staging / name, folder / name)
        except OSError as error:
            raise OutputError(f"{folder}: cannot put the results in place ({error.strerror})") from error
        _synced(folder, folder, synced)
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _synced(path: Path, out: Path, sync: Callable[[Path], None]) -> None:
    """``sync(path)``, a disk's refusal an OutputError naming ``out``."""
    try:
        sync(path)
    except OSError as error:
        raise OutputError(
            f"{out}: cannot write the output to the disk ({error.strerror or error})"
        ) from error


def _same_access(folder: Path, new: Path) -> None:
    """Give ``new``, which takes ``folder``'s place, who may read and write it: its mode (a
    group's setgid, a private 0700), its group and owner, its extended attributes (an ACL among
    them) — a user's folder made for an export kept them not (it took the umask's 0755 and
    the user's own group). Each as far as the system lets this user set it."""
    st = folder.stat()
    with contextlib.suppress(OSError):
        os.chown(new, st.st_uid if os.geteuid() == 0 else -1, st.st_gid)
    with contextlib.suppress(OSError):
        os.chmod(new, stat.S_IMODE(st.st_mode))  # after chown, which clears setgid
    for name in _xattrs(folder):
        with contextlib.suppress(OSError):
            os.setxattr(new, name, os.getxattr(folder, name, follow_symlinks=False), follow_symlinks=False)


def _xattrs(path: Path) -> list[str]:
    try:
        return os.listxattr(path, follow_symlinks=False)
    except (OSError, AttributeError):  # none, or a system without them (macOS's Python)
        return []


def _staging(parent: Path, prefix: str, out: Path) -> Path:
    """A new hidden folder ``<prefix><pid>-<random>`` in ``parent``, with the mode the umask
    gives (``tempfile.mkdtemp``'s would be 0700 whatever the umask)."""
    try:
        parent.mkdir(parents=True, exist_ok=True)
        while True:
            staging = parent / f"{prefix}{os.getpid()}-{uuid.uuid4().hex[:12]}"
            with contextlib.suppress(FileExistsError):
                staging.mkdir()
                return staging
    except OSError as error:
        raise OutputError(f"{out}: cannot create the output folder ({error.strerror or error})") from error


def remove_stale(folder: Path, prefix: str) -> list[Path]:
    """Remove the folders ``prefix<pid>-…`` in ``folder`` whose process is gone: what a killed
    run (SIGKILL cannot be caught) left. Returns what it removed."""
    removed = []
    for path in folder.glob(f"{glob.escape(prefix)}*-*"):
        pid = path.name[len(prefix) :].split("-", 1)[0]
        if path.is_dir() and pid.isdigit() and not _alive(int(pid), path):
            shutil.rmtree(path, ignore_errors=True)
            removed.append(path)
    return removed


def _alive(pid: int, left: Path) -> bool:
    """Whether process ``pid``, which named ``left`` after itself, may still be writing it: a
    process of that number is there and — where the system says when it started (Linux's /proc)
    — it started before ``left`` last changed (its mtime or ctime: made, written, renamed). After
    a power cut and a reboot the number is another process's, started after; its leftover would
    otherwise stay for good (a swapped-away older folder never put back)."""
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # someone else's
        pass
    started = _started_s(pid)
    if started is None:
        return True
    try:
        status = left.lstat()
    except OSError:
        return True
    return started <= max(status.st_mtime, status.st_ctime) + _START_SLACK_S


# the boot time /proc gives is in whole seconds: a process is taken for the writer of what
# changed up to this long before it started
_START_SLACK_S = 2.0


def _started_s(pid: int) -> float | None:
    """When process ``pid`` started, in seconds of the epoch (Linux's /proc); None elsewhere."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        lines = Path("/proc/stat").read_text().splitlines()
        boot = next(int(line.split()[1]) for line in lines if line.startswith("btime "))
        return boot + int(fields[19]) / os.sysconf("SC_CLK_TCK")  # field 22, starttime, in ticks
    except (OSError, ValueError, IndexError, StopIteration):
        return None


def inside(path: Path, folder: Path) -> bool:
    """``path`` is ``folder`` or in it, however spelt."""
    inner, outer = os.path.realpath(path), os.path.realpath(folder)
    return inner == outer or inner.startswith(outer.rstrip(os.sep) + os.sep)


def _put_in(staging: Path, place: Path, out: Path) -> None:
    """``staging`` renamed to ``place`` (rename(2) replaces only an empty folder, atomically);
    into an empty folder that is there, its entries are moved, Ctrl-C and SIGTERM held back."""
    try:
        if place.is_dir():
            if any(place.iterdir()):
                raise FileExistsError(errno.ENOTEMPTY, "not empty")
            with _held():
                for entry in sorted(staging.iterdir()):
                    os.rename(entry, place / entry.name)
        else:
            staging.rename(place)
    except OSError as error:
        if error.errno in (errno.ENOTEMPTY, errno.EEXIST, errno.ENOTDIR, errno.EISDIR):
            raise OutputError(
                f"{out}: was filled while c2n wrote (another run?) — left as it is; run again with "
                "a new --out"
            ) from error
        raise OutputError(f"{out}: cannot put the output folder in place ({error.strerror})") from error


@contextlib.contextmanager
def _held() -> Iterator[None]:
    """Ctrl-C and SIGTERM held back for the body, then delivered."""
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT, signal.SIGTERM})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _swap_in(staging: Path, place: Path, out: Path, ours: Callable[[Path], bool]) -> None:
    """``staging`` in ``place``'s stead, the older folder removed after — unless something put in
    it while c2n wrote is not ``ours`` (a user's file, another command's log): then it is left as
    it was and the new one not put in. Where the system can (Linux's renameat2), the two folders
    trade places in one step, so no moment — a kill, a power cut — leaves ``place`` missing."""
    try:
        if exchange(staging, place):  # staging now holds the older folder: folder_atomically removes it
            foreign = [p.name for p in sorted(staging.iterdir()) if not ours(p)]
            if foreign:
                _trade_back(staging, place, out, foreign)
            return
    except OSError as error:
        raise OutputError(f"{out}: cannot put the output folder in place ({error.strerror})") from error
    olds = []
    try:
        for _ in range(5):  # another run may swap its folder in between our two renames
            old = place.with_name(f"{_old_prefix(place)}{os.getpid()}-{uuid.uuid4().hex[:8]}")
            with contextlib.suppress(FileNotFoundError):
                place.rename(old)
                olds.append(old)
                foreign = [p.name for p in sorted(old.iterdir()) if not ours(p)]
                if foreign:
                    olds.remove(old)
                    _put_back(old, place, out, foreign)
            try:
                staging.rename(place)
                return
            except OSError as error:
                if not place.exists():
                    raise OutputError(
                        f"{out}: cannot put the output folder in place ({error.strerror})"
                    ) from error
        raise OutputError(f"{out}: other runs keep writing this folder — choose another --out")
    except OSError as error:
        raise OutputError(f"{out}: cannot put the output folder in place ({error.strerror})") from error
    finally:
        for old in olds:
            shutil.rmtree(old, ignore_errors=True)


_RENAME_EXCHANGE = 2  # <linux/fs.h>
_AT_FDCWD = -100


def exchange(a: Path, b: Path) -> bool:
    """``a`` and ``b`` trade places atomically (renameat2 with RENAME_EXCHANGE: Linux 3.15, most
    local file systems). False where the system or the file system cannot, or ``b`` is missing:
    the caller renames instead. The standard library has no binding for it."""
    renameat2 = getattr(_libc(), "renameat2", None)
    if renameat2 is None:
        return False
    done = renameat2(_AT_FDCWD, os.fsencode(a), _AT_FDCWD, os.fsencode(b), _RENAME_EXCHANGE)
    if done == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.ENOENT, errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP, errno.ENOTSUP, errno.EXDEV):
        return False
    raise OSError(code, os.strerror(code), str(b))


@functools.cache
def _libc() -> ctypes.CDLL:
    return ctypes.CDLL(None, use_errno=True)


def _trade_back(staging: Path, place: Path, out: Path, foreign: list[str]) -> None:
    """The older folder (in ``staging`` once exchanged), found holding ``foreign`` files, traded
    back into ``place``; always an OutputError. Where it cannot be, it is kept under a name of
    its own, and named (``staging`` is removed after)."""
    shown = _listed(foreign)
    try:
        if not exchange(staging, place):
            raise OSError(errno.ENOTSUP, "cannot exchange")
    except OSError:
        kept = place.with_name(f".{place.name}.kept-{uuid.uuid4().hex[:8]}")
        try:
            staging.rename(kept)
        except OSError:
            kept = staging
        raise _Kept(f"{out}: {shown} was put in it while c2n wrote; the folder is kept as {kept}") from None
    raise OutputError(
        f"{out}: {shown} was put in it while c2n wrote — left as it is, this run's output not put in; "
        "run again with a new --out"
    )


class _Kept(OutputError):
    """The folder where c2n staged its output holds a user's files now: it is not removed."""


def _listed(names: list[str]) -> str:
    """The first three of ``names``, an ellipsis for the rest."""
    return ", ".join(names[:3]) + (" …" if len(names) > 3 else "")


def _old_prefix(place: Path) -> str:
    return f".{place.name}.old-"


def recover_swapped_away(place: Path, ours: Callable[[Path], bool]) -> None:
    """An older folder a killed run left swapped away (``.NAME.old-PID-…``, where the two folders
    could not trade places in one step and the run died between its two renames): put back where
    ``place`` is missing (the user's previous output, as it was), removed where ``place`` is there
    and it holds only ``ours``; anything else is left as it is."""
    prefix = _old_prefix(place)
    found = [p for p in place.parent.glob(f"{glob.escape(prefix)}*") if p.is_dir()]
    for old in sorted(found, key=lambda p: p.stat().st_mtime_ns, reverse=True):  # the newest first
        pid = old.name[len(prefix) :].split("-", 1)[0]
        if pid.isdigit() and _alive(int(pid), old):
            continue  # another run, between its renames now
        with contextlib.suppress(OSError):
            if not os.path.lexists(place):
                old.rename(place)
            elif all(ours(p) for p in old.iterdir()):
                shutil.rmtree(old)


def _put_back(old: Path, place: Path, out: Path, foreign: list[str]) -> None:
    """``old``, found holding ``foreign`` files once swapped away, renamed back (or, where
    another run took the place meanwhile, left where it is and named); always an OutputError."""
    shown = _listed(foreign)
    try:
        old.rename(place)
    except OSError:
        raise OutputError(
            f"{out}: {shown} was put in it while c2n wrote; the folder is kept as {old}"
        ) from None
    raise OutputError(
        f"{out}: {shown} was put in it while c2n wrote — left as it is, this run's output not put in; "
        "run again with a new --out"
    )
