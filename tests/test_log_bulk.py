"""The bulk readers (BLF: python-can's object walk with unneeded frames skipped, the needed ones
in FrameBlocks read with numpy; MF4: asammdf's arrays) against python-can's readers, the
reference: the same frames reach the pipeline, every other frame is counted the same, the results
are identical."""

import copy
import json
from pathlib import Path
from typing import Any

import can
import numpy as np
import pytest
from can.io.blf import OBJ_HEADER_BASE_STRUCT, OBJ_HEADER_V1_STRUCT, TIME_TEN_MICS

from app.config import load_config
from app.decode.decoder import Decoder
from app.errors import LogFileError
from app.pipeline import Pipeline
from app.sinks import summary
from app.sources.blocks import FrameBlock
from app.sources.logs import LogReport, LogSource, check_readable, read_log
from app.sources.mf4_bulk import MDF, data_groups, holds_frames
from tests.simulated import cached_drive


class MixedUnitsWriter(can.BLFWriter):
    """python-can's BLF writer (whose objects give their time in ns) with every other object's
    time in 10 µs, its header's flags 1, as other loggers write it."""

    objects = 0

    def _add_object(self, obj_type: int, data: bytes, timestamp: float | None = None) -> None:
        self.objects += 1
        if self.objects % 2 or timestamp is None or self.start_timestamp is None:
            super()._add_object(obj_type, data, timestamp)
            return
        header_size = OBJ_HEADER_BASE_STRUCT.size + OBJ_HEADER_V1_STRUCT.size
        ticks = max(round((timestamp - self.start_timestamp) * 1e5), 0)
        padding = b"\x00" * (len(data) % 4)
        self.stop_timestamp = timestamp
        self._buffer += [
            OBJ_HEADER_BASE_STRUCT.pack(b"LOBJ", header_size, 1, header_size + len(data), obj_type),
            OBJ_HEADER_V1_STRUCT.pack(TIME_TEN_MICS, 0, 0, ticks),
            data,
            padding,
        ]
        self._buffer_size += header_size + len(data) + len(padding)
        self.object_count += 1
        if self._buffer_size >= self.max_container_size:
            self._flush()


def busy_drive(folder: Path, suffix: str, extra: tuple[can.Message, ...] = (), offset: float = 0.0) -> Path:
    """A simulated drive on a busy bus: background ids, 29-bit ids, CAN FD frames, a second
    channel, in one log file (a BLF with times in 10 µs and in ns), its times moved by
    ``offset``."""
    drive = cached_drive()
    rng = np.random.default_rng(11)
    start, end = drive.messages[0].timestamp, drive.messages[-1].timestamp
    messages = list(drive.messages) + list(extra)
    for k, t in enumerate(np.sort(rng.uniform(start, end, 20_000)).tolist()):
        fd = k % 50 == 0
        messages.append(
            can.Message(
                timestamp=t,
                arbitration_id=int(rng.integers(0x300, 0x340)) if k % 3 else int(rng.integers(0, 0x1FFFFFFF)),
                is_extended_id=k % 3 == 0,
                is_fd=fd,
                data=bytes(rng.integers(0, 256, 16 if fd else 8, dtype=np.uint8)),
                channel=k % 2,
            )
        )
    messages.sort(key=lambda m: m.timestamp)
    path = folder / f"drive{suffix}"
    with MixedUnitsWriter(path) if suffix == ".blf" else can.Logger(path) as writer:
        for message in messages:
            if offset:
                message = copy.copy(message)  # the cached drive's own Messages stay as they are
                message.timestamp += offset
            writer.on_message_received(message)
    return path


def analysed(path: Path, bulk: bool) -> dict[str, Any]:
    """The drive's summary; ``bulk``: read as ``c2n analyze`` reads it (a BLF or an MF4 as
    FrameBlocks)."""
    pipeline = Pipeline(load_config())
    source = LogSource([path], triage=pipeline.decoder if bulk else None)
    blocks = 0
    for item in source.items(blocks=bulk):
        if isinstance(item, FrameBlock):
            pipeline.process_block(item)
            blocks += 1
        else:
            pipeline.process(item)
    if bulk and path.suffix == ".mf4":  # blocks where asammdf's arrays are read: data frames only
        with MDF(path) as mdf:
            assert (blocks > 0) == (data_groups(mdf) is not None)
    if path.suffix == ".blf":  # its runs of CAN message objects: blocks whenever read in bulk
        assert (blocks > 0) == bulk
    pipeline.finish()
    result = summary.build(pipeline.snapshot(), pipeline.config, [str(path)], source.reports).to_json()
    assert source.reports[0].done and source.reports[0].stopped is None
    result["frames_read"] = source.reports[0].frames
    return result


@pytest.fixture(scope="module", params=[".blf", ".mf4"])
def drive_log(request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory) -> Path:
    return busy_drive(tmp_path_factory.mktemp("bulk"), request.param)


@pytest.fixture(scope="module")
def by_frame(drive_log: Path) -> dict[str, Any]:
    """The reference: the drive analysed through python-can's reader, frame by frame."""
    return analysed(drive_log, bulk=False)


def test_bulk_reading_gives_the_same_results_as_reading_frame_by_frame(
    drive_log: Path, by_frame: dict[str, Any]
) -> None:
    in_bulk = analysed(drive_log, bulk=True)
    assert in_bulk["frames"]["total"] == in_bulk["frames_read"] > 20_000
    assert in_bulk["frames"]["unknown_id"] >= 20_000 - in_bulk["frames"]["fd_frames"]
    assert in_bulk["frames"]["fd_frames"] == 400
    assert in_bulk["crossings"], "the drive gives crossings"
    if drive_log.suffix == ".blf":  # objects cut across python-can's 128 KiB containers
        assert drive_log.stat().st_size > 3 * 128 * 1024 // 4
    assert json.dumps(in_bulk, sort_keys=True) == json.dumps(by_frame, sort_keys=True)


def test_the_frames_read_in_bulk_are_python_cans_own(drive_log: Path) -> None:
    """What the bulk reader yields is python-can's reader's frames, in order, less only frames
    the decoder has no use for — which it counted instead."""
    decoder = Decoder(load_config())
    in_bulk = list(read_log(drive_log, LogReport(drive_log), triage=decoder))
    passed_over = 0
    k = 0
    for theirs in can.LogReader(drive_log):
        ours = in_bulk[k] if k < len(in_bulk) else None
        if ours is not None and ours.equals(
            theirs, timestamp_delta=0.0, check_channel=True, check_direction=True
        ):
            assert (ours.is_fd, ours.bitrate_switch, ours.error_state_indicator, ours.dlc) == (
                theirs.is_fd,
                theirs.bitrate_switch,
                theirs.error_state_indicator,
                theirs.dlc,
            )
            k += 1
            continue
        assert decoder.skip_kind(theirs.channel, theirs.arbitration_id, theirs.is_extended_id) is not None, (
            theirs
        )
        passed_over += 1
    assert k == len(in_bulk) > 0
    assert passed_over > 15_000
    assert decoder.counts.total == passed_over  # counted without being decoded


def frames_of(items: list[can.Message | FrameBlock]) -> list[tuple[Any, ...]]:
    """Each frame's fields as python-can's Message gives them, a block's row by row."""
    out: list[tuple[Any, ...]] = []
    for item in items:
        if isinstance(item, can.Message):
            out.append(
                (
                    item.timestamp,
                    item.arbitration_id,
                    item.is_extended_id,
                    item.channel,
                    bytes(item.data),
                    item.dlc,
                    item.is_fd,
                    item.is_remote_frame,
                    item.is_error_frame,
                )
            )
            continue
        assert item.channel is not None and item.data.shape[1] >= int(item.length.max())
        for k, length in enumerate(item.length.tolist()):
            row = item.data[k]
            assert not row[length:].any()  # the bytes past the data length are zeros, as _block pads
            fields = (item.frame_id[k], item.extended[k], item.channel[k], item.fd[k])
            frame_id, extended, channel, fd = (x.item() for x in fields)
            out.append(
                (
                    item.t[k].item(),
                    frame_id,
                    extended,
                    channel,
                    row[:length].tobytes(),
                    length,
                    fd,
                    False,
                    False,
                )
            )
    return out


@pytest.mark.parametrize("clock", ["unix", "from power-on"])
def test_a_blf_read_in_blocks_gives_python_cans_frames(tmp_path: Path, clock: str) -> None:
    """Frame for frame, timestamp to the bit: the blocks and Messages of a BLF read in blocks are
    python-can's reader's frames, in order, less the frames passed over (counted instead), on the
    busy drive (times in 10 µs and ns, 29-bit ids, CAN FD, two channels) with an error frame, and
    needed frames a block does not hold: remote, with a dlc over 8, a time too late to be exact as
    a float of ns (more than 2**53 ns, 104 days, after the start). On a clock from power-on the
    file starts at 0 (its header has no date): the times are the objects' own, every bit seen."""
    decoder = Decoder(load_config())
    drive = cached_drive().messages
    needed = next(
        m for m in drive if decoder.skip_kind(m.channel, m.arbitration_id, m.is_extended_id) is None
    )
    t = drive[200].timestamp

    def like(**fields: Any) -> can.Message:
        return can.Message(arbitration_id=needed.arbitration_id, is_extended_id=False, **fields)

    odd = (
        can.Message(timestamp=t, is_error_frame=True, channel=0),
        like(timestamp=t + 0.0001, is_remote_frame=True, dlc=8, channel=needed.channel),
        like(timestamp=t + 0.0002, dlc=15, data=bytes(range(8)), channel=needed.channel),
        like(timestamp=t + 0.0003, data=bytes(range(8)), channel=-1),  # raw channel 0
        *(  # two: the writer gives one of them in ns, the other in 10 µs (a block holds that one)
            like(timestamp=drive[-1].timestamp + 105 * 86_400 + k, data=bytes(8), channel=needed.channel)
            for k in (0, 1)
        ),
    )
    path = busy_drive(tmp_path, ".blf", odd, offset=0.0 if clock == "unix" else 0.5 - drive[0].timestamp)
    report = LogReport(path)
    items = list(read_log(path, report, triage=decoder, blocks=True))
    blocks = [item for item in items if isinstance(item, FrameBlock)]
    in_blocks = sum(len(b) for b in blocks)
    theirs = [m for m in can.LogReader(path) if not (m.is_error_frame or m.is_remote_frame or m.is_fd)]
    kept = [
        m
        for m in can.LogReader(path)
        if decoder.skip_kind(m.channel, m.arbitration_id, m.is_extended_id) is None
        or m.is_error_frame
        or m.is_remote_frame
        or m.is_fd  # python-can's parser reads CAN FD objects: they come as Messages
    ]
    assert frames_of(items) == frames_of(kept)  # type: ignore[arg-type]
    assert report.frames == len(theirs) + 1 + 1 + 400 and report.stopped is None
    assert in_blocks > 30_000 and len(items) - len(blocks) == 400 + 4  # CAN FD, the odd frames
    assert decoder.counts.total == report.frames - in_blocks - (len(items) - len(blocks))
    assert (can.BLFReader(path).start_timestamp == 0) == (clock == "from power-on")


@pytest.mark.parametrize("suffix", [".blf", ".mf4"])
def test_error_and_remote_frames_are_counted_the_same(tmp_path: Path, suffix: str) -> None:
    t = cached_drive().messages[100].timestamp
    error = can.Message(timestamp=t, is_error_frame=True, channel=0)
    remote = can.Message(timestamp=t + 0.001, arbitration_id=0x7E5, is_remote_frame=True, dlc=8, channel=1)
    path = busy_drive(tmp_path, suffix, (error, remote))
    if suffix == ".mf4":
        with MDF(path) as mdf:
            assert data_groups(mdf) is None  # python-can reads error and remote groups too: its reader's job
    in_bulk = analysed(path, bulk=True)
    assert (in_bulk["frames"]["error_frames"], in_bulk["frames"]["remote_frames"]) == (1, 1)
    assert json.dumps(in_bulk, sort_keys=True) == json.dumps(analysed(path, bulk=False), sort_keys=True)


@pytest.mark.parametrize("drive_log", [".mf4"], indirect=True)
@pytest.mark.parametrize("chunk", [997, 5_000])
def test_mf4_chunks_of_any_size_read_the_same(
    drive_log: Path, by_frame: dict[str, Any], monkeypatch: pytest.MonkeyPatch, chunk: int
) -> None:
    monkeypatch.setattr("app.sources.mf4_bulk.CHUNK", chunk)
    assert json.dumps(analysed(drive_log, bulk=True), sort_keys=True) == json.dumps(by_frame, sort_keys=True)


def test_an_mf4_is_checked_without_python_cans_reader_and_agrees_with_it(tmp_path: Path) -> None:
    """``check_readable`` opens an MF4 without asammdf's bus-logging pass (which reads the whole
    file), and says what python-can's reader would find: frames, or none at all."""
    drive = cached_drive()
    full, empty = tmp_path / "full.mf4", tmp_path / "empty.mf4"
    with can.Logger(full) as writer:
        for message in drive.messages[:500]:
            writer.on_message_received(message)
    with can.Logger(empty):
        pass
    assert holds_frames(full) and next(iter(can.LogReader(full)), None) is not None
    check_readable(full)
    assert not holds_frames(empty) and next(iter(can.LogReader(empty)), None) is None
    with pytest.raises(LogFileError, match=r"empty\.mf4: no CAN frames in the file"):
        check_readable(empty)
