"""MF4 bus logging read in bulk: asammdf's arrays of a whole channel group, not a python-can
Message per frame.

Most frames of a drive are of ids the pipeline never decodes; they are counted per (channel, id)
with numpy, and only the others become Messages, built as python-can's MF4Reader builds them
(tests/test_log_bulk.py holds the two readers to the same frames and counts). Files with error
or remote frames, or several data groups whose times go back, are left to python-can's reader.
"""

import heapq
import itertools
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import can
import numpy as np
from asammdf import MDF, Source
from asammdf.blocks.v4_constants import FLAG_CG_BUS_EVENT

from app.sources.blocks import FrameBlock, key_codes
from app.sources.triage import NotInBulk, Triage

CHUNK = 200_000  # frames per asammdf request: bounded memory on files of any size
_ID_MASK = 0x1FFFFFFF
_DATA = "CAN_DataFrame"


class TriagedMF4Reader:
    """The frames of an MF4 that ``triage`` needs, in python-can's order (its heapq merge of the
    groups by time); the others counted through ``triage``, and ``skipped`` hears how many.
    With ``blocks``, a file of one data group yields them as a FrameBlock per chunk, not as
    Messages. Raises NotInBulk for a file python-can's reader should read."""

    def __init__(
        self, path: Path, triage: Triage, skipped: Callable[[int], None], blocks: bool = False
    ) -> None:
        self.triage = triage
        self.skipped = skipped
        self.blocks = blocks
        self.mdf = open_mdf(path)
        try:
            groups = data_groups(self.mdf)
            if groups is None:
                raise NotInBulk("error or remote frames")
            self.start = self.mdf.header.start_time.timestamp()
            self.groups = groups
            self.whole: list[_Frames] = []
            if len(groups) > 1:  # merged by time: each group must be in time order
                self.whole = [_Frames(self.mdf.get(_DATA, g, raw=False), self.start) for g in groups]
                if any(np.any(np.diff(frames.t) < 0) for frames in self.whole):
                    raise NotInBulk("several data groups whose times go back")
        except BaseException:
            self.mdf.close()
            raise

    def __iter__(self) -> Iterator[can.Message | FrameBlock]:
        if self.whole:
            return heapq.merge(*(self._needed(f) for f in self.whole), key=lambda m: m.timestamp)
        return self._chunks(self.groups[0]) if self.groups else iter(())

    def stop(self) -> None:
        self.mdf.close()

    def _chunks(self, group: int) -> Iterator[can.Message | FrameBlock]:
        cycles = self.mdf.groups[group].channel_group.cycles_nr
        for offset in range(0, cycles, CHUNK):
            signal = self.mdf.get(_DATA, group, record_offset=offset, record_count=CHUNK, raw=False)
            frames = _Frames(signal, self.start)
            if self.blocks and frames.byte_matrix:
                rows = self._rows(frames)
                if len(rows):
                    yield frames.block(rows)
            else:
                yield from frames.messages(self._rows(frames))

    def _needed(self, frames: "_Frames") -> Iterator[can.Message]:
        return frames.messages(self._rows(frames))

    def _rows(self, frames: "_Frames") -> np.ndarray:
        keep = frames.triage(self.triage)
        self.skipped(len(keep) - int(np.count_nonzero(keep)))
        return np.flatnonzero(keep)


def open_mdf(path: Path) -> Any:
    """The file's blocks, without asammdf's bus-logging pass: with no DBC attached, that pass
    reads every frame of the file to map ids to groups, which nothing here uses."""
    return MDF(path, process_bus_logging=False)  # type: ignore[call-arg]  # read by MDF4, untyped in MDF


def holds_frames(path: Path) -> bool:
    """Whether the file has a CAN frame python-can's MF4Reader would read, reading the first of
    each group (python-can's reader would open the file with the bus-logging pass first: half a
    second per million frames). Raises what asammdf raises on a damaged file."""
    mdf = open_mdf(path)
    try:
        found = False
        for index, group in enumerate(mdf.groups):
            names = _can_group_names(group)
            if names is not None:
                name = next(n for n in (_DATA, "CAN_ErrorFrame", "CAN_RemoteFrame") if n in names)
                found |= len(mdf.get(name, index, record_offset=0, record_count=1, raw=True)) > 0
        return found
    finally:
        mdf.close()


def _can_group_names(group: Any) -> list[str] | None:
    """The channel names of a group python-can's MF4Reader reads CAN frames from, else None."""
    channel_group = group.channel_group
    if not channel_group.flags & FLAG_CG_BUS_EVENT or channel_group.cycles_nr == 0:
        return None
    source = channel_group.acq_source
    if source is None or not source.source_type & Source.SOURCE_BUS or source.bus_type != Source.BUS_TYPE_CAN:
        return None
    names = [channel.name for channel in group.channels]
    return names if {_DATA, "CAN_ErrorFrame", "CAN_RemoteFrame"} & set(names) else None


def data_groups(mdf: Any) -> list[int] | None:
    """The groups python-can's MF4Reader reads, when all of them hold CAN data frames (None when
    it would also read error or remote frames)."""
    groups = []
    for index, group in enumerate(mdf.groups):
        names = _can_group_names(group)
        if names is None:
            continue
        if _DATA not in names:
            return None  # error or remote frames
        groups.append(index)
    return groups


class _Frames:
    """One asammdf Signal of CAN_DataFrame records as columns."""

    def __init__(self, signal: Any, start: float) -> None:
        samples = signal.samples
        names = samples.dtype.names
        self.t = signal.timestamps + start
        self.frame_id = samples[f"{_DATA}.ID"] & _ID_MASK
        self.length = samples[f"{_DATA}.DataLength"]
        self.data = samples[f"{_DATA}.DataBytes"]

        def column(name: str) -> np.ndarray | None:
            return samples[f"{_DATA}.{name}"] if f"{_DATA}.{name}" in names else None

        self.channel, self.ide, self.dir = column("BusChannel"), column("IDE"), column("Dir")
        self.edl, self.brs, self.esi = column("EDL"), column("BRS"), column("ESI")
        self.byte_matrix = self.data.ndim == 2 and self.data.dtype == np.uint8  # python-can's writer's

    def triage(self, triage: Triage) -> np.ndarray:
        """Count the frames the pipeline does not need; return the mask of those it does."""
        ide = (
            self.ide.astype(bool) if self.ide is not None else np.ones(len(self.t), bool)
        )  # python-can's default
        keys = key_codes(self.channel, ide, self.frame_id)
        unique, first, inverse, counts = np.unique(
            keys, return_index=True, return_inverse=True, return_counts=True
        )
        fd = (
            np.bincount(inverse, weights=self.edl.astype(bool), minlength=len(unique))
            if self.edl is not None
            else None
        )
        needed = np.zeros(len(unique), bool)
        for k, i in enumerate(first.tolist()):
            key_channel = int(self.channel[i]) if self.channel is not None else None
            frame_id, extended = int(self.frame_id[i]), bool(ide[i])
            kind = triage.skip_kind(key_channel, frame_id, extended)
            if kind is None:
                needed[k] = True
            else:
                fd_frames = int(fd[k]) if fd is not None else 0
                triage.count_skipped(key_channel, frame_id, extended, kind, int(counts[k]), fd_frames)
        return needed[inverse]

    def block(self, rows: np.ndarray) -> FrameBlock:
        """The frames at ``rows`` as columns (the fields python-can's MF4Reader would give)."""
        n = len(rows)
        return FrameBlock(
            t=self.t[rows],
            frame_id=self.frame_id[rows],
            extended=self.ide[rows].astype(bool) if self.ide is not None else np.ones(n, bool),
            channel=self.channel[rows] if self.channel is not None else None,
            data=self.data[rows],
            length=self.length[rows].astype(np.int64),
            fd=self.edl[rows].astype(bool) if self.edl is not None else np.zeros(n, bool),
        )

    def messages(self, rows: np.ndarray) -> Iterator[can.Message]:
        """The frames at ``rows`` as python-can's MF4Reader makes them, each column turned into
        Python values once for all of them rather than frame by frame."""
        n = len(rows)

        def values(column: np.ndarray | None, default: object) -> Iterable[Any]:
            """A column's values at the rows, or python-can's default where the file has none."""
            return column[rows].tolist() if column is not None else itertools.repeat(default, n)

        if self.dir is None:
            is_rx: Iterable[Any] = itertools.repeat(True, n)
        else:
            direction = self.dir[rows]
            is_rx = (direction == b"Rx" if direction.dtype.kind == "S" else direction == 0).tolist()
        columns = zip(
            self.t[rows].tolist(),
            self.frame_id[rows].tolist(),
            self._payloads(rows),
            values(self.channel, None),
            is_rx,
            values(self.ide, True),
            values(self.edl, False),
            values(self.brs, False),
            values(self.esi, False),
            strict=True,
        )
        for t, frame_id, data, channel, rx, extended, fd, brs, esi in columns:
            yield can.Message(
                timestamp=t,
                arbitration_id=frame_id,
                data=data,
                channel=channel,
                is_rx=rx,
                is_extended_id=bool(extended),
                is_fd=bool(fd),
                bitrate_switch=bool(brs),
                error_state_indicator=bool(esi),
            )

    def _payloads(self, rows: np.ndarray) -> list[bytes]:
        """The data bytes of the frames at ``rows``, each cut to its length."""
        lengths = self.length[rows].tolist()
        data = self.data[rows]
        if not self.byte_matrix:  # frame by frame
            return [data[k][:length].tobytes() for k, length in enumerate(lengths)]
        blob, width = data.tobytes(), data.shape[1]
        return [blob[k * width : k * width + length] for k, length in enumerate(lengths)]
