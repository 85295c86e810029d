"""Frames in, role values out: cantools decoding and role mapping, gated by the sensor status and
counted by what each frame was.

Malformed frames are data, not exceptions: every frame is counted by what it was, and only
values that are fit to use reach the pipeline.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import can
import numpy as np

from app.config import Config, RoleSpec
from app.dbc import ChannelSpec, channel_matches
from app.decode.bits import ColumnReader, Reader, column_reader, signal_reader
from app.decode.counts import FrameCounts
from app.decode.status import SensorStatus
from app.records import Record
from app.sources.blocks import FrameBlock, RecordBlock, key_codes

_MAX_ROUTES = 65_536  # (channel, id) keys whose route is remembered
_MAX_SEEN = 4096  # keys whose frames are tallied: each read of the counts goes over them all


@dataclass(frozen=True)
class _RoleBinding:
    role: str
    signal: str
    factor: float
    low: float  # SI range from the DBC's minimum/maximum
    high: float
    channel: ChannelSpec | None


@dataclass(frozen=True)
class _MessageBinding:
    message: Any  # cantools Message
    channel: ChannelSpec | None
    roles: tuple[_RoleBinding, ...]
    status: tuple[tuple[str, str], ...]  # status signals in this message: ("Message.Signal", "Signal")
    read: Reader | None  # the needed signals' values from a frame's data (None: nothing needed)
    columns: ColumnReader | None  # the same from many frames' data at once, where it can
    roles_by_channel: dict[object, tuple[_RoleBinding, ...]] = field(default_factory=dict)

    @property
    def needed(self) -> bool:
        return bool(self.roles or self.status)

    def roles_on(self, channel: object) -> tuple[_RoleBinding, ...]:
        """The roles this message gives on a frame's channel (worked out once per channel)."""
        roles = self.roles_by_channel.get(channel)
        if roles is None:
            roles = tuple(role for role in self.roles if channel_matches(role.channel, channel))
            if len(self.roles_by_channel) < 64:  # a log of many channel names must not grow it
                self.roles_by_channel[channel] = roles
        return roles


class Decoder:
    """Turns python-can messages into Records, counting every frame.

    The first data frame of a key (channel, id, extended) works out where its key goes; later
    ones are tallied per key and the tallies are added to the counts whenever they are read, so
    ``counts`` is exact at every read and a frame nothing needs costs a lookup and an addition
    (tools/bench.py, ``decode, background frame``).
    """

    def __init__(self, config: Config) -> None:
        self._counts = FrameCounts()
        self._seen: dict[tuple[object, int, bool], _Seen] = {}
        self.status = SensorStatus(config.status, config.filter.status_timeout_s)
        self._bindings: dict[tuple[int, bool], list[_MessageBinding]] = {}
        self._routes: dict[tuple[object, int, bool], _MessageBinding | str] = {}
        status_names = {c.name for c in config.status}
        for dbc in config.dbcs:
            for message in dbc.database.messages:
                roles = tuple(
                    _bind_role(spec, message)
                    for spec in config.roles.values()
                    if spec.message == message.name
                )
                status = tuple(
                    (f"{message.name}.{s.name}", s.name)
                    for s in message.signals
                    if f"{message.name}.{s.name}" in status_names
                )
                key = (message.frame_id, bool(message.is_extended_frame))
                needed = [role.signal for role in roles] + [signal for _, signal in status]
                names = list(dict.fromkeys(needed))
                read = signal_reader(message, names) if needed else None
                columns = column_reader(message, names) if needed else None
                self._bindings.setdefault(key, []).append(
                    _MessageBinding(message, dbc.channel, roles, status, read, columns)
                )
        # (id, extended) -> the DBC's message name (the first DBC's, if several define it)
        self.message_names: Mapping[tuple[int, bool], str] = MappingProxyType(
            {key: str(bindings[0].message.name) for key, bindings in self._bindings.items()}
        )

    @property
    def counts(self) -> FrameCounts:
        """What every frame so far was."""
        for key, seen in self._seen.items():
            if seen.frames or seen.used:
                self._add(key, seen)
        return self._counts

    def skip_kind(self, channel: object, frame_id: int, extended: bool) -> str | None:
        """For a data frame of this key: the count it goes to when nothing in it is needed
        (``unknown_id``, ``other_channel``, ``unused``: what ``decode`` would count it as), or
        None when it must be decoded. For readers that count such frames in bulk."""
        route = self._route((channel, frame_id, extended))
        return route if isinstance(route, str) else None

    def _route(self, key: tuple[object, int, bool]) -> "_MessageBinding | str":
        """Where a data frame of this (channel, id, extended) goes: its binding, or the count
        it adds to. Worked out once per key."""
        route = self._routes.get(key)
        if route is not None:
            return route
        channel, frame_id, extended = key
        candidates = self._bindings.get((frame_id, bool(extended)))
        if candidates is None:
            route = "unknown_id"
        else:
            binding = next((b for b in candidates if channel_matches(b.channel, channel)), None)
            route = "other_channel" if binding is None else binding if binding.needed else "unused"
        if len(self._routes) < _MAX_ROUTES:  # a bus of random ids must not grow it without bound
            self._routes[key] = route
        return route

    def count_skipped(
        self, channel: object, frame_id: int, extended: bool, kind: str, frames: int, fd_frames: int
    ) -> None:
        """Count ``frames`` data frames of one key that ``skip_kind`` sent to ``kind``, as
        ``decode`` would have counted them one by one."""
        counts = self._counts
        counts.total += frames
        counts.by_id[(channel, frame_id, extended)] += frames
        counts.fd_frames += fd_frames
        setattr(counts, kind, getattr(counts, kind) + frames)

    def decode(self, msg: can.Message) -> Record | None:
        """Count the frame; return a Record when it carries role values (usable or not)."""
        key = (msg.channel, msg.arbitration_id, msg.is_extended_id)
        seen = self._seen.get(key)
        if seen is None or msg.is_error_frame or msg.is_remote_frame:
            return self._decode_first(msg, key)
        seen.frames += 1
        if msg.is_fd:
            seen.fd_frames += 1
        binding = seen.binding
        return None if binding is None else self._read(binding, seen, msg)

    def _decode_first(self, msg: can.Message, key: tuple[object, int, bool]) -> Record | None:
        """A frame of a key not seen yet, an error or a remote frame: counted here, and the
        data frame's key learned for the tallies."""
        counts = self._counts
        counts.total += 1
        counts.by_id[key] += 1
        if msg.is_fd:
            counts.fd_frames += 1
        if msg.is_error_frame:
            counts.error_frames += 1
            return None
        if msg.is_remote_frame:
            counts.remote_frames += 1
            return None
        route = self._route(key)
        if isinstance(route, str):
            setattr(counts, route, getattr(counts, route) + 1)
            if len(self._seen) < _MAX_SEEN:
                self._seen[key] = _Seen(route, None, ())
            return None
        seen = _Seen(None, route, route.roles_on(msg.channel))
        record = self._read(route, seen, msg)
        if len(self._seen) < _MAX_SEEN:
            self._seen[key] = seen
        else:  # a bus of random ids must not make every read of the counts long: count it now
            self._add(key, seen)
        return record

    def _read(self, binding: "_MessageBinding", seen: "_Seen", msg: can.Message) -> Record | None:
        """The role values of a data frame of a needed message."""
        counts = self._counts
        data = msg.data
        length = binding.message.length
        if len(data) != length or msg.dlc != length:  # a text log's line cut in its data: dlc ≠ bytes
            counts.bad_length += 1
            kind = "cut" if msg.dlc != len(data) else "short" if len(data) < length else "long"
            counts.bad_by_id[(msg.arbitration_id, kind)] += 1
            return None
        try:
            decoded = binding.read(data)  # type: ignore[misc]  # a needed binding reads
        except Exception:
            counts.undecodable += 1
            counts.bad_by_id[(msg.arbitration_id, "undecodable")] += 1
            return None
        t = msg.timestamp
        if not -1e15 < t < 1e15:  # NaN or infinite (a text log's): no place in time
            counts.bad_time += 1
            return None
        if binding.status:
            self.status.update(t, {name: float(decoded[signal]) for name, signal in binding.status})
        roles = seen.roles
        if not roles and not binding.status:
            counts.other_channel += 1  # its roles are bound to another channel
            return None
        seen.used += 1
        signals: dict[str, float] = {}
        rejected: dict[str, str] = {}
        isfinite, why_not = math.isfinite, self.status.why_not
        for role in roles:
            value = float(decoded[role.signal]) * role.factor
            if not isfinite(value):
                rejected[role.role] = "not a number"
            elif not role.low <= value <= role.high:
                rejected[role.role] = "out of range"
            else:
                reason = why_not(role.role, t)
                if reason is None:
                    signals[role.role] = value
                else:
                    rejected[role.role] = reason
        if rejected:
            self._count_rejected(rejected)
        elif not signals:
            return None
        return Record(t, msg.channel, msg.arbitration_id, signals, rejected)

    def _count_rejected(self, rejected: dict[str, str]) -> None:
        for reason in dict.fromkeys(rejected.values()):
            names = ", ".join(r for r, why in rejected.items() if why == reason)
            self._counts.rejected[f"{reason} ({names})"] += 1

    def decode_block(self, block: FrameBlock) -> RecordBlock:
        """``decode`` over a block of frames at once: the same counts, and the Records ``decode``
        would give one by one, as columns. The signals are read per message as columns; the
        sensor status is applied in arrival order (tests/test_blocks.py holds the two equal)."""
        counts, n = self._counts, len(block)
        order, starts, firsts = _by_key(block)
        carried: dict[str, np.ndarray] = {}  # role -> value, NaN where the frame has none
        checked: dict[str, np.ndarray] = {}  # role -> why not usable: 0 fine, else a _Reasons code
        roles_of: list[tuple[_RoleBinding, ...] | None] = [None] * n  # rows that make a Record
        status_rows: list[tuple[np.ndarray, dict[str, np.ndarray]]] = []
        reasons = _Reasons()
        for first, rows in zip(firsts, np.split(order, starts), strict=True):
            key_channel = block.channel[first].item() if block.channel is not None else None
            frame_id, extended = int(block.frame_id[first]), bool(block.extended[first])
            key = (key_channel, frame_id, extended)
            counts.total += len(rows)
            counts.by_id[key] += len(rows)
            counts.fd_frames += int(np.count_nonzero(block.fd[rows]))
            route = self._route(key)
            if isinstance(route, str):  # a reader that passes frames nothing needs
                setattr(counts, route, getattr(counts, route) + len(rows))
                continue
            rows, decoded = self._read_columns(route, frame_id, rows, block)
            if route.status:
                status_rows.append((rows, {name: decoded[signal] for name, signal in route.status}))
            roles = route.roles_on(key_channel)
            if not roles and not route.status:
                counts.other_channel += len(rows)
                continue
            counts.used += len(rows)
            for role in roles:
                counts.role_frames[role.role] += len(rows)
                value = decoded[role.signal] * role.factor
                column = carried.setdefault(role.role, np.full(n, np.nan))
                column[rows] = value
                why = checked.setdefault(role.role, np.zeros(n, np.int64))
                finite = np.isfinite(value)
                why[rows] = np.where(
                    ~finite,
                    reasons.code("not a number"),
                    np.where((role.low <= value) & (value <= role.high), 0, reasons.code("out of range")),
                )
            if roles:
                for row in rows.tolist():
                    roles_of[row] = roles
        self._apply_status(block.t, status_rows, carried, checked, reasons)
        return self._records(block, carried, checked, roles_of, reasons)

    def _read_columns(
        self, binding: "_MessageBinding", frame_id: int, rows: np.ndarray, block: FrameBlock
    ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """The rows of one key that ``_read`` would read (bad lengths and undecodable frames
        counted and left out), and the needed signals' columns at them."""
        counts, length = self._counts, binding.message.length
        lengths = block.length[rows]
        bad = lengths != length
        if bad.any():
            short = int(np.count_nonzero(lengths[bad] < length))
            counts.bad_length += int(np.count_nonzero(bad))
            for kind, frames in (("short", short), ("long", int(np.count_nonzero(bad)) - short)):
                if frames:
                    counts.bad_by_id[(frame_id, kind)] += frames
            rows = rows[~bad]
        if binding.columns is not None and block.data.shape[1] >= length:
            return rows, binding.columns(block.data[rows])
        read: Reader = binding.read  # type: ignore[assignment]  # a needed binding reads
        good, values = [], []
        for row in rows.tolist():
            try:
                values.append(read(block.data[row, :length].tobytes()))
            except Exception:
                counts.undecodable += 1
                counts.bad_by_id[(frame_id, "undecodable")] += 1
                continue
            good.append(row)
        names = [role.signal for role in binding.roles] + [signal for _, signal in binding.status]
        columns = {name: np.array([float(v[name]) for v in values]) for name in names}
        return np.array(good, np.int64), columns

    def _apply_status(
        self,
        t: np.ndarray,
        status_rows: list[tuple[np.ndarray, dict[str, np.ndarray]]],
        carried: dict[str, np.ndarray],
        checked: dict[str, np.ndarray],
        reasons: "_Reasons",
    ) -> None:
        """Update the sensor status with the block's status frames in arrival order, and mark
        each role value that ``SensorStatus.why_not`` would drop at its frame."""
        status = self.status
        roles = [role for role in checked if status.applies(role)]
        event_rows, changes = _status_changes(status_rows, status.values)
        # verdicts[k]: each role's verdict after k status frames; times[k]: that status's time
        verdicts = np.zeros((len(event_rows) + 1, len(roles)), np.int64)
        times = np.full(len(event_rows) + 1, np.nan)
        if status.t is None:
            verdicts[0] = reasons.code("no sensor status yet")
        else:
            times[0] = status.t
            verdicts[0] = [reasons.code(status.why_not(role, status.t)) for role in roles]
        times[1:] = t[event_rows]
        for k, update in changes.items():
            status.update(float(times[k]), update)
            verdicts[k] = [reasons.code(status.why_not(role, float(times[k]))) for role in roles]
        # a frame that changes no value leaves the verdicts as the frame before it left them
        source = np.zeros(len(verdicts), np.int64)
        source[list(changes)] = list(changes)
        verdicts = verdicts[np.maximum.accumulate(source)]
        if len(event_rows):
            status.t = float(times[-1])  # the last frame's time, whatever it changed
        stale = reasons.code(status.stale)
        for j, role in enumerate(roles):
            rows = np.flatnonzero((checked[role] == 0) & ~np.isnan(carried[role]))
            since = np.searchsorted(event_rows, rows, side="right")  # a frame's own status counts
            old = np.abs(t[rows] - times[since]) > status.timeout_s
            checked[role][rows] = np.where(old, stale, verdicts[since, j])

    def _records(
        self,
        block: FrameBlock,
        carried: dict[str, np.ndarray],
        checked: dict[str, np.ndarray],
        roles_of: "list[tuple[_RoleBinding, ...] | None]",
        reasons: "_Reasons",
    ) -> RecordBlock:
        """The rows ``_read`` makes a Record of, with their usable values and rejections."""
        n = len(block)
        usable, dropped = np.zeros(n, bool), np.zeros(n, bool)
        for role, why in checked.items():
            usable |= (why == 0) & ~np.isnan(carried[role])
            dropped |= why != 0
        keep = np.array([roles is not None for roles in roles_of], bool) & (usable | dropped)
        index = np.cumsum(keep) - 1
        rejected: dict[int, dict[str, str]] = {}
        for row in np.flatnonzero(dropped & keep).tolist():
            codes = {binding.role: int(checked[binding.role][row]) for binding in roles_of[row] or ()}
            why_not = {role: reasons.texts[code] for role, code in codes.items() if code}
            self._count_rejected(why_not)
            rejected[int(index[row])] = why_not
        values = {
            role: np.where(checked[role] == 0, column, np.nan)[keep] for role, column in carried.items()
        }
        channel = block.channel[keep].tolist() if block.channel is not None else [None] * int(keep.sum())
        return RecordBlock(block.t[keep], channel, block.frame_id[keep].tolist(), values, rejected)

    def _add(self, key: tuple[object, int, bool], seen: "_Seen") -> None:
        """Add a key's tallies to the counts and start them again."""
        counts, frames, used = self._counts, seen.frames, seen.used
        if frames:
            counts.total += frames
            counts.by_id[key] += frames
            counts.fd_frames += seen.fd_frames
            if seen.kind is not None:
                setattr(counts, seen.kind, getattr(counts, seen.kind) + frames)
        if used:
            counts.used += used
            for role in seen.roles:
                counts.role_frames[role.role] += used
        seen.frames = seen.fd_frames = seen.used = 0


class _Seen:
    """A key whose route is known, and its frames not yet added to the counts: ``frames`` data
    frames after the first (``fd_frames`` of them CAN FD), each of kind ``kind`` when nothing
    in them is needed; ``used`` of them gave the roles ``roles`` (or a sensor status)."""

    __slots__ = ("binding", "fd_frames", "frames", "kind", "roles", "used")

    def __init__(
        self, kind: str | None, binding: "_MessageBinding | None", roles: "tuple[_RoleBinding, ...]"
    ) -> None:
        self.kind = kind
        self.binding = binding
        self.roles = roles
        self.frames = self.fd_frames = self.used = 0


class _Reasons:
    """Why a role value was dropped, as small integer codes (0: not dropped) for columns."""

    def __init__(self) -> None:
        self.texts: list[str] = [""]
        self._codes: dict[str | None, int] = {None: 0}

    def code(self, text: str | None) -> int:
        code = self._codes.get(text)
        if code is None:
            code = self._codes[text] = len(self.texts)
            self.texts.append(str(text))
        return code


def _status_changes(
    status_rows: list[tuple[np.ndarray, dict[str, np.ndarray]]], before: dict[str, float]
) -> tuple[np.ndarray, dict[int, dict[str, float]]]:
    """The status frames of a block in arrival order (their rows), and those that change a value
    the status holds: {k (1 for the first frame): its values}. A value compared with the one before
    it among frames of its message, the first with ``before`` (NaN is always a change). Messages
    that share a signal are taken as changing at every frame."""
    if not status_rows:
        return np.zeros(0, np.int64), {}
    rows = np.concatenate([r for r, _ in status_rows])
    order = np.argsort(rows, kind="stable")
    names = [name for _, values in status_rows for name in values]
    shared = len(names) != len(set(names))
    changed = []
    for r, values in status_rows:
        flags = np.zeros(len(r), bool)
        for name, column in values.items():
            previous = np.concatenate([[before.get(name, np.nan)], column[:-1]])
            flags |= ~(column == previous)
        changed.append(flags | shared)
    flags = np.concatenate(changed)[order]
    position = np.concatenate([np.arange(len(r)) for r, _ in status_rows])[order]
    group = np.concatenate([np.full(len(r), g) for g, (r, _) in enumerate(status_rows)])[order]
    changes = {
        k + 1: {name: float(column[i]) for name, column in status_rows[g][1].items()}
        for k, (i, g) in enumerate(zip(position.tolist(), group.tolist(), strict=True))
        if flags[k]
    }
    return rows[order], changes


def _by_key(block: FrameBlock) -> tuple[np.ndarray, np.ndarray, list[int]]:
    """The block's rows grouped by key (channel, id, extended), each group in arrival order:
    (rows, where each group after the first starts, a row of each group)."""
    keys = key_codes(block.channel, block.extended, block.frame_id)
    _, first, inverse, sizes = np.unique(keys, return_index=True, return_inverse=True, return_counts=True)
    return np.argsort(inverse, kind="stable"), np.cumsum(sizes)[:-1], first.tolist()


def _bind_role(spec: RoleSpec, message: Any) -> _RoleBinding:
    signal = message.get_signal_by_name(spec.signal)
    low, high = (-math.inf, math.inf)
    if _range_is_real(signal):
        a, b = signal.minimum * spec.factor, signal.maximum * spec.factor
        low, high = min(a, b), max(a, b)
    return _RoleBinding(spec.role, spec.signal, spec.factor, low, high, spec.channel)


def _range_is_real(signal: Any) -> bool:
    """A DBC's [min|max] is a validity range only if the signal's bits can reach beyond it;
    many DBCs carry placeholders such as [0|65535] on a signed signal, or [0|0]."""
    if signal.minimum is None or signal.maximum is None or not signal.minimum < signal.maximum:
        return False
    if signal.is_float:
        return True
    bits = signal.length
    raw_low, raw_high = (-(2 ** (bits - 1)), 2 ** (bits - 1) - 1) if signal.is_signed else (0, 2**bits - 1)
    ends = sorted((raw_low * signal.scale + signal.offset, raw_high * signal.scale + signal.offset))
    tolerance = abs(signal.scale)
    return bool(ends[0] - tolerance <= signal.minimum and signal.maximum <= ends[1] + tolerance)
