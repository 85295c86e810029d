"""The bulk readers (BLF: python-can's object walk with unneeded frames skipped; MF4: asammdf's
arrays) against python-can's readers, the reference: the same frames reach the pipeline, every
other frame is counted the same, the results are identical."""

import json
from pathlib import Path
from typing import Any

import can
import numpy as np
import pytest

from app.config import load_config
from app.decode.decoder import Decoder
from app.errors import LogFileError
from app.pipeline import Pipeline
from app.sinks import summary
from app.sources.blocks import FrameBlock
from app.sources.logs import LogReport, LogSource, check_readable, read_log
from app.sources.mf4_bulk import MDF, data_groups, holds_frames
from tests.simulated import cached_drive


def busy_drive(folder: Path, suffix: str, extra: tuple[can.Message, ...] = ()) -> Path:
    """A simulated drive on a busy bus: background ids, 29-bit ids, CAN FD frames, a second
    channel, in one log file."""
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
    with can.Logger(path) as writer:
        for message in messages:
            writer.on_message_received(message)
    return path


def analysed(path: Path, bulk: bool) -> dict[str, Any]:
    """The drive's summary; ``bulk``: read as ``c2n analyze`` reads it (an MF4 as FrameBlocks)."""
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
