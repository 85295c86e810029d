"""Many frames at once, as columns: what a bulk reader hands the pipeline instead of a python-can
Message per frame (``c2n analyze`` and ``c2n gap`` on BLF and MF4), and what the decoder makes of them.

A block holds consecutive frames in arrival order, so the pipeline's result over blocks is its
result frame by frame (tests/test_log_bulk.py, tests/test_blocks.py).
"""

from dataclasses import dataclass, field

import numpy as np

FloatArray = np.ndarray


def key_codes(channel: np.ndarray | None, extended: np.ndarray, frame_id: np.ndarray) -> np.ndarray:
    """Each frame's key (channel, extended, id) as one uint64, for grouping frames by key with
    numpy (no channel column: channel 0 for all)."""
    channels = channel.astype(np.uint64) if channel is not None else np.zeros(len(frame_id), np.uint64)
    return (
        (channels << np.uint64(33))
        | (extended.astype(np.uint64) << np.uint64(32))
        | frame_id.astype(np.uint64)
    )


@dataclass(frozen=True)
class FrameBlock:
    """Data frames of keys the decoder needs: ``data`` a byte matrix (a row per frame, at least
    as wide as the longest), ``length`` each frame's data length. ``channel`` is None where the
    log has no channel column (python-can's None), ``extended`` and ``fd`` per frame."""

    t: FloatArray
    frame_id: np.ndarray
    extended: np.ndarray
    channel: np.ndarray | None
    data: np.ndarray
    length: np.ndarray
    fd: np.ndarray

    def __len__(self) -> int:
        return len(self.t)


def rows(block: FrameBlock, begin: int, end: int) -> FrameBlock:
    """The frames ``begin`` to ``end`` of a block, as a block."""
    channel = block.channel[begin:end] if block.channel is not None else None
    return FrameBlock(
        block.t[begin:end],
        block.frame_id[begin:end],
        block.extended[begin:end],
        channel,
        block.data[begin:end],
        block.length[begin:end],
        block.fd[begin:end],
    )


@dataclass
class RecordBlock:
    """The Records of a FrameBlock as columns: ``values`` role -> column, NaN where the record
    has no usable value of the role; ``rejected`` row -> {role: why}, as ``Record.rejected``."""

    t: FloatArray
    channel: list[object]
    frame_id: list[int]
    values: dict[str, FloatArray]
    rejected: dict[int, dict[str, str]] = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.t)

    def signals(self, row: int) -> dict[str, float]:
        """``Record.signals`` of one row."""
        return {role: value for role, column in self.values.items() if (value := float(column[row])) == value}
