"""A log's clock unit from its optical sensor's frames: the spacings the reader keeps
(``sources/spacing.py``) and what they say (``results/log_clock.py``), checked on numbers."""

import math
from pathlib import Path

import can
import numpy as np
import pytest

from app.config import load_config
from app.results.log_clock import clock_notes, clock_problem, sensor_messages
from app.sources.blocks import FrameBlock
from app.sources.logs import LogReport
from app.sources.spacing import SPACINGS_KEPT, FrameSpacing, Spacing

SENSOR_ID = 0x7E5  # Correvit: the Mondeo config's vx, vy and beta


def _block(t: list[float], ids: list[int]) -> FrameBlock:
    n = len(t)
    return FrameBlock(
        t=np.array(t),
        frame_id=np.array(ids),
        extended=np.zeros(n, bool),
        channel=None,
        data=np.zeros((n, 8), np.uint8),
        length=np.full(n, 8),
        fd=np.zeros(n, bool),
    )


def test_frames_and_blocks_give_the_same_spacing_of_each_watched_id() -> None:
    """Consecutive frames of one id, across blocks and frames alike; other ids and times that
    are no number are left out; the busiest id is the one with the most spacings."""
    times = [0.01 * k for k in range(40)]
    ids = [SENSOR_ID if k % 2 else 0x7E4 for k in range(40)]
    by_frame, by_block = (
        FrameSpacing(frozenset({SENSOR_ID, 0x7E4})),
        FrameSpacing(frozenset({SENSOR_ID, 0x7E4})),
    )
    for t, frame_id in zip(times, ids, strict=True):
        by_frame.add(can.Message(timestamp=t, arbitration_id=frame_id))
    by_frame.add(can.Message(timestamp=math.nan, arbitration_id=SENSOR_ID))
    by_frame.add(can.Message(timestamp=5.0, arbitration_id=0x123))  # not watched
    by_frame.add(can.Message(timestamp=0.41, arbitration_id=SENSOR_ID))
    by_block.add(_block(times[:25], ids[:25]))
    by_block.add(_block([*times[25:], math.nan, 5.0, 0.41], [*ids[25:], SENSOR_ID, 0x123, SENSOR_ID]))
    for spacing in (by_frame.busiest(), by_block.busiest()):
        assert spacing is not None and (spacing.frame_id, spacing.spacings) == (SENSOR_ID, 20)
        assert spacing.median == pytest.approx(0.02)
    assert FrameSpacing(frozenset({SENSOR_ID})).busiest() is None  # no frame: no spacing


def test_the_watched_ids_pauses_are_kept_over_the_whole_file_frames_and_blocks_alike() -> None:
    """No watched frame for longer than pause_s, between the last before and the first after —
    past the spacings' cap too; a frame of another id does not end a pause, nor does the first
    frame make one."""
    times = [*(0.02 * k for k in range(SPACINGS_KEPT + 10)), 600.0, 600.02, 601.5]
    ids = [SENSOR_ID] * len(times)
    by_frame, by_block = FrameSpacing(frozenset({SENSOR_ID}), 1.0), FrameSpacing(frozenset({SENSOR_ID}), 1.0)
    for t, frame_id in zip(times, ids, strict=True):
        by_frame.add(can.Message(timestamp=t, arbitration_id=frame_id))
        if t == 600.0:
            by_frame.add(can.Message(timestamp=300.0, arbitration_id=0x123))  # another id's: no end
    by_block.add(_block(times[:5000], ids[:5000]))
    by_block.add(_block([*times[5000:-3], 300.0], [*ids[5000:-3], 0x123]))
    by_block.add(_block(times[-3:], ids[-3:]))
    last = 0.02 * (SPACINGS_KEPT + 9)
    for spacing in (by_frame, by_block):
        assert spacing.pauses == [(pytest.approx(last), 600.0), (600.02, 601.5)]
    unbounded = FrameSpacing(frozenset({SENSOR_ID}))  # no pause_s: none kept
    unbounded.add(_block(times, ids))
    assert unbounded.pauses == []


def test_an_id_is_watched_until_it_has_its_spacings() -> None:
    spacing = FrameSpacing(frozenset({SENSOR_ID}))
    spacing.add(_block([0.02 * k for k in range(SPACINGS_KEPT + 50)], [SENSOR_ID] * (SPACINGS_KEPT + 50)))
    assert spacing.watching == set()
    kept = spacing.busiest()
    assert kept is not None and kept.spacings == SPACINGS_KEPT and kept.median == pytest.approx(0.02)


@pytest.mark.parametrize(
    ("median", "cycle_s", "words"),
    [
        (
            10.0,
            0.02,
            "are 10 s apart (median), where a sensor sends one every 20 ms (its DBC's cycle): "
            "timestamps in milliseconds read as seconds, 1000× too slow — past gap_reset_s (1 s) the filter "
            "restarts at every frame; convert the timestamp column to seconds (÷ 1000)",
        ),
        (
            4.0,
            None,
            "are 4 s apart (median), where a sensor sends one every 4–20 ms: timestamps in "
            "milliseconds read as seconds, 1000× too slow",
        ),
        (
            19_999.25,
            0.02,
            "are 20,000 s apart (median), where a sensor sends one every 20 ms (its DBC's "
            "cycle): timestamps in microseconds read as seconds, 1,000,000× too slow",
        ),
        (1.5e7, None, "timestamps in nanoseconds read as seconds, 10⁹× too slow"),
    ],
)
def test_a_sensor_spaced_past_the_filter_s_restart_names_the_unit_and_the_fix(
    median: float, cycle_s: float | None, words: str
) -> None:
    """The unit is the power of 1000 nearest the spacing over the sensor's cycle (its DBC's,
    else 50–250 Hz): 10 s for a 20-ms cycle is milliseconds, 20,000 s microseconds."""
    why = clock_problem(Spacing(SENSOR_ID, median, 500), 1.0, cycle_s)
    assert why is not None and why.startswith("the optical sensor's frames (id 0x7E5) ") and words in why


def test_a_spacing_within_the_filter_s_restart_or_the_sensor_s_own_says_nothing() -> None:
    """A spacing up to gap_reset_s is not the clock's (the filter bridges it); one of the order of
    the sensor's cycle past a gap_reset_s set shorter than it is the config's, named so (it read
    "the optical data stopped 10343 times" and blamed the driving); one past every unit asks
    about the column."""
    assert clock_problem(Spacing(SENSOR_ID, 0.01, 500), 1.0, 0.02) is None
    assert clock_problem(Spacing(SENSOR_ID, 1.0, 500), 1.0, 0.02) is None
    assert clock_problem(Spacing(SENSOR_ID, math.inf, 500), 1.0, None) is None  # ±1e308 apart
    short = clock_problem(Spacing(SENSOR_ID, 0.02, 500), 0.001, 0.02)
    assert short == (
        "[filter] gap_reset_s = 0.001 s is shorter than the optical sensor's frame spacing (id 0x7E5, "
        "20 ms median): the filter restarts at every frame — set it to 3 of the sensor's cycles or "
        "more (the default is 1 s)"
    )
    # equal to the cycle, half the frames' jitter put them past it: 5,135 restarts, C2n moved 2.5 %
    equal = clock_problem(Spacing(SENSOR_ID, 0.01, 500), 0.01, 0.01)
    assert (
        equal is not None and "0.01 s is within a lost frame of the optical sensor's frame spacing" in equal
    )
    assert "restarts at every late or lost frame" in equal
    assert clock_problem(Spacing(SENSOR_ID, 0.01, 500), 0.03, 0.01) is None  # a lost frame and jitter
    slow = clock_problem(Spacing(SENSOR_ID, 0.2, 500), 0.1, None)  # 22× 50–250 Hz's middle
    assert (
        slow is not None and slow.startswith("[filter] gap_reset_s = 0.1 s is shorter") and "200 ms" in slow
    )
    asked = clock_problem(Spacing(SENSOR_ID, 1e12, 500), 1.0, 0.02)
    assert asked is not None and asked.endswith(
        ": are the timestamps in seconds? past gap_reset_s (1 s) the filter restarts at every "
        "frame — if not, convert them to seconds"
    )
    # a log thinned to a frame every 1.5 s is 75× the cycle, not 1000×: no unit is named for it
    thinned = clock_problem(Spacing(SENSOR_ID, 1.5, 500), 1.0, 0.02)
    assert thinned is not None and "are the timestamps in seconds?" in thinned and "milli" not in thinned


def test_the_sensor_s_ids_and_cycle_come_from_the_config_s_roles_and_dbc() -> None:
    """The Mondeo config's vx, vy and beta are Correvit's, every 20 ms by the Kistler DBC; a note
    for each log whose sensor frames say so (a log without them, or read by no LogSource, none)."""
    config = load_config()
    assert sensor_messages(config) == {SENSOR_ID: 0.02}
    report = LogReport(Path("drive.csv"), spacing=FrameSpacing(frozenset(sensor_messages(config))))
    report.spacing.add(_block([10.0 * k for k in range(5)], [SENSOR_ID] * 5))
    (note,) = clock_notes([report, LogReport(Path("other.csv"))], config)
    assert note.path == Path("drive.csv") and note.done and "1000× too slow" in str(note.stopped)


def test_where_the_watched_clock_goes_back_is_kept_frames_and_blocks_alike() -> None:
    """A second recording appended, or the logger's clock set back: the watched frames' time
    falls more than pause_s below the latest — kept in file order, and the pauses after it are
    measured from there (each tagged with the rewinds before it). A jitter within pause_s is none,
    nor is another id's stray time."""
    first = [0.02 * k for k in range(500)]  # 0–9.98 s
    second = [-300.0 + 0.02 * k for k in range(300)]  # back to −300 s
    times = [*first, 9.5, *second, 100.0, 100.02]  # 9.5: half a second late, no rewind
    ids = [SENSOR_ID] * len(times)
    by_frame, by_block = FrameSpacing(frozenset({SENSOR_ID}), 1.0), FrameSpacing(frozenset({SENSOR_ID}), 1.0)
    for t, frame_id in zip(times, ids, strict=True):
        by_frame.add(can.Message(timestamp=t, arbitration_id=frame_id))
        if t == 5.0:
            by_frame.add(can.Message(timestamp=-500.0, arbitration_id=0x123))  # another id's: none
    by_block.add(_block(times[:400], ids[:400]))
    by_block.add(_block(times[400:], ids[400:]))  # the rewind and the pause after it in one block
    for spacing in (by_frame, by_block):
        assert spacing.rewinds == [(pytest.approx(9.98), -300.0)]
        assert spacing.pauses == [(pytest.approx(-300.0 + 0.02 * 299), 100.0)]
        assert spacing.pause_rewinds == [1]


def test_the_parts_of_a_file_whose_clock_goes_back_follow_the_file_frames_and_blocks_alike() -> None:
    """A file in whose second recording a pause falls: three parts — by order where the clock goes
    back, by time at the pause — every frame of another id with the sensor's frames around it,
    those of the next recording before its sensor's first frame with that recording."""
    from app.results.within_file import Parting

    first = [0.02 * k for k in range(500)]
    second = [-300.0 + 0.02 * k for k in range(300)]
    times = [*first, -300.5, *second, 100.0, 100.02, 99.0]  # the next recording's bus wakes first
    ids = [SENSOR_ID] * len(first) + [0x123] + [SENSOR_ID] * (len(second) + 2) + [0x123]
    spacing = FrameSpacing(frozenset({SENSOR_ID}), 1.0)
    spacing.add(_block(times, ids))
    expected = [0] * len(first) + [1] * (1 + len(second)) + [2, 2, 2]
    assert Parting(spacing)(ids, times).tolist() == expected
    parting = Parting(spacing)
    assert [int(parting([i], [t])[0]) for i, t in zip(ids, times, strict=True)] == expected
    parting = Parting(spacing)
    assert [*parting(ids[:450], times[:450]).tolist(), *parting(ids[450:], times[450:]).tolist()] == expected
    assert Parting(spacing).spans((0.0, 99.0)) == [
        (0.0, pytest.approx(9.98)),
        (-300.5 + 0.5, pytest.approx(-300.0 + 0.02 * 299)),
        (100.0, 99.0),
    ]
