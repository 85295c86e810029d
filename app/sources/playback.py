"""Replay with the recorded timing, like canplayer: pacing and looping of a message stream.

The clock and the sleep are parameters, so tests pace without real waiting.
"""

import math
import time
from collections.abc import Callable, Iterable, Iterator

import can


def paced(
    messages: Iterable[can.Message],
    rate: float = 1.0,
    clock: Callable[[], float] = time.perf_counter,
    sleep: Callable[[float], None] = time.sleep,
    max_wait_s: float = 5.0,
) -> Iterator[can.Message]:
    """Yield each message when its recorded time comes, ``rate`` times faster than recorded.

    Gaps longer than ``max_wait_s`` (in playback time) are shortened to it, like python-can's
    MessageSync ``skip``; where the time goes back (a logger's clock set back, two logs joined)
    the frames go on from there at their own pace, not all at once until their time catches up.
    A frame without a finite time goes out at once and moves no clock.
    """
    if rate <= 0:
        raise ValueError("rate must be > 0")
    start_wall: float | None = None
    start_log = 0.0
    skipped = 0.0
    previous = None
    for message in messages:
        if not math.isfinite(message.timestamp):
            yield message
            continue
        if start_wall is None:
            start_wall, start_log = clock(), message.timestamp
        else:
            gap = (message.timestamp - previous) / rate if previous is not None else 0.0
            if gap > max_wait_s:
                skipped += gap - max_wait_s
            elif gap < 0.0:  # the clock went back: on from the last frame's moment
                skipped += gap
        previous = message.timestamp
        due = start_wall + (message.timestamp - start_log) / rate - skipped
        wait = due - clock()
        if wait > 0:
            sleep(wait)
        yield message


def looped(read: Callable[[], Iterable[can.Message]], loops: int | None) -> Iterator[can.Message]:
    """Repeat a recording ``loops`` times (None: forever), shifting timestamps so they keep rising."""
    offset = 0.0
    count = 0
    while loops is None or count < loops:
        first = last = None
        for message in read():
            if first is None:
                first = message.timestamp
            last = message.timestamp
            if offset:
                message.timestamp += offset
            yield message
        if first is None or last is None:
            return
        offset += (last - first) + 0.01
        count += 1


def drive_time(messages: Iterable[can.Message | None], rate: float) -> Iterator[can.Message | None]:
    """A drive replayed ``rate`` times faster than it was driven, given its own time back: each
    frame's time is stretched by ``rate`` from the first frame's (None, a quiet moment, passes)."""
    if rate <= 0:
        raise ValueError("rate must be > 0")
    start: float | None = None
    for message in messages:
        if message is not None:
            if start is None:
                start = message.timestamp
            message.timestamp = start + (message.timestamp - start) * rate
        yield message
