"""BLF read without a Message for frames nobody needs.

python-can's BLFReader builds a Message for every object, with its timestamp worked out in
``Decimal``; most frames of a drive are of ids the pipeline never decodes. This reader is
python-can's, containers, compression and all, except for its object walk: a run of plain CAN
message objects (48 bytes each, header version 1: what loggers and python-can's writer write) is
read as one numpy array, and elsewhere an object's channel and id are read from their fixed
places. A frame the decoder does not need is counted by key and passed over; every other object
— needed frames, remote and error frames, CAN FD, anything else — is parsed by python-can's own
code. tests/test_log_bulk.py holds it to python-can's reader frame for frame.
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
        ("header", "V16"),
        ("channel", "<u2"),
        ("flags", "u1"),
        ("dlc", "u1"),
        ("id", "<u4"),
        ("data", "V8"),
    ]
)


class TriagedBLFReader(can.BLFReader):
    """python-can's BLFReader that counts the frames ``triage`` does not need instead of
    yielding them; ``skipped`` hears how many frames each container had of those."""

    def __init__(self, path: Path, triage: Triage, skipped: Callable[[int], None]) -> None:
        super().__init__(path)
        self.triage = triage
        self.skipped = skipped
        self._kinds: dict[tuple[int, int], tuple[object, int, bool, str] | None] = {}

    def _parse_data(self, data: bytes) -> Iterator[can.Message]:
        """python-can's object walk (the same positions, the same end-of-container rule), with
        the frames nobody needs counted and skipped; the rest parsed by python-can."""
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
                        end, needed = run
                        for at in needed:
                            yield from parse(data[at : at + _RUN.itemsize])
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

    def _run(self, data: bytes, pos: int, skipped: Counter[tuple[int, int]]) -> tuple[int, list[int]] | None:
        """A run of whole CAN message objects (header v1, no padding) from ``pos``, read as one
        numpy array: the frames nobody needs counted into ``skipped``. Returns where the run ends
        and where its other objects start (None for a run of one: the walk takes it)."""
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
        needed = (pos + _RUN.itemsize * np.flatnonzero(~passed_over)).tolist()
        return pos + _RUN.itemsize * length, needed

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
