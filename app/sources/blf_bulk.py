"""BLF read without a Message for frames nobody needs, and with ``blocks`` without one for the
frames the pipeline decodes either.

python-can's BLFReader builds a Message for every object, with its timestamp worked out in
``Decimal``; most frames of a drive are of ids the pipeline never decodes. This reader is
python-can's, containers, compression and all, except for its object walk: a run of plain CAN
message objects (48 bytes each, header version 1: what loggers and python-can's writer write) is
read as one numpy array, and elsewhere an object's channel and id are read from their fixed
places. A frame the decoder does not need is counted by key and passed over. With ``blocks``, the
needed data frames of a run (up to 8 bytes) become FrameBlocks, their fields worked out with numpy
as python-can works them out (the timestamp to the same bit: ``_block``); every other object —
needed frames without ``blocks``, remote and error frames, CAN FD, anything else — is parsed by
python-can's own code into a Message, in file order. tests/test_log_bulk.py holds it to
python-can's reader frame for frame.
"""

import struct
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

import can
import numpy as np
from can.io.blf import (
    CAN_MESSAGE,
    CAN_MESSAGE2,
    CAN_MSG_EXT,
    OBJ_HEADER_BASE_STRUCT,
    OBJ_HEADER_V1_STRUCT,
    OBJ_HEADER_V2_STRUCT,
    REMOTE_FLAG,
    BLFParseError,
)

from app.sources.blocks import FrameBlock
from app.sources.triage import Triage

_CHANNEL_FLAGS_ID = struct.Struct("<HBxL")  # a CAN message object's channel, flags, (dlc), id
_V1_FRAME = struct.Struct("<4sHHLL16xHBxL")  # base header, v1 header, and those three fields
_HEADER_SIZE = {1: OBJ_HEADER_V1_STRUCT.size, 2: OBJ_HEADER_V2_STRUCT.size}
_CAN_MESSAGES = (CAN_MESSAGE, CAN_MESSAGE2)
_MAX_KINDS = 65_536  # (channel, id) pairs remembered: a log of random ids must not grow it
_UNKNOWN = object()
_RUN = np.dtype(  # a CAN message object with header version 1, as numpy reads a run of them
    [
        ("signature", "S4"),
        ("header_size", "<u2"),
        ("version", "<u2"),
        ("size", "<u4"),
        ("type", "<u4"),
        ("time_unit", "<u4"),  # the object header's flags: 1 for 10 µs, else 1 ns (python-can's rule)
        ("client", "<u2"),
        ("object_version", "<u2"),
        ("timestamp", "<u8"),
        ("channel", "<u2"),
        ("flags", "u1"),
        ("dlc", "u1"),
        ("id", "<u4"),
        ("data", "u1", (8,)),
    ]
)
_EXACT = 1 << 53  # raw timestamps below this are exact as floats: divided, rounded as Decimal rounds
_Item = can.Message | np.ndarray  # a Message, or a run's objects that go into a block


class TriagedBLFReader(can.BLFReader):
    """python-can's BLFReader that counts the frames ``triage`` does not need instead of
    yielding them; ``skipped`` hears how many frames each container had of those. With
    ``blocks``, the needed data frames of runs come as FrameBlocks, the other objects as
    python-can's Messages, in file order."""

    def __init__(
        self, path: Path, triage: Triage, skipped: Callable[[int], None], blocks: bool = False
    ) -> None:
        super().__init__(path)
        self.triage = triage
        self.skipped = skipped
        self.blocks = blocks
        self._kinds: dict[tuple[int, int], tuple[object, int, bool, str] | None] = {}

    def __iter__(self) -> Iterator[can.Message | FrameBlock]:  # type: ignore[override]  # blocks too
        return super().__iter__()

    def _parse_data(self, data: bytes) -> Iterator[can.Message | FrameBlock]:  # type: ignore[override]
        """The container's objects: the walk's Messages, and with ``blocks`` its run objects
        gathered into a FrameBlock, yielded before the next Message and before the walk stops
        (the container's end, or damage: every frame before it is given)."""
        if not self.blocks:
            yield from self._walk(data)  # type: ignore[misc]  # no blocks: Messages only
            return
        gathered: list[np.ndarray] = []
        try:
            for item in self._walk(data):
                if isinstance(item, np.ndarray):
                    gathered.append(item)
                    continue
                if gathered:
                    yield self._block(gathered)
                    gathered = []
                yield item
        except Exception:
            if gathered:
                yield self._block(gathered)
            raise
        if gathered:
            yield self._block(gathered)

    def _walk(self, data: bytes) -> Iterator[_Item]:
        """python-can's object walk (the same positions, the same end-of-container rule), with
        the frames nobody needs counted and skipped; the rest parsed by python-can, or with
        ``blocks`` a run's data frames given as its objects (``_needed``)."""
        parse = super()._parse_data
        unpack_header = OBJ_HEADER_BASE_STRUCT.unpack_from
        unpack_v1_frame = _V1_FRAME.unpack_from
        unpack_frame = _CHANNEL_FLAGS_ID.unpack_from
        skipped: Counter[tuple[int, int]] = Counter()
        max_pos = len(data)
        pos = 0
        try:
            while True:
                self._pos = pos
                if not data.startswith(b"LOBJ", pos):  # padding before the object
                    try:
                        pos = data.index(b"LOBJ", pos, pos + 8)
                    except ValueError as error:
                        if pos + 8 > max_pos:
                            return
                        raise BLFParseError("Could not find next object") from error
                if pos + _V1_FRAME.size <= max_pos:  # the usual object: a CAN message, header v1
                    _, _, version, obj_size, obj_type, channel, flags, can_id = unpack_v1_frame(data, pos)
                else:
                    _, _, version, obj_size, obj_type = unpack_header(data, pos)
                next_pos = pos + obj_size
                if next_pos > max_pos:
                    return  # the object continues in the next container
                if obj_size == _RUN.itemsize and version == 1 and obj_type in _CAN_MESSAGES:
                    run = self._run(data, pos, skipped)  # this object and the like after it
                    if run is not None:
                        end, objects, at = run
                        if self.blocks:
                            yield from self._needed(data, objects, at)
                        else:
                            for start in at.tolist():
                                yield from parse(data[start : start + _RUN.itemsize])
                        pos = end
                        continue
                if obj_type in _CAN_MESSAGES and version in _HEADER_SIZE:
                    if version != 1 or pos + _V1_FRAME.size > max_pos:
                        body = pos + OBJ_HEADER_BASE_STRUCT.size + _HEADER_SIZE[version]
                        channel, flags, can_id = unpack_frame(data, body)
                    if not flags & REMOTE_FLAG and self._kind(channel, can_id) is not None:
                        skipped[(channel, can_id)] += 1
                        pos = next_pos
                        continue
                yield from parse(data[pos:next_pos])
                pos = next_pos
        finally:
            self._count(skipped)

    def _run(
        self, data: bytes, pos: int, skipped: Counter[tuple[int, int]]
    ) -> tuple[int, np.ndarray, np.ndarray] | None:
        """A run of whole CAN message objects (header v1, no padding) from ``pos``, read as one
        numpy array: the frames nobody needs counted into ``skipped``. Returns where the run ends,
        its other objects and where they start (None for a run of one: the walk takes it)."""
        n = (len(data) - pos) // _RUN.itemsize
        if n < 2:
            return None
        objects = np.frombuffer(data, _RUN, count=n, offset=pos)
        alike = (
            (objects["signature"] == b"LOBJ")
            & (objects["size"] == _RUN.itemsize)
            & (objects["version"] == 1)
            & np.isin(objects["type"], _CAN_MESSAGES)
        )
        length = n if alike.all() else int(np.argmin(alike))
        if length < 2:
            return None
        objects = objects[:length]
        raw = (objects["channel"].astype(np.uint64) << np.uint64(32)) | objects["id"].astype(np.uint64)
        unique, inverse = np.unique(raw, return_inverse=True)
        skip = np.array(
            [self._kind(key >> 32, key & 0xFFFFFFFF) is not None for key in unique.tolist()], bool
        )
        passed_over = skip[inverse] & (objects["flags"] & REMOTE_FLAG == 0)
        for k, frames in enumerate(np.bincount(inverse[passed_over], minlength=len(unique)).tolist()):
            if frames:
                key = int(unique[k])
                skipped[(key >> 32, key & 0xFFFFFFFF)] += frames
        rows = np.flatnonzero(~passed_over)
        return pos + _RUN.itemsize * length, objects[rows], pos + _RUN.itemsize * rows

    def _needed(self, data: bytes, objects: np.ndarray, at: np.ndarray) -> Iterator[_Item]:
        """A run's needed objects, in order: the data frames of up to 8 bytes as slices of
        ``objects`` (for ``_block``), the others (remote frames, a dlc over 8, a timestamp too
        large to be exact as a float) parsed by python-can."""
        plain = (
            (objects["flags"] & REMOTE_FLAG == 0) & (objects["dlc"] <= 8) & (objects["timestamp"] < _EXACT)
        )
        start = 0
        for k in np.flatnonzero(~plain).tolist():
            if k > start:
                yield objects[start:k]
            begin = int(at[k])
            yield from super()._parse_data(data[begin : begin + _RUN.itemsize])
            start = k + 1
        if start < len(objects):
            yield objects[start:]

    def _block(self, gathered: list[np.ndarray]) -> FrameBlock:
        """The data frames of run objects as python-can's parser reads them: the timestamp in
        10 µs where the header's flags are 1, else in ns, from the file's start. python-can takes
        ``float(Decimal(raw) * Decimal("1e-5"))`` (or 1e-9), the exact product rounded once; a raw
        value below 2**53 is exact as a float, so dividing it by 1e5 (or 1e9, exact too) rounds the
        same quotient the same way. Then the start is added, as python-can adds it."""
        objects = gathered[0] if len(gathered) == 1 else np.concatenate(gathered)
        dlc = objects["dlc"].astype(np.int64)
        unit = np.where(objects["time_unit"] == 1, 1e5, 1e9)
        raw_id = objects["id"]
        return FrameBlock(
            t=objects["timestamp"].astype(np.float64) / unit + self.start_timestamp,
            frame_id=(raw_id & np.uint32(0x1FFFFFFF)).astype(np.uint32),
            extended=(raw_id & np.uint32(CAN_MSG_EXT)) != 0,
            channel=objects["channel"].astype(np.int64) - 1,
            data=np.where(np.arange(8) < dlc[:, None], objects["data"], 0).astype(np.uint8),  # data[:dlc]
            length=dlc,
            fd=np.zeros(len(objects), bool),
        )

    def _kind(self, channel: int, can_id: int) -> tuple[object, int, bool, str] | None:
        """(channel, id, extended, count) of a frame nobody needs, as python-can would read its
        key; None for a frame to parse. Asked of the decoder once per (channel, id)."""
        raw = (channel, can_id)
        kind = self._kinds.get(raw, _UNKNOWN)
        if kind is _UNKNOWN:
            key = (channel - 1, can_id & 0x1FFFFFFF, bool(can_id & CAN_MSG_EXT))
            count = self.triage.skip_kind(*key)
            kind = None if count is None else (*key, count)
            if len(self._kinds) < _MAX_KINDS:
                self._kinds[raw] = kind
        return kind  # type: ignore[return-value]

    def _count(self, skipped: Counter[tuple[int, int]]) -> None:
        for (raw_channel, can_id), frames in skipped.items():
            channel, frame_id, extended, kind = self._kind(raw_channel, can_id)  # type: ignore[misc]
            self.triage.count_skipped(channel, frame_id, extended, kind, frames, 0)
        self.skipped(sum(skipped.values()))
