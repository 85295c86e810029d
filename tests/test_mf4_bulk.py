"""The MF4 bulk reader (asammdf arrays) against python-can's MF4Reader, the reference: the same
frames reach the pipeline, every other frame is counted the same, the results are identical."""

import json
from pathlib import Path
from typing import Any

import can
import numpy as np
import pytest

from app import summary
from app.config import load_config
from app.decode import Decoder
from app.mf4_bulk import MDF, data_groups
from app.pipeline import Pipeline
from app.sources import LogReport, LogSource, read_log
from tests.simulated import cached_drive


def busy_drive(folder: Path, extra: list[can.Message] = ()) -> Path:  # type: ignore[assignment]
    """A simulated drive on a busy bus: background ids, 29-bit ids, CAN FD frames, a second
    channel, a frame of a known id on the wrong channel, all in one MF4."""
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
    path = folder / "drive.mf4"
    with can.Logger(path) as writer:
        for message in messages:
            writer.on_message_received(message)
    return path


def analysed(path: Path, bulk: bool) -> dict[str, Any]:
    pipeline = Pipeline(load_config())
    source = LogSource([path], triage=pipeline.decoder if bulk else None)
    for message in source:
        pipeline.process(message)
    pipeline.finish()
    result = summary.build(pipeline, [str(path)], source.reports)
    assert source.reports[0].done and source.reports[0].stopped is None
    result["frames_read"] = source.reports[0].frames
    return result


@pytest.fixture(scope="module")
def drive_mf4(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return busy_drive(tmp_path_factory.mktemp("bulk"))


@pytest.fixture(scope="module")
def by_frame(drive_mf4: Path) -> dict[str, Any]:
    """The reference: the drive analysed through python-can's reader, frame by frame."""
    return analysed(drive_mf4, bulk=False)


def test_bulk_reading_gives_the_same_results_as_reading_frame_by_frame(
    drive_mf4: Path, by_frame: dict[str, Any]
) -> None:
    in_bulk = analysed(drive_mf4, bulk=True)
    assert in_bulk["frames"]["total"] == in_bulk["frames_read"] > 20_000
    assert in_bulk["frames"]["unknown_id"] >= 20_000 - in_bulk["frames"]["fd_frames"]
    assert in_bulk["frames"]["fd_frames"] == 400
    assert in_bulk["crossings"], "the drive gives crossings"
    assert json.dumps(in_bulk, sort_keys=True) == json.dumps(by_frame, sort_keys=True)


def test_the_frames_read_in_bulk_are_python_cans_own(drive_mf4: Path) -> None:
    path = drive_mf4
    decoder = Decoder(load_config())
    in_bulk = list(read_log(path, LogReport(path), triage=decoder))
    reference = list(can.LogReader(path))
    needed = [
        m for m in reference if decoder.skip_kind(m.channel, m.arbitration_id, m.is_extended_id) is None
    ]
    assert 0 < len(in_bulk) == len(needed) < len(reference)
    for ours, theirs in zip(in_bulk, needed, strict=True):
        assert ours.equals(theirs, timestamp_delta=0.0, check_channel=True, check_direction=True)
        assert (ours.is_fd, ours.bitrate_switch, ours.error_state_indicator, ours.dlc) == (
            theirs.is_fd,
            theirs.bitrate_switch,
            theirs.error_state_indicator,
            theirs.dlc,
        )
    assert decoder.counts.total == len(reference) - len(needed)  # the rest counted, not decoded


def test_a_file_with_error_frames_is_read_frame_by_frame_with_the_same_counts(tmp_path: Path) -> None:
    t = cached_drive().messages[100].timestamp
    error = can.Message(timestamp=t, is_error_frame=True, channel=0)
    path = busy_drive(tmp_path, [error])
    with MDF(path) as mdf:
        assert data_groups(mdf) is None  # python-can reads an error-frame group too
    in_bulk = analysed(path, bulk=True)
    assert in_bulk["frames"]["error_frames"] == 1
    assert json.dumps(in_bulk, sort_keys=True) == json.dumps(analysed(path, bulk=False), sort_keys=True)


@pytest.mark.parametrize("chunk", [997, 5_000])
def test_chunks_of_any_size_read_the_same(
    drive_mf4: Path, by_frame: dict[str, Any], monkeypatch: pytest.MonkeyPatch, chunk: int
) -> None:
    monkeypatch.setattr("app.mf4_bulk.CHUNK", chunk)
    assert json.dumps(analysed(drive_mf4, bulk=True), sort_keys=True) == json.dumps(by_frame, sort_keys=True)
