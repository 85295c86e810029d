"""The fast Kalman kernel against filterpy's KalmanFilter: the same numbers over whole drives."""

import numpy as np
import pytest
from filterpy.common import Q_continuous_white_noise
from scipy.linalg import block_diag

from app.config import load_config
from app.decode import Decoder
from app.estimator import MotionFilter
from app.kalman import FilterpyKalman, PairKalman, transition
from tests.simulated import cached_drive

Q = (0.05, 0.02, 0.5)


def test_transition_equals_filterpy_reference() -> None:
    for dt in (0.004, 0.02, 0.5):
        f, q = transition(dt, *Q)
        reference_q = block_diag(*(Q_continuous_white_noise(2, dt, d) for d in Q))
        reference_f = block_diag(*([np.array([[1.0, dt], [0.0, 1.0]])] * 3))
        np.testing.assert_allclose(q, reference_q, rtol=0, atol=1e-18)
        np.testing.assert_allclose(f, reference_f, rtol=0, atol=0)


def test_one_step_equals_filterpy() -> None:
    """A prediction and a frame of three measurements (vx with the lateral offset, v, r)."""
    rows = [(12.1, (1.0, 0.0, -0.4), 4e-4), (0.3, (0.0, 1.0, 0.0), 1e-4), (0.2, (0.0, 0.0, 1.0), 1e-6)]
    fast, reference = PairKalman(*Q), FilterpyKalman(*Q)
    for kalman in (fast, reference):
        kalman.reset([12.0, 0.1, 0.2, 0.0, 0.15, 0.0], [0.01, 1.0, 0.01, 0.25, 0.0025, 0.01])
        kalman.predict(0.004)
        assert kalman.innovation(12.1, (1.0, 0.0, -0.4))[0] == pytest.approx(0.1 + 0.4 * 0.15 - 0.0004)
        kalman.update(rows)
    (x, p), (x_ref, p_ref) = fast.state(), reference.state()
    np.testing.assert_allclose(x, x_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(p, p_ref, rtol=0, atol=1e-12)
    assert x[0] != pytest.approx(12.0004, abs=1e-6)  # the frame moved the state


@pytest.mark.parametrize(
    ("scenario", "lateral_m"), [("constant_radius", 0.0), ("radii", 0.0), ("step_steer", 0.45)]
)
def test_the_motion_filter_gives_filterpys_estimates_over_a_drive(scenario: str, lateral_m: float) -> None:
    """Every estimate of a whole drive (gating, learned noise, angle linearisation, resets
    included) within 1e-9 of the filter run on filterpy's KalmanFilter."""
    config = load_config()
    drive = cached_drive(scenario)
    decoder = Decoder(config)
    records = [r for r in map(decoder.decode, drive.messages) if r is not None]
    resolutions = {role: spec.resolution for role, spec in config.roles.items()}
    filters = [
        MotionFilter(config.filter, lateral_m, frozenset(config.roles), resolutions, kalman=kalman)
        for kalman in (PairKalman, FilterpyKalman)
    ]
    compared = 0
    for record in records:
        fast, reference = (f.step(record) for f in filters)
        assert (fast is None) == (reference is None)
        if fast is None or reference is None:
            continue
        for name, value in fast._asdict().items():
            other = getattr(reference, name)
            if value is None or other is None:
                assert value is other, name
            else:
                assert value == pytest.approx(other, rel=0, abs=1e-9), name
        compared += 1
    assert compared > 1000
    assert filters[0].counts == filters[1].counts
    assert filters[0].noise_sigma() == pytest.approx(filters[1].noise_sigma(), rel=1e-9)
