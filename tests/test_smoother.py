"""The offline RTS smoother (filterpy) against the simulated truth."""

import numpy as np

from app.config import Config
from app.estimate.smoother import smooth
from app.sim.sensors import LOG_START
from tests.simulated import cached_drive


def truth_at(drive_t: np.ndarray, trace_t: np.ndarray, values: np.ndarray) -> np.ndarray:
    return np.asarray(np.interp(drive_t - LOG_START, trace_t, values))


def test_smoothing_halves_the_filter_error(config: Config) -> None:
    drive = cached_drive()
    trace = drive.trace
    assert trace is not None
    [track] = smooth(config, drive.messages)
    truths = {
        0: trace.u,
        2: trace.lateral_velocity_at(config.d_m - trace.params.b_m),
        4: trace.r,
    }
    for index, values in truths.items():
        reference = truth_at(track.t, trace.t, values)
        filtered = np.sqrt(np.mean((track.filtered[:, index] - reference) ** 2))
        smoothed = np.sqrt(np.mean((track.smoothed[:, index] - reference) ** 2))
        assert smoothed < 0.7 * filtered, (index, filtered, smoothed)
    assert np.allclose(track.smoothed[-1], track.filtered[-1])  # the last step has no future


def test_chunks_give_the_same_smoothing(config: Config) -> None:
    messages = cached_drive().messages[:15000]
    [whole] = smooth(config, messages)
    [chunked] = smooth(config, messages, chunk=1500, overlap=600)
    assert np.max(np.abs(chunked.smoothed - whole.smoothed)) < 1e-6
