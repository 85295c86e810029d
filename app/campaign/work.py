"""A campaign's drives sent to workers, resumably: local processes or a Dask cluster.

Each task runs where the logs are (``analysis.analyse`` on a worker); it hashes its log and config
there and, when the result of that pair is known already (``known``), returns only the key.
Every finished row is written to ``cache/<key>.json`` at once, so a re-run analyses only what is
new or changed and an interrupted run picks up where it stopped.
"""

import concurrent.futures as cf
import contextlib
import errno
import fcntl
import json
import multiprocessing
import os
import re
import signal
import socket
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from app.campaign.analysis import Job, analyse, config_hash, content_hash, logs_hash, where
from app.campaign.manifest import Manifest
from app.campaign.row import SessionRow
from app.errors import C2nError, Interrupted, printable
from app.output.files import partial_pid, write_json
from app.sim.workers import ends_with_parent

CACHE = "cache"
HASHES = "hashes.json"  # not a row: its stem is no key
WRITTEN = "written.json"  # the digests of the results each run put in place (``ownership.ours``)
# a row's key: the logs' and the config's hashes (a session's parts' hashes joined by "+" before
# 2026-11-29, whose campaigns were refused the second time: their cache held "files c2n did not write")
_ROW_NAME = re.compile(r"(?:[0-9a-f]{32}\+)*[0-9a-f]{32}-[0-9a-f]{32}\.json")


@dataclass(frozen=True)
class Task:
    job: Job
    known: frozenset[str]  # keys whose rows the campaign has already


def _one_hash(path: Path) -> str:
    return content_hash([path])


def run_task(task: Task) -> SessionRow | str:
    """On a worker: the row of one drive, or only its key when that row is known."""
    try:
        raws, config_path, dbc_dir = where(task.job)
        key = f"{logs_hash(task.job.log, raws, _one_hash)}-{config_hash(config_path, dbc_dir, _one_hash)}"
    except (C2nError, OSError) as error:
        message = error.strerror if isinstance(error, OSError) and error.strerror else str(error)
        return SessionRow(error=printable(f"{task.job.log}: {message}"))
    if key in task.known:
        return key
    return replace(analyse(task.job), key=key)


# what every worker needs, imported once in the fork server (~2.5 s of numba, scipy, python-can
# and the pipeline) instead of once per worker on cores the workers share
PRELOAD = [
    "app.campaign.fork_server",  # the server's own signals
    "app.campaign.analysis",
    "app.pipeline",
    "app.run_loop",
    "app.sinks.summary",
    "app.sources.logs",
]


@contextmanager
def local_workers(n: int) -> Iterator[cf.Executor]:
    """Worker processes on this machine, each forked from a fork server that imported what they
    need and nothing of the campaign's state (spawned fresh where there is no fork server)."""
    context: multiprocessing.context.BaseContext = multiprocessing.get_context("spawn")
    if "forkserver" in multiprocessing.get_all_start_methods():
        server = multiprocessing.get_context("forkserver")
        server.set_forkserver_preload(PRELOAD)
        context = server
    with cf.ProcessPoolExecutor(max_workers=n, mp_context=context, initializer=_start_worker) as pool:
        yield pool


def _start_worker() -> None:
    """A worker leaves Ctrl-C, SIGTERM and SIGHUP (sent to the whole process group: a terminal's,
    systemd's, a scheduler's) to the campaign, which keeps what is done and stops the rest; a
    worker killed by one broke the pool, and Python 3.11's pool then waited for good. And it
    ends when the campaign does, however that ends: a fork server's children are not the
    campaign's, and would live on after a kill -9 of it."""
    for ending in (signal.SIGINT, signal.SIGTERM, signal.SIGHUP):  # the campaign's to act on
        signal.signal(ending, signal.SIG_IGN)
    ends_with_parent()


CONNECT_TIMEOUT_S = 10.0  # a scheduler on a reachable network answers in far less
_LARGEST_HANDSHAKE = 1 << 20  # bytes: a Dask handshake is a small dict of versions


def probe_scheduler(address: str, timeout_s: float = CONNECT_TIMEOUT_S) -> None:
    """Raise a C2nError unless a Dask scheduler answers at ``tcp://host:port`` within ``timeout_s``.

    A Dask server writes its handshake as soon as it accepts a connection (a length-prefixed
    frame); anything else that accepts one (a web server, waiting for a request) would leave
    ``distributed.Client`` waiting for that handshake with no end."""
    host, sep, port = address.removeprefix("tcp://").rpartition(":")
    host = host.strip("[]")
    if not sep or not host or not port.isdigit():
        raise C2nError(f"--scheduler {printable(address)}: want tcp://HOST:PORT")
    try:
        with socket.create_connection((host, int(port)), timeout=timeout_s) as connection:
            head = connection.recv(8)
    except TimeoutError:
        raise C2nError(
            f"--scheduler {printable(address)}: something accepted the connection but sent no Dask "
            f"handshake in {timeout_s:g} s — is it a Dask scheduler's address (often port 8786)?"
        ) from None
    except OSError as error:
        reason = error.strerror or type(error).__name__
        raise C2nError(f"--scheduler {printable(address)}: no Dask scheduler answers ({reason})") from None
    if len(head) < 8 or not 0 < int.from_bytes(head, "little") <= _LARGEST_HANDSHAKE:
        raise C2nError(
            f"--scheduler {printable(address)}: what answers there is not a Dask scheduler "
            "(its first bytes are no Dask handshake)"
        )


@contextmanager
def dask_workers(address: str) -> Iterator[cf.Executor]:
    """The workers of a Dask distributed cluster (``distributed.Client(address)``); ``local``
    starts a ``LocalCluster`` of one single-threaded worker process per CPU for the run."""
    from distributed import Client, LocalCluster  # the command checked they are there

    with contextlib.ExitStack() as stack:
        if address == "local":
            workers = os.cpu_count() or 1
            cluster = LocalCluster(  # type: ignore[no-untyped-call]
                n_workers=workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                # no dashboard, but the scheduler's HTTP routes are served anyway: on port 8787 of
                # every interface, else (taken by a Jupyter's cluster or another campaign) on
                # another after a UserWarning of four lines; a free port of this machine's own
                scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
            )
            stack.enter_context(cluster)
            address = cluster.scheduler_address
        if address.startswith("tcp://"):
            probe_scheduler(address)
        try:
            client = Client(address, timeout=f"{CONNECT_TIMEOUT_S:g}s")  # type: ignore[no-untyped-call]
        except (OSError, TimeoutError) as error:
            raise C2nError(f"--scheduler {address}: no Dask scheduler answers ({error})") from None
        stack.callback(client.close)
        with client.get_executor(pure=False) as executor:  # type: ignore[no-untyped-call]
            yield executor


@contextmanager
def claimed(out: Path) -> Iterator[Path]:
    """``out``'s cache folder, made where missing and held by this run alone for the ``with``
    body (flock(2) on the folder, let go however the run ends, a kill included): a second
    campaign on the same ``--out`` meanwhile is refused in one line, where the two would each
    put their results in place and leave a set of files mixed from both. The folders it made
    go again if they are still empty (a run refused before any work)."""
    cache = out / CACHE
    try:
        made = _make(cache)
        held = os.open(cache, os.O_RDONLY)
    except OSError as error:
        raise C2nError(f"{cache}: cannot be made ({error.strerror}) — choose another --out") from None
    try:
        try:
            fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise C2nError(
                f"{out}: another c2n campaign is writing it — wait for that one to end, or choose "
                "another --out"
            ) from None
        except OSError as error:  # a file system without locks (some network mounts): unguarded
            if error.errno not in (errno.ENOLCK, errno.EOPNOTSUPP, errno.ENOTSUP):
                raise C2nError(f"{cache}: cannot be held ({error.strerror})") from None
        yield cache
    finally:
        os.close(held)
        _unmake(made)


def run_campaign(
    manifest: Manifest,
    config: Path | None,
    out: Path,
    workers: Callable[[], AbstractContextManager[cf.Executor]],
    on_row: Callable[[int, SessionRow], None] = lambda i, row: None,
) -> list[SessionRow]:
    """Every entry's row, in manifest order; ``on_row(index, row)`` as each arrives. A drive
    whose log and config this machine sees and whose key has a row already is not sent at all;
    the workers are started (``workers()``) only when something is left to analyse."""
    cache = out / CACHE
    try:
        made = _make(cache)
    except OSError as error:
        raise C2nError(f"{cache}: cannot be made ({error.strerror}) — choose another --out") from None
    stored = _stored(cache)
    memo = HashMemo(cache / HASHES)
    rows: list[SessionRow | None] = [None for _ in manifest.entries]
    pending = []
    for i, entry in enumerate(manifest.entries):
        key = memo.key(Job(entry.log, config))
        if key is not None and key in stored:
            rows[i] = row = replace(_seen_at(stored[key], Job(entry.log, config)), cached=True)
            on_row(i, row)
        else:
            pending.append(i)
    if not pending:
        memo.save()
        return _all(rows)
    known = frozenset(stored)
    with contextlib.ExitStack() as stack:
        try:
            executor = stack.enter_context(workers())
        except BaseException:  # refused (or Ctrl-C) before any work: the folders made go again
            _unmake(made)
            raise
        memo.save()
        jobs = {i: Job(manifest.entries[i].log, config) for i in pending}
        futures = {executor.submit(run_task, Task(jobs[i], known)): i for i in pending}
        try:
            done = cf.as_completed(futures)
            for future in done:
                _take(future.result(), futures[future], jobs[futures[future]], rows, stored, cache, on_row)
        except KeyboardInterrupt:  # what is done is kept; what runs is finished; the rest not started
            for future in futures:
                future.cancel()
            cf.wait(futures)
            for future, i in futures.items():  # (one cut short while being taken, too)
                if rows[i] is None and not future.cancelled() and future.exception() is None:
                    _take(future.result(), i, jobs[i], rows, stored, cache, on_row)
            kept = sum(1 for row in rows if row is not None)
            raise Interrupted(
                f"{kept} of {len(rows)} sessions are done and kept in {cache}; "
                "run the same command again to go on"
            ) from None
        except cf.BrokenExecutor:  # a worker killed outright: the kernel's OOM killer, kill -9
            kept = sum(1 for row in rows if row is not None)
            raise C2nError(
                f"a worker process ended in the middle of a drive (killed: out of memory?): {kept} of "
                f"{len(rows)} sessions are done and kept in {cache}; run the same command again to go "
                "on (--workers 1 shows which log it was)"
            ) from None
    return _all(rows)


def _seen_at(row: SessionRow, job: Job) -> SessionRow:
    """A kept row with the paths of its log and config as this run gives them (the same content
    moved or renamed since: its results named the old place)."""
    try:
        raws, config_path, _ = where(job)
    except (C2nError, OSError):  # not readable here (a cluster's worker read it): as kept
        return row
    return row.seen_at([str(raw) for raw in raws], str(config_path))


def _all(rows: list[SessionRow | None]) -> list[SessionRow]:
    assert all(row is not None for row in rows)  # every entry's row arrived
    return [row for row in rows if row is not None]


def _make(folder: Path) -> list[Path]:
    """Make ``folder`` and its missing parents; the ones this call made (another process's are
    not), outermost first."""
    missing = [path for path in (folder, *folder.parents) if not os.path.lexists(path)]
    made = []
    for path in reversed(missing):
        try:
            path.mkdir()
        except FileExistsError:  # made meanwhile by someone else: not ours
            continue
        made.append(path)
    return made


def _unmake(made: list[Path]) -> None:
    """Remove the folders ``_make`` made, innermost first, each only while it is empty."""
    for path in reversed(made):
        with contextlib.suppress(OSError):
            path.rmdir()


def _take(
    done: SessionRow | str,
    i: int,
    job: Job,
    rows: list[SessionRow | None],
    stored: dict[str, SessionRow],
    cache: Path,
    on_row: Callable[[int, SessionRow], None],
) -> None:
    """A worker's row: kept in the cache (or, when only its key came back, the row kept there)."""
    if isinstance(done, str):
        row = replace(_seen_at(stored[done], job), cached=True)
    elif done.key is not None:
        write_json(cache / f"{done.key}.json", done.to_json(), "the campaign's cache")
        row = replace(done, cached=False)
    else:  # its log could not be read here: no key, nothing to keep
        row = done
    rows[i] = row
    on_row(i, row)


def is_memo(data: object) -> bool:
    """What ``HashMemo`` writes: each file's path to its size, times and inode, and its content
    hash (an older c2n's: size and mtime only, hashed again)."""
    return isinstance(data, dict) and all(
        isinstance(entry, list)
        and len(entry) in (3, 5)
        and all(isinstance(x, int) for x in entry[:-1])
        and isinstance(entry[-1], str)
        for entry in data.values()
    )


def is_cache(folder: Path) -> bool:
    """A campaign's cache folder, known by its content: rows named by their keys (two BLAKE2b
    hashes), the hash memo, a killed write's temporaries — a user's own ``cache`` is not. A memo
    that does not read (a disk's fault) beside rows is still the cache's: ``HashMemo`` takes it
    for none, and hashes again."""
    try:
        entries = list(folder.iterdir())
    except OSError:
        return False
    rows = any(_ROW_NAME.fullmatch(entry.name) for entry in entries)
    for entry in entries:
        if entry.name == HASHES:
            if not rows and not _a_memo(entry):
                return False
        elif entry.name == WRITTEN:
            continue
        elif not _ROW_NAME.fullmatch(entry.name) and not _a_rows_temporary(entry.name, folder):
            return False
    return True


def _a_memo(path: Path) -> bool:
    try:
        return is_memo(json.loads(path.read_text(encoding="utf-8")))
    except (OSError, ValueError):
        return False


def _a_rows_temporary(name: str, folder: Path) -> bool:
    """A row's (or the memo's) temporary a killed write left: ``.<key>.<pid>.partial.json``."""
    stem = name[1:].split(".", 1)[0] if name.startswith(".") else ""
    return (_ROW_NAME.fullmatch(f"{stem}.json") is not None or f"{stem}.json" == HASHES) and (
        partial_pid(name, folder / f"{stem}.json") is not None
    )


class HashMemo:
    """Content hashes of the files this machine sees, kept by (path, size, mtime): a re-run reads
    no log whose file is unchanged. A file it cannot see or read gets no key here (its worker
    hashes it, or says what is wrong)."""

    def __init__(self, path: Path) -> None:
        self.path = path
        try:
            known = json.loads(path.read_text(encoding="utf-8"))
        except (OSError, ValueError):
            known = None
        self._known: dict[str, list[Any]] = known if is_memo(known) else {}  # a damaged one: none
        self._configs: dict[tuple[Path, Path | None], str] = {}

    def key(self, job: Job) -> str | None:
        try:
            raws, config_path, dbc_dir = where(job)
            log_hash = logs_hash(job.log, raws, self._hash)
            config_key = (config_path, dbc_dir)
            if config_key not in self._configs:
                self._configs[config_key] = config_hash(config_path, dbc_dir, self._hash)
        except (C2nError, OSError):
            return None
        return f"{log_hash}-{self._configs[config_key]}"

    def _hash(self, path: Path) -> str:
        """The file's content hash, remembered by its size, modification and change times and
        inode: a log copied over another of the same size and date (a logger without a clock, one
        that cuts files at a size; `touch -d`) keeps the size and mtime, and its earlier drive's
        result was taken for it. The change time no program sets back."""
        stat = path.stat()
        name = str(path.resolve())
        seen = [stat.st_size, stat.st_mtime_ns, stat.st_ctime_ns, stat.st_ino]
        known = self._known.get(name)
        if known is not None and known[:-1] == seen:
            return str(known[-1])
        digest = content_hash([path])
        self._known[name] = [*seen, digest]
        return digest

    def save(self) -> None:
        with contextlib.suppress(C2nError):  # only a speed-up: the next run hashes again
            write_json(self.path, self._known, "the campaign's hash memo")


def _stored(cache: Path) -> dict[str, SessionRow]:
    """The rows of earlier runs (a file that does not read back, or was written by a c2n that
    kept rows otherwise, is no row: its drive runs again)."""
    rows = {}
    for path in cache.glob("*.json"):
        if path.name == HASHES:
            continue
        try:
            row = SessionRow.from_json(json.loads(path.read_text(encoding="utf-8")))
        except (OSError, ValueError):
            continue
        if row.key == path.stem:
            rows[path.stem] = row
    return rows
