"""Frames from live buses: opened through python-can, read in arrival order, and reopened with
back-off when one goes away while the session goes on.

A source is an iterable of ``can.Message``. Library errors become one-line BusErrors here, at the
edge.
"""

import errno
import logging
import queue
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any

import can

from app.errors import BusError, C2nError, one_line
from app.sources.bus_health import BusHealth

log = logging.getLogger(__name__)


def open_buses(
    interface: str | None, channels: Sequence[str | int | None], bitrate: int | None, **kwargs: Any
) -> list[can.BusABC]:
    """Open one python-can bus per channel. None values fall back to python-can's config file and
    CAN_INTERFACE / CAN_CHANNEL / CAN_BITRATE."""
    buses: list[can.BusABC] = []
    options = dict(kwargs)
    if bitrate is not None:
        options["bitrate"] = bitrate
    for channel in channels or [None]:
        try:
            buses.append(can.Bus(interface=interface, channel=channel, **options))
        except Exception as error:
            for bus in buses:
                bus.shutdown()
            named = channel if channel is not None else "(default channel)"
            where = f"{interface or 'default interface'} {named}"
            hint = _bus_hint(interface, channel, error)
            raise BusError(f"{where}: cannot open ({one_line(error)}) — {hint}") from error
    return buses


def _bus_hint(interface: str | None, channel: object, error: BaseException) -> str:
    """What to do, by what the operating system said (SocketCAN's errno)."""
    if interface is None:
        return "give -i/-c, or set CAN_INTERFACE and CAN_CHANNEL, or write ~/can.conf"
    if interface != "socketcan":
        return "check the interface name, channel and driver"
    name = str(channel) if channel is not None else "can0"
    virtual = name.startswith("vcan")
    code = _errno(error)
    if code == errno.EAFNOSUPPORT:  # no CAN in the kernel
        return f"this kernel has no CAN support loaded: sudo modprobe can can_raw{' vcan' if virtual else ''}"
    if code == errno.ENODEV:  # no such interface
        if virtual:
            return f"no such device: sudo ip link add dev {name} type vcan && sudo ip link set up {name}"
        return f"no such device: is the adapter plugged in and its driver loaded? (ip link show {name})"
    if code == errno.ENETDOWN:
        if virtual:
            return f"it is down: sudo ip link set up {name}"
        return f"it is down: sudo ip link set {name} up type can bitrate 500000 (the bus's bit rate)"
    return f"check the interface (ip -details link show {name})"


def _errno(error: BaseException) -> int | None:
    """The OS error number behind a python-can error, if there is one."""
    seen: BaseException | None = error
    while seen is not None:
        if isinstance(seen, OSError) and seen.errno is not None:
            return seen.errno
        code = getattr(seen, "error_code", None)
        if isinstance(code, int):
            return code
        seen = seen.__cause__ or seen.__context__
    return None


@dataclass(frozen=True)
class _Failure:
    """A bus's receive thread failed (cable pulled, interface gone, driver error)."""

    bus: can.BusABC
    error: BaseException


class _Forward(can.Listener):
    """Puts a bus's frames on the shared queue, naming the channel if the interface did not."""

    def __init__(self, out: "queue.SimpleQueue[can.Message | _Failure]", bus: can.BusABC) -> None:
        self.out = out
        self.bus = bus
        self.channel = bus.channel_info

    def on_message_received(self, msg: can.Message) -> None:
        if msg.channel is None:
            msg.channel = self.channel
        self.out.put(msg)

    def on_error(self, exc: Exception) -> None:
        self.out.put(_Failure(self.bus, exc))


@dataclass(frozen=True)
class Backoff:
    """Waits between attempts to reopen a lost bus: ``first_s``, doubling up to ``max_s``."""

    first_s: float = 0.5
    max_s: float = 5.0

    def delay_s(self, failed_attempts: int) -> float:
        return float(min(self.first_s * 2.0**failed_attempts, self.max_s))


@dataclass
class _Lost:
    since: float
    retry_at: float
    failed_attempts: int = 0


# At most this long reading what the buses hold after a stop: a reader behind its bus catches up
# at its own speed (100,000 frames/s, tools/bench.py: 10 s is a minute of a saturated 1 Mbit/s bus),
# well inside the 90 s a shutdown (systemd) waits after its SIGTERM. Only a bus sending faster
# than the reader can keep it reading that long; what it still holds then is said to be lost.
_DRAIN_S = 10.0
_SAY_S = 1.0  # a stop still reading after this long says so: a screen silent for longer looks hung


class BusSource:
    """Frames from one or more live buses in arrival order.

    Iterating yields a message, or None after ``idle_s`` without one (so the caller can redraw
    and flush the recording). It ends when ``stop`` is set, once it has given the frames that
    arrived before (``_drained``), or once the buses fall quiet after ``finished`` is set (a player
    that has sent everything).

    A bus that fails ends it with BusError, unless ``reopen`` is given (index → a new bus for
    that channel): then the lost bus is closed, None is yielded at once, and reopening is tried
    after ``backoff`` delays on ``clock`` until it works; the other buses go on meanwhile.
    ``on_change`` hears each loss, failed attempt and return as one line.
    """

    def __init__(
        self,
        buses: Sequence[can.BusABC],
        stop: threading.Event,
        finished: threading.Event | None = None,
        idle_s: float = 0.05,
        reopen: Callable[[int], can.BusABC] | None = None,
        backoff: Backoff = Backoff(),
        clock: Callable[[], float] = time.monotonic,
        on_change: Callable[[str], None] | None = None,
        hurry: threading.Event | None = None,
    ) -> None:
        self.buses = list(buses)
        self.stop = stop
        self.hurry = hurry or threading.Event()  # set: the stop reads no more of what waits
        self.finished = finished
        self.idle_s = idle_s
        self.reopen = reopen
        self.backoff = backoff
        self.clock = clock
        self.on_change = on_change or (lambda text: None)
        self.names = [str(bus.channel_info) for bus in self.buses]
        self.lost: dict[int, _Lost] = {}
        self.losses: list[str] = []  # one line per time a bus went away or bus-off, for the summary
        self.health = BusHealth()
        self._queue: queue.SimpleQueue[can.Message | _Failure] = queue.SimpleQueue()
        self._notifiers: dict[int, can.Notifier] = {}

    @property
    def problem(self) -> str | None:
        """Which buses are lost, bus-off or error-passive, for the dashboard (None while all are well)."""
        if not self.lost and not self.health.troubled:
            return None
        now = self.clock()
        lost = [
            f"{self.names[i]} lost for {now - lost.since:.0f} s, "
            f"next try in {max(lost.retry_at - now, 0.0):.1f} s"
            for i, lost in sorted(self.lost.items())
        ]
        return "; ".join(lost + self.health.problems(now))

    def _check_health(self, msg: can.Message) -> None:
        line = self.health.see(msg, self.clock())
        if line is not None:
            if str(msg.channel) in self.health.troubled:  # a new trouble, not a return
                self.losses.append(line.partition(" — ")[0])
            self.on_change(line)

    def __iter__(self) -> Iterator[can.Message | None]:
        """One bus is read in the caller's thread: no hand-off between threads per frame, which
        would cost more than decoding it (tools/bench.py). Several buses get a receive thread
        each, feeding one queue."""
        return self._read_one() if len(self.buses) == 1 else self._read_queued()

    def _read_queued(self) -> Iterator[can.Message | None]:
        try:
            for index in range(len(self.buses)):
                self._listen(index)
            stop, health = self.stop, self.health
            while not stop.is_set():
                if self.lost:
                    self._retry(self.clock())
                item = self._receive_queued()
                if item is None:
                    if self.finished is not None and self.finished.is_set():
                        return
                    yield None
                    continue
                if isinstance(item, _Failure):
                    if self._lose(item):
                        yield None  # the caller flushes the recording now
                    continue
                if item.is_error_frame or health.troubled:
                    self._check_health(item)
                yield item
            self.close()  # the receive threads end; what they and the buses hold is the session's
            yield from self._drained()
        finally:
            self.close()

    def _receive_queued(self) -> "can.Message | _Failure | None":
        try:
            return self._queue.get(timeout=self.idle_s)
        except queue.Empty:
            return None

    def _read_one(self) -> Iterator[can.Message | None]:
        """``__iter__`` for one bus, read in this thread. While frames keep coming, each costs
        its ``recv`` and a few checks (tools/bench.py, live throughput)."""
        stop, health, idle_s = self.stop, self.health, self.idle_s
        try:
            while not stop.is_set():
                if self.lost:
                    self._retry(self.clock(), listen=False)
                if self.lost:  # the only bus is away: wait for the next attempt
                    time.sleep(max(0.0, min(idle_s, self.lost[0].retry_at - self.clock())))
                    if self.finished is not None and self.finished.is_set():
                        return
                    yield None
                    continue
                bus = self.buses[0]
                recv, channel = bus.recv, bus.channel_info
                while True:
                    try:
                        msg = recv(idle_s)
                    except Exception as error:  # what a receive thread would report to its listener
                        if self._lose(_Failure(bus, error)):
                            yield None  # the caller flushes the recording now
                        break
                    if msg is None:
                        if self.finished is not None and self.finished.is_set():
                            return
                        yield None
                        break
                    if msg.channel is None:
                        msg.channel = channel
                    if msg.is_error_frame or health.troubled:
                        self._check_health(msg)
                    yield msg
                    if stop.is_set():
                        break
            yield from self._drained()
        finally:
            self.close()

    def _drained(self) -> Iterator[can.Message]:
        """What is left when the session is stopped: the frames that arrived before the stop and
        wait unread (a reader behind its bus holds seconds of them), from the receive threads'
        queue and then each bus, until they are empty — for ``_DRAIN_S`` at most, where a bus
        goes on sending after the stop; then what it holds is not read, and ``losses`` says so."""
        deadline = time.monotonic() + _DRAIN_S
        last: float | None = None
        say = self._saying_at(self.clock() + _SAY_S)
        while True:
            if time.monotonic() >= deadline or self.hurry.is_set():
                self._left_unread(last)
                return
            say()
            try:
                item = self._queue.get_nowait()
            except queue.Empty:
                break
            if not isinstance(item, _Failure):
                last = item.timestamp
                yield item
        for index, bus in enumerate(self.buses):
            while index not in self.lost:
                if time.monotonic() >= deadline or self.hurry.is_set():
                    self._left_unread(last)
                    return
                say()
                try:
                    msg = bus.recv(0.0)
                except Exception:  # a bus that fails now: the session has ended anyway
                    break
                if msg is None:
                    break
                if msg.channel is None:
                    msg.channel = bus.channel_info
                last = msg.timestamp
                yield msg

    def _saying_at(self, when: float) -> Callable[[], None]:
        """A check, made at each frame the stop reads, that says once, from ``when`` on, that the
        session is stopping: a reader far behind its bus reads for seconds after Ctrl-C, and a
        user who sees nothing happen presses it again and loses what waits."""
        said = False

        def say() -> None:
            nonlocal said
            if not said and self.clock() >= when:
                said = True
                self.on_change(
                    f"stopping: reading the frames that arrived before the stop (for {_DRAIN_S:g} s "
                    "at most) — Ctrl-C again ends the session now, without them"
                )

        return say

    def _left_unread(self, last: float | None) -> None:
        after = f" (after the frame at {last:.3f} s)" if last is not None else ""
        if self.hurry.is_set():
            self.losses.append(
                "a second Ctrl-C (or SIGTERM, SIGHUP) ended the stop before the buses were read "
                f"empty: what they still held{after} is not in the session"
            )
            return
        self.losses.append(
            f"the stop found the buses sending faster than c2n reads: after {_DRAIN_S:g} s of reading "
            f"what waited, the frames still held{after} are not in the session"
        )

    def _listen(self, index: int) -> None:
        bus = self.buses[index]
        self._notifiers[index] = can.Notifier(bus, [_Forward(self._queue, bus)], timeout=self.idle_s)

    def _lose(self, failure: _Failure) -> bool:
        """Close a failed bus and schedule its reopening; False for a stale report."""
        index = next((i for i, bus in enumerate(self.buses) if bus is failure.bus), None)
        if index is None or index in self.lost:
            return False  # the receive thread reported again before it was stopped
        name, reason = self.names[index], one_line(failure.error)
        if self.reopen is None:
            raise BusError(f"{name}: the bus failed ({reason})")
        notifier = self._notifiers.pop(index, None)
        if notifier is not None:
            notifier.stop(timeout=1.0)
        _shutdown(failure.bus)
        now = self.clock()
        delay = self.backoff.delay_s(0)
        self.lost[index] = _Lost(since=now, retry_at=now + delay)
        self.losses.append(f"{name}: the bus went away ({reason})")
        self.on_change(f"{self.losses[-1]} — recording kept, retrying in {delay:g} s")
        return True

    def _retry(self, now: float, listen: bool = True) -> None:
        if self.reopen is None:
            return
        for index, lost in list(self.lost.items()):
            if now < lost.retry_at:
                continue
            name = self.names[index]
            try:
                bus = self.reopen(index)
            except (C2nError, can.CanError, OSError) as error:
                lost.failed_attempts += 1
                delay = self.backoff.delay_s(lost.failed_attempts)
                lost.retry_at = now + delay
                self.on_change(f"{name}: still gone ({one_line(error)}) — retrying in {delay:g} s")
                continue
            self.buses[index] = bus
            del self.lost[index]
            if listen:
                self._listen(index)
            self.on_change(f"{name}: the bus is back after {now - lost.since:.1f} s — measuring again")

    def close(self) -> None:
        for notifier in self._notifiers.values():
            notifier.stop(timeout=1.0)
        self._notifiers.clear()


def _shutdown(bus: can.BusABC) -> None:
    try:
        bus.shutdown()
    except (can.CanError, OSError) as error:  # it is already gone
        log.debug("closing a failed bus: %s", error)
