"""Work in a forked process (``app.gap.forked``): the same result as here, what it raises raised
here, nothing left running."""

import multiprocessing
import os
import signal
import threading
from types import MappingProxyType

import pytest

from app.gap.forked import Background, Later, can_fork, map_forked

pytestmark = pytest.mark.skipif(not can_fork(), reason="the platform cannot fork: the work runs here")
PARENT = os.getpid()


class Tally:
    """Items taken one by one; the end says what it saw, and in which process."""

    def __init__(self) -> None:
        self.items: list[int] = []

    def take(self, item: int) -> None:
        self.items.append(item)

    def end(self, last: int) -> tuple[list[int], int, int]:
        return [*self.items, last], os.getpid(), sum(self.items)


def _run(background: bool) -> tuple[list[int], int, int]:
    tally = Tally()
    work = Background(tally.take, tally.end, background)
    for k in range(1000):
        work.put(k)
    later = work.end(-1)
    tally.items.append(10**9)  # after the fork: the child's copy never sees it
    return later.get()


def test_the_background_takes_every_item_in_order_in_another_process() -> None:
    here, there = _run(background=False), _run(background=True)
    assert here[0] == there[0] == [*range(1000), -1]
    assert here[2] == there[2] == sum(range(1000))
    assert here[1] == os.getpid() and there[1] != os.getpid()


def test_what_the_background_raises_is_raised_by_get() -> None:
    def take(item: int) -> None:
        if item == 3:
            raise ValueError("item 3 is bad")

    later = _filled(Background(take, lambda last: last, background=True), 5)
    with pytest.raises(ValueError, match="item 3 is bad"):
        later.get()


def test_an_item_that_cannot_cross_raises_at_once_and_stops_the_process() -> None:
    work: Background[object, None, None] = Background(lambda item: None, lambda last: None, background=True)
    with pytest.raises(Exception, match="pickle"):
        work.put(threading.Lock())
    assert not _children()


def test_a_background_that_dies_says_so() -> None:
    def take(item: int) -> None:
        os.kill(os.getpid(), signal.SIGKILL)

    later = _filled(Background(take, lambda last: last, background=True), 1)
    with pytest.raises(RuntimeError, match=f"exit code {-signal.SIGKILL} and no result"):
        later.get()


def test_a_result_dropped_unasked_stops_its_process() -> None:
    gate = multiprocessing.get_context("fork").Event()
    work = Background(lambda item: gate.wait(), lambda last: last, background=True)
    later = _filled(work, 1)
    assert _children()
    del later, work
    assert not _children()


def test_read_only_views_cross_as_read_only_views() -> None:
    view = MappingProxyType({"vx": 1.5})
    got = _filled(Background(lambda item: None, lambda last: last, background=True), 0, last=view).get()
    assert got == view and isinstance(got, MappingProxyType)


def test_map_forked_is_the_loop_here() -> None:
    assert map_forked(lambda i: (i * i, os.getpid() != PARENT), 7, workers=2) == [
        (i * i, True) for i in range(7)
    ]
    assert map_forked(lambda i: (i * i, os.getpid() != PARENT), 7, workers=1) == [
        (i * i, False) for i in range(7)
    ]


def _filled(work: Background, n: int, last: object = None) -> Later:  # type: ignore[type-arg]
    for k in range(n):
        work.put(k)
    return work.end(last)


def _children() -> list[multiprocessing.process.BaseProcess]:
    return [p for p in multiprocessing.active_children() if p.is_alive()]
