"""``c2n live`` left running through a tyre change: the parts between the optical sensor's pauses
are run alone beside the whole (``app/pipeline.py (PartedPipeline)``), and parts that disagree leave the
run no one C2n (``app/results/parts.py``); parts that agree, and a run that never paused, give
what the one pipeline gives."""

import json
import threading
import uuid
from pathlib import Path

import can
import pytest

from app.cli import main
from app.cli.demo import Player
from app.config import Config, load_config
from app.pipeline import PartedPipeline, Pipeline
from app.results.log_clock import sensor_messages
from app.run_loop import run
from app.sinks import summary
from tests.test_reliability import wait_until
from tests.test_separate_recordings import _drive, _one_file, shifted

BEFORE, AFTER = 14.89, 15.91  # the two sets' true C2n
PAUSE_S = 600.0  # ten minutes parked, the sensor off


@pytest.fixture(scope="module")
def day() -> list[can.Message]:
    """14.89 for 150 s, the sensor off for ten minutes, 15.91 for 150 s: one bus, one run."""
    before, after = _drive(BEFORE, 5).messages, _drive(AFTER, 6).messages
    return [*before, *shifted(after, before[-1].timestamp + PAUSE_S - after[0].timestamp)]


def _run(pipeline: Pipeline, frames: list[can.Message]) -> Pipeline:
    assert run(frames, pipeline)
    return pipeline


def test_two_tyre_sets_across_a_pause_give_no_one_c2n_but_each_part_its_own(
    day: list[can.Message], config: Config
) -> None:
    """The one pipeline read 15.43 [15.20, 15.67] — between the sets, outside both — and that
    was live's result line; now no C2n, and each part's own C2n, its truth inside, in the
    refusal and in the summary's parts."""
    pooled = _run(Pipeline(config), day).snapshot().headline
    assert pooled is not None and pooled.ci95[0] > BEFORE and pooled.ci95[1] < AFTER
    snapshot = _run(PartedPipeline(config), day).snapshot()
    assert snapshot.headline is None
    first, second = snapshot.parts
    assert (round(first.begin_t - snapshot.t0), round(first.end_t - snapshot.t0)) == (0, 150)
    assert (round(second.begin_t - snapshot.t0), round(second.end_t - snapshot.t0)) == (750, 900)
    for part, truth in ((first, BEFORE), (second, AFTER)):
        assert part.headline is not None and part.headline.ci95[0] <= truth <= part.headline.ci95[1]
    why = snapshot.refusal
    assert why.startswith("the parts between the optical sensor's pauses disagree, each alone: 0–150 s 14.9")
    assert "; 750–900 s 15.9" in why and "split the session's recording at its pauses (c2n split)" in why
    written = summary.build(snapshot, config, ["can0"]).to_json()
    assert written["c2n"] is None and written["no_result"] == why
    rows = written["parts"]
    assert [(row["from_s"], row["to_s"]) for row in rows] == [
        pytest.approx((0.0, 150.0), abs=0.5),
        pytest.approx((750.0, 900.0), abs=0.5),
    ]
    assert rows[0]["c2n_ci95"][0] <= BEFORE <= rows[0]["c2n_ci95"][1]
    assert rows[1]["c2n_ci95"][0] <= AFTER <= rows[1]["c2n_ci95"][1]
    assert not any("soften" in w or "slope" in w for w in written["warnings"])  # no fit's advice


def test_a_dropout_and_a_run_without_a_pause_give_what_the_one_pipeline_gives(config: Config) -> None:
    """Two seconds without the optical sensor: two parts that agree, the result the one
    pipeline's to the digit and no word of parts in the result; no pause: no parts at all."""
    drive = _drive(BEFORE, 5).messages
    start, optical = drive[0].timestamp, set(sensor_messages(config))
    dropout = [m for m in drive if not (m.arbitration_id in optical and 70.0 <= m.timestamp - start < 72.0)]
    for frames, parts in ((dropout, 2), (drive, 0)):
        one = _run(Pipeline(config), frames).snapshot()
        parted = _run(PartedPipeline(config), frames).snapshot()
        assert one.headline is not None and parted.headline == one.headline
        assert len(parted.parts) == parts and parted.parts_disagree is None
        assert parted.refusal == one.refusal and parted.crossings == one.crossings


def test_live_through_a_tyre_change_says_each_part_and_no_one_c2n(
    day: list[can.Message], tmp_path: Path
) -> None:
    """The day over a virtual bus into ``c2n live``: the result line and both summaries (the
    session's and --json) say the parts disagree, with no C2n, and the recording keeps every
    frame; exit 0 (it read `C2n = 15.429` with no word)."""
    log = _one_file(tmp_path / "day.log", (day, 0.0))
    channel = f"test-{uuid.uuid4().hex}"
    stop = threading.Event()

    sessions, out = tmp_path / "sessions", tmp_path / "live.json"

    def play() -> None:
        wait_until(lambda: any(sessions.glob("*/frames.log")), "the session to start")  # its bus is open
        with can.Bus(interface="virtual", channel=channel, preserve_timestamps=True) as tx:
            Player(log, tx, rate=1e6, stop=stop).run()

    sender = threading.Thread(target=play)
    sender.start()
    argv = ["live", "-i", "virtual", "-c", channel, "--record", str(sessions), "--json", str(out)]
    try:
        code = main([*argv, "--duration", "10"])  # the frames sent in a second or two, then read
    finally:
        stop.set()
        sender.join()
    assert code == 0
    [session] = sessions.iterdir()
    for written in (json.loads(out.read_text()), json.loads((session / "summary.json").read_text())):
        assert written["c2n"] is None and written["frames"]["total"] == len(day)
        assert written["no_result"].startswith("the parts between the optical sensor's pauses disagree")
        assert len(written["parts"]) == 2
    assert sum(1 for _ in can.LogReader(session / "frames.log")) == len(day)


def test_a_bus_gives_no_blocks_to_the_parted_pipeline() -> None:
    from app.sources.blocks import RecordBlock

    with pytest.raises(TypeError, match="one by one"):
        PartedPipeline(load_config()).take_block(RecordBlock.__new__(RecordBlock))
