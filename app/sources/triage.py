"""What a bulk log reader asks the decoder: which frames it needs, and how to count the rest.

Most frames of a drive are of ids nothing decodes. A reader that can tell a frame's key (channel,
id, extended) without building a Message asks ``skip_kind``; the frames the pipeline does not need
are counted with ``count_skipped`` — as ``Decoder.decode`` would have counted them one by one —
and never become Messages.
"""

from typing import Protocol


class Triage(Protocol):
    def skip_kind(self, channel: object, frame_id: int, extended: bool) -> str | None:
        """The count a data frame of this key goes to when the pipeline needs nothing from it
        (``unknown_id``, ``other_channel``, ``unused``); None when it must be decoded."""
        ...

    def count_skipped(
        self, channel: object, frame_id: int, extended: bool, kind: str, frames: int, fd_frames: int
    ) -> None:
        """Count ``frames`` data frames of one key (``fd_frames`` of them CAN FD) as ``kind``."""
        ...


class NotInBulk(Exception):
    """The file is one a bulk reader leaves to python-can's frame-by-frame reader."""
