"""Replay pacing and looping, with a fake clock (no real waiting)."""

import can
import pytest

from app.sources.playback import looped, paced


class FakeClock:
    def __init__(self) -> None:
        self.now = 100.0
        self.sleeps: list[float] = []

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.sleeps.append(seconds)
        self.now += seconds


def messages(times: list[float]) -> list[can.Message]:
    return [can.Message(timestamp=t, arbitration_id=1) for t in times]


def test_paced_keeps_recorded_gaps_scaled_by_rate() -> None:
    clock = FakeClock()
    out = [m.timestamp for m in paced(messages([10.0, 10.5, 11.5]), rate=2.0, clock=clock, sleep=clock.sleep)]
    assert out == [10.0, 10.5, 11.5]
    assert clock.sleeps == pytest.approx([0.25, 0.5])


def test_long_gaps_are_shortened() -> None:
    clock = FakeClock()
    list(paced(messages([0.0, 100.0, 101.0]), rate=1.0, clock=clock, sleep=clock.sleep, max_wait_s=2.0))
    assert clock.sleeps == pytest.approx([2.0, 1.0])


def test_a_clock_going_back_keeps_the_pace_it_had() -> None:
    """Two logs joined, the second's clock 300 s behind: its frames went out at once, 300 s of
    driving in a burst, until their times caught up. Now they go on at their own pace."""
    clock = FakeClock()
    list(paced(messages([400.0, 401.0, 100.0, 100.5, 101.5]), rate=1.0, clock=clock, sleep=clock.sleep))
    assert clock.sleeps == pytest.approx([1.0, 0.5, 1.0])  # the frame at 100 s right after 401's


def test_a_frame_without_a_time_goes_at_once_and_moves_no_clock() -> None:
    """A first frame timed NaN made every frame's due time NaN: the whole log in one burst."""
    clock = FakeClock()
    list(
        paced(
            messages([float("nan"), 10.0, 10.5, float("nan"), 11.5]), rate=1.0, clock=clock, sleep=clock.sleep
        )
    )
    assert clock.sleeps == pytest.approx([0.5, 1.0])


def test_rate_must_be_positive() -> None:
    with pytest.raises(ValueError):
        list(paced(messages([0.0]), rate=0.0))


def test_looped_timestamps_keep_rising() -> None:
    out = [m.timestamp for m in looped(lambda: messages([5.0, 6.0]), loops=3)]
    assert out == pytest.approx([5.0, 6.0, 6.01, 7.01, 7.02, 8.02])
    assert out == sorted(out)
