"""BLF read without a Message for frames nobody needs.

python-can's BLFReader builds a Message for every object, with its timestamp worked out in
``Decimal``; most frames of a drive are of ids the pipeline never decodes. This reader is
python-can's, containers, compression and all, except that before an object is parsed its CAN id
and channel are read (two fields at fixed places) and asked of the decoder: a frame it does not
need is counted by key and passed over; every other object — needed frames, remote and error
frames, CAN FD, anything else — is parsed by python-can's own code. tests/test_log_bulk.py holds
it to python-can's reader frame for frame.
"""

import struct
from collections import Counter
from collections.abc import Callable, Iterator
from pathlib import Path

import can
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

from app.triage import Triage

_CHANNEL_FLAGS_ID = struct.Struct("<HBxL")  # a CAN message object's channel, flags, (dlc), id
_HEADER_SIZE = {1: OBJ_HEADER_V1_STRUCT.size, 2: OBJ_HEADER_V2_STRUCT.size}
_SKIP = "skip"


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
        unpack_frame = _CHANNEL_FLAGS_ID.unpack_from
        kinds = self._kinds
        skipped: Counter[tuple[int, int]] = Counter()
        max_pos = len(data)
        pos = 0
        try:
            while True:
                self._pos = pos
                try:
                    pos = data.index(b"LOBJ", pos, pos + 8)
                except ValueError:
                    if pos + 8 > max_pos:
                        return
                    raise BLFParseError("Could not find next object") from None
                _, _, header_version, obj_size, obj_type = unpack_header(data, pos)
                next_pos = pos + obj_size
                if next_pos > max_pos:
                    return  # the object continues in the next container
                if obj_type in (CAN_MESSAGE, CAN_MESSAGE2) and header_version in _HEADER_SIZE:
                    body = pos + OBJ_HEADER_BASE_STRUCT.size + _HEADER_SIZE[header_version]
                    channel, flags, can_id = unpack_frame(data, body)
                    if not flags & REMOTE_FLAG:
                        raw = (channel, can_id)
                        if raw not in kinds:
                            kinds[raw] = self._kind(channel, can_id)
                        if kinds[raw] is not None:
                            skipped[raw] += 1
                            pos = next_pos
                            continue
                self._pos = pos
                yield from parse(data[pos:next_pos])
                self._pos = pos = next_pos
        finally:
            self._count(skipped)

    def _kind(self, channel: int, can_id: int) -> tuple[object, int, bool, str] | None:
        key = (channel - 1, can_id & 0x1FFFFFFF, bool(can_id & CAN_MSG_EXT))  # as python-can reads it
        kind = self.triage.skip_kind(*key)
        return None if kind is None else (*key, kind)

    def _count(self, skipped: Counter[tuple[int, int]]) -> None:
        for raw, frames in skipped.items():
            channel, frame_id, extended, kind = self._kinds[raw]  # type: ignore[misc]
            self.triage.count_skipped(channel, frame_id, extended, kind, frames, 0)
        self.skipped(sum(skipped.values()))
