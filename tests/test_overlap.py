"""Two recordings of one stretch of driving (a second logger on the bus, a copy cut or thinned)
are told from two drives, and `c2n analyze` does not count the stretch twice."""

import json
import random
from pathlib import Path

import can
import pytest

from app.config import load_config
from app.pipeline import Pipeline
from app.results.log_clock import sensor_messages
from app.sources.logs import LogSource
from app.sources.overlap import WINDOW, SensorPrints, overlapping, spanned
from tests.simulated import cached_drive
from tests.test_reliability_inputs import run_cli
from tests.test_separate_recordings import _write

SENSOR = frozenset(sensor_messages(load_config()))


def _prints(messages: list[can.Message]) -> SensorPrints:
    prints = SensorPrints(SENSOR)
    for message in messages:
        prints.add(message)
    return prints


def _second_logger(messages: list[can.Message], lost: float, seed: int = 1) -> list[can.Message]:
    """What a second logger on the bus keeps: started later, stopped sooner, ``lost`` of the
    frames dropped at random."""
    rng = random.Random(seed)
    cut = len(messages) // 20
    return [m for m in messages[cut:-cut] if rng.random() >= lost]


def test_frames_and_blocks_keep_the_same_runs(tmp_path: Path) -> None:
    """A BLF read in blocks (numpy) keeps the runs its frames read one by one keep."""
    messages = cached_drive("constant_radius", 1, 14.9).messages
    blf = _write(tmp_path / "d.blf", messages)
    blocks = SensorPrints(SENSOR)
    source = LogSource([blf], triage=Pipeline(load_config()).decoder)
    for item in source.items(blocks=True):
        if item is not None:
            blocks.add(item)
    frames = _prints(messages)
    assert len(frames.runs) > 500 and blocks.runs == frames.runs


def test_a_second_loggers_copy_is_the_same_driving_and_another_drive_is_not() -> None:
    messages = cached_drive("constant_radius", 1, 14.9).messages
    whole = _prints(messages)
    for lost in (0.0, 0.02, 0.1):  # a run is lost with any of its 16 frames: 10 % lost keeps 19 %
        copy = _prints(_second_logger(messages, lost))
        assert spanned(whole, copy) > 0.95
        assert overlapping([("a", whole), ("b", copy)]) is not None
    other = _prints(cached_drive("constant_radius", 2, 14.9).messages)  # another drive: its own noise
    assert not whole.runs.keys() & other.runs.keys() and overlapping([("a", whole), ("c", other)]) is None
    later = _prints(messages[: len(messages) // 3])  # a third of the drive beside the rest of it:
    rest = _prints(messages[len(messages) // 3 :])  # two parts of one drive, not one stretch twice
    assert overlapping([("first", later), ("rest", rest)]) is None


def test_a_standing_sensors_frames_make_no_runs() -> None:
    """Payloads that do not change (a car standing, a sensor holding its last value) are in
    every drive: no run of them is kept."""
    [frame_id] = SENSOR
    held = [
        can.Message(timestamp=0.01 * k, arbitration_id=frame_id, data=bytes(8)) for k in range(40 * WINDOW)
    ]
    toggling = [
        can.Message(timestamp=0.01 * k, arbitration_id=frame_id, data=bytes([k % 3] + [0] * 7))
        for k in range(40 * WINDOW)
    ]
    assert not _prints(held).runs and not _prints(toggling).runs


def test_analyze_does_not_count_a_drive_and_its_second_loggers_copy_twice(tmp_path: Path) -> None:
    """Pooled, or given as one drive, a drive and a second logger's copy of it (2 % of its frames
    lost) read one C2n with an interval √2 too narrow; now no C2n, and why, naming both."""
    messages = cached_drive("constant_radius", 1, 14.9).messages
    blf = _write(tmp_path / "car [laptop].blf", messages)
    copy = _write(tmp_path / "vector logger.log", _second_logger(messages, 0.02))
    for how in (["--pool"], []):
        out = tmp_path / "s.json"
        code, _, err = run_cli(["analyze", *how, str(blf), str(copy), "--json", str(out)])
        assert code == 1 and not out.exists(), err
        assert (
            "car [laptop].blf and vector logger.log hold the same driving (the optical sensor's frames" in err
        )
        assert "one drive recorded twice — a second logger on the bus" in err and "analyse one of them" in err
    other = _write(tmp_path / "next day.log", cached_drive("constant_radius", 2, 14.9).messages)
    out = tmp_path / "pooled.json"
    code, _, err = run_cli(["analyze", "--pool", str(blf), str(other), "--json", str(out)])
    assert code == 0 and json.loads(out.read_text())["c2n"] is not None, err


def test_a_campaign_counts_one_stretch_of_driving_once(tmp_path: Path) -> None:
    """A campaign listing a drive, a second logger's copy of it and another drive: the copy's row
    names the drive that counts (it was two sessions of one tyre set, its group's interval
    narrowed by √2); the other drive counts."""
    import csv

    messages = cached_drive("constant_radius", 1, 14.9).messages
    _write(tmp_path / "car.blf", messages)
    _write(tmp_path / "second logger.log", _second_logger(messages, 0.02))
    _write(tmp_path / "next day.log", cached_drive("constant_radius", 2, 14.9).messages)
    manifest = tmp_path / "manifest.csv"
    manifest.write_text("log,tyre_set\ncar.blf,A\nsecond logger.log,A\nnext day.log,A\n")
    out = tmp_path / "campaign"
    code, _, err = run_cli(["campaign", str(manifest), "--workers", "1", "--out", str(out)])
    assert code == 0, err
    rows = {row["log"]: row for row in csv.DictReader((out / "results.csv").open(encoding="utf-8-sig"))}
    assert rows["car.blf"]["error"] == rows["next day.log"]["error"] == ""
    said = rows["second logger.log"]["error"]
    assert "second logger.log: the same driving as " in said and said.endswith(
        "car.blf (line 2): counted once"
    )
    comparison = json.loads((out / "comparison.json").read_text())
    assert comparison["groups"]["all"]["n_sessions"] == 2  # the two drives that count


def test_of_two_copies_the_whole_drive_counts_not_a_fragment_listed_first(tmp_path: Path) -> None:
    """A fragment cut from a drive, listed before the drive itself: the fragment counted and the
    whole drive was the repeat (the group read 14.486 where the whole drive reads 14.729). Now
    the copy with the most frames counts wherever the manifest lists it."""
    import csv

    messages = cached_drive("constant_radius", 1, 14.9).messages
    _write(tmp_path / "fragment.log", messages[len(messages) // 5 : len(messages) // 2])
    _write(tmp_path / "car.blf", messages)
    manifest = tmp_path / "manifest.csv"
    manifest.write_text("log,tyre_set\nfragment.log,A\ncar.blf,A\n")
    out = tmp_path / "campaign"
    code, _, err = run_cli(["campaign", str(manifest), "--workers", "1", "--out", str(out)])
    assert code == 0, err
    rows = {row["log"]: row for row in csv.DictReader((out / "results.csv").open(encoding="utf-8-sig"))}
    assert rows["car.blf"]["error"] == ""
    assert rows["fragment.log"]["error"].endswith("car.blf (line 3): counted once")
    assert "fragment.log: the same driving as " in err
    group = json.loads((out / "comparison.json").read_text())["groups"]["all"]
    assert group["n_sessions"] == 1 and group["c2n"] == pytest.approx(float(rows["car.blf"]["c2n"]))
