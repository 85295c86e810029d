"""One drive, whatever file holds it: a log's content identity, from its frames, not its bytes.

The same drive saved as ``.log`` and as ``.blf`` (or copied, or linked) has other bytes but the
same frames: the same identifiers and data in the same order over the same time. Counting it twice
narrows an interval by √2 and halves a difference that is not there, so ``c2n analyze`` (several
files, ``--pool``, ``--merge``) and ``c2n campaign`` read a repeated drive once and say so.

The frames' identifiers, flags and data bytes are hashed in file order; the time stamps are not:
the formats keep them to different resolutions (BLF nanoseconds, candump and ASC microseconds), so
any rounding grid would split some frame of a 100,000 between two cells. The drive's duration is
kept beside the hash and must agree to within the coarsest of those resolutions (``TIME_TOLERANCE_S``)
— a drive's sensor noise already makes its data bytes its own.
"""

import hashlib
import struct
from collections.abc import Iterable
from dataclasses import dataclass

import can

TIME_TOLERANCE_S = 1e-3  # TRC 1.x keeps milliseconds: the coarsest time stamp of the formats read


@dataclass(frozen=True)
class DriveIdentity:
    digest: str  # BLAKE2b of the frames' ids, flags and data, in order
    frames: int
    duration_s: float  # first to last frame

    def same_drive(self, other: "DriveIdentity") -> bool:
        return (
            self.digest == other.digest
            and self.frames == other.frames
            and abs(self.duration_s - other.duration_s) <= TIME_TOLERANCE_S
        )

    @property
    def text(self) -> str:
        """As a results column holds it."""
        return f"{self.digest}:{self.frames}:{self.duration_s:.3f}"

    @staticmethod
    def parse(text: object) -> "DriveIdentity | None":
        if not isinstance(text, str) or text.count(":") != 2:
            return None
        digest, frames, duration = text.split(":")
        try:
            return DriveIdentity(digest, int(frames), float(duration))
        except ValueError:
            return None


_FRAME = struct.Struct("<I??B")


def identity_of(messages: Iterable[can.Message]) -> DriveIdentity:
    """The identity of the drive these frames make (``app.sources.logs.drive_identity`` reads
    them from a file)."""
    digest = hashlib.blake2b(digest_size=16)
    frames = 0
    first = last = 0.0
    for msg in messages:
        data = bytes(msg.data or b"")
        digest.update(_FRAME.pack(msg.arbitration_id, msg.is_extended_id, msg.is_remote_frame, len(data)))
        digest.update(data)
        if not frames:
            first = msg.timestamp
        last = msg.timestamp
        frames += 1
    return DriveIdentity(digest.hexdigest(), frames, last - first)
