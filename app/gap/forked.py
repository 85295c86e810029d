"""Work in forked processes: ``c2n gap`` keeps both cores busy.

A forked process inherits the drive, the fits so far and the compiled model, so nothing has to be
pickled on the way in but what is made after the fork; results cross the process edge as pickles
(plain numbers and dataclasses of them). Where the platform cannot fork (Windows, and macOS's
default), or where the caller asks for none, the same work runs here, in order: the results are the
same either way (tests/test_trace_blocks.py, tests/test_forked.py).
"""

import multiprocessing
import queue
import threading
import weakref
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from multiprocessing.reduction import ForkingPickler
from types import MappingProxyType
from typing import Any, Generic, TypeVar, cast

_T = TypeVar("_T")
_I = TypeVar("_I")
_E = TypeVar("_E")

_WORK: Callable[[int], object] | None = None  # what forked workers call, by index


def _mapping_proxy(viewed: dict[Any, Any]) -> "MappingProxyType[Any, Any]":
    return MappingProxyType(viewed)


def _reduce_mapping_proxy(
    view: "MappingProxyType[Any, Any]",
) -> tuple[Callable[[dict[Any, Any]], "MappingProxyType[Any, Any]"], tuple[dict[Any, Any]]]:
    return _mapping_proxy, (dict(view),)


# A snapshot's read-only views cross the process edge as the dicts they view, read-only again there.
ForkingPickler.register(MappingProxyType, _reduce_mapping_proxy)


def can_fork() -> bool:
    return "fork" in multiprocessing.get_all_start_methods()


def _call(index: int) -> object:
    if _WORK is None:
        raise RuntimeError("no work: map_forked sets it before the workers fork")
    return _WORK(index)


def map_forked(work: Callable[[int], _T], n: int, workers: int) -> list[_T]:
    """``work(i)`` for i < n, with ``workers`` > 1 in forked processes."""
    if workers <= 1 or n <= 1 or not can_fork():
        return [work(i) for i in range(n)]
    global _WORK
    _WORK = work
    try:
        context = multiprocessing.get_context("fork")
        with ProcessPoolExecutor(max_workers=min(workers, n), mp_context=context) as pool:
            return cast(list[_T], list(pool.map(_call, range(n))))
    finally:
        _WORK = None


class Later(Generic[_T]):
    """A result, maybe still being worked out in a forked process: ``get`` waits for it and raises
    what the work raised. A Later dropped unasked stops its process."""

    def __init__(self, value: _T | None = None) -> None:
        self._value = value
        self._receive: Connection | None = None  # where a forked process sends it
        self._process: BaseProcess | None = None

    @classmethod
    def now(cls, value: _T) -> "Later[_T]":
        return cls(value)

    @classmethod
    def _from(cls, process: BaseProcess, receive: Connection) -> "Later[_T]":
        later: Later[_T] = cls()
        later._receive, later._process = receive, process
        weakref.finalize(later, _stop, process)
        return later

    def get(self) -> _T:
        if self._receive is not None and self._process is not None:
            receive, process, self._receive = self._receive, self._process, None
            try:
                ok, value = receive.recv()
            except EOFError:
                process.join()
                raise RuntimeError(
                    f"the background process ended with exit code {process.exitcode} and no result"
                ) from None
            finally:
                receive.close()
            process.join()
            if not ok:
                raise cast(BaseException, value)
            self._value = cast(_T, value)
        return cast(_T, self._value)


class Background(Generic[_I, _E, _T]):
    """``take(item)`` for every item ``put``, then ``end(last)`` for the result: in a forked process
    that takes the items as they come (``background``), else here, at once. The process is forked
    at construction, so it holds what the caller held then. Items are pickled by ``put`` (what
    cannot cross raises there) and written by a thread, so ``put`` does not wait for the process.
    The process is a daemon that ``stop`` ends, and so does the caller's exit, or its death: each
    process closes the pipes' ends it does not use, so the other one reads the end of its pipe."""

    def __init__(
        self, take: Callable[[_I], object], end: Callable[[_E], _T], background: bool = False
    ) -> None:
        self._take, self._end = take, end
        self._process: BaseProcess | None = None
        if not (background and can_fork()):
            return
        context = multiprocessing.get_context("fork")
        inbox, self._inbox = context.Pipe(duplex=False)
        self._receive, send = context.Pipe(duplex=False)
        self._process = context.Process(
            target=_serve, args=(take, end, inbox, send, (self._inbox, self._receive)), daemon=True
        )
        self._process.start()
        inbox.close()
        send.close()
        self._outbox: queue.SimpleQueue[bytes | None] = queue.SimpleQueue()
        threading.Thread(target=_feed, args=(self._outbox, self._inbox), daemon=True).start()

    def put(self, item: _I) -> None:
        if self._process is None:
            self._take(item)
        else:
            self._send((False, item))

    def end(self, last: _E) -> Later[_T]:
        if self._process is None:
            return Later.now(self._end(last))
        self._send((True, last))
        self._outbox.put(None)  # the feeder closes the pipe once it has written everything
        return Later._from(self._process, self._receive)

    def _send(self, message: tuple[bool, object]) -> None:
        try:
            self._outbox.put(bytes(ForkingPickler.dumps(message)))
        except BaseException:
            self.stop()
            raise

    def stop(self) -> None:
        if self._process is not None:
            _stop(self._process)
            self._outbox.put(None)
            self._receive.close()


def _feed(outbox: "queue.SimpleQueue[bytes | None]", pipe: Connection) -> None:
    """The feeder thread: the pickled items down the pipe, in order, until None; a process that
    died stops it (``Later.get`` says so)."""
    try:
        while (data := outbox.get()) is not None:
            pipe.send_bytes(data)
    except OSError:
        pass
    finally:
        pipe.close()


def _stop(process: BaseProcess) -> None:
    if process.exitcode is None:
        process.terminate()
        process.join()


def _serve(
    take: Callable[[object], object],
    end: Callable[[object], object],
    inbox: Connection,
    send: Connection,
    parents: tuple[Connection, ...],
) -> None:
    """In the child: every item to ``take``, then ``end``'s result (or what was raised) down the
    pipe. The parent's ends are closed first: its death ends the inbox."""
    for connection in parents:
        connection.close()
    try:
        while True:
            last, item = ForkingPickler.loads(inbox.recv_bytes())
            if last:
                message: tuple[bool, object] = (True, end(item))
                break
            take(item)
    except BaseException as error:
        message = (False, error)
    try:
        send.send(message)
    except BrokenPipeError:
        pass  # the parent is gone
    except Exception as error:  # an unpicklable result or error
        send.send((False, RuntimeError(f"the background result could not be sent: {error!r}")))
    finally:
        send.close()
