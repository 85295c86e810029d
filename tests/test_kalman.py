"""The compiled motion filter against the reference on filterpy's KalmanFilter: the same numbers
over whole drives, and one step by hand."""

import dataclasses
import math

import numpy as np
import pytest
from filterpy.common import Q_continuous_white_noise
from scipy.linalg import block_diag

from app.config import FilterSettings, load_config
from app.decode.decoder import Decoder
from app.estimate import compiled
from app.estimate.compiled import CompiledMotionFilter
from app.estimate.motion_model import transition
from app.estimate.reference import FilterpyKalman, MotionFilter
from app.records import Record
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
    """A prediction and a frame of three measurements (vx with the lateral offset, v, r), through
    the compiled kernel's predict and scalar updates and through filterpy's joint update."""
    rows = [(12.1, (1.0, 0.0, -0.4), 4e-4), (0.3, (0.0, 1.0, 0.0), 1e-4), (0.2, (0.0, 0.0, 1.0), 1e-6)]
    x0, p0 = [12.0, 0.1, 0.2, 0.0, 0.15, 0.0], [0.01, 1.0, 0.01, 0.25, 0.0025, 0.01]
    reference = FilterpyKalman(*Q)
    reference.reset(x0, p0)
    reference.predict(0.004)
    reference.update(rows)
    state, params = np.zeros(compiled._N_STATE), np.zeros(compiled._N_PARAMS)
    params[[compiled._QU, compiled._QV, compiled._QR]] = Q
    state[:6], state[6:42] = x0, np.diag(p0).ravel()
    compiled._predict(state, params, 0.004)
    innovation, _ = compiled._innovation(state, 12.1, 1.0, 0.0, -0.4)
    assert innovation == pytest.approx(0.1 + 0.4 * 0.15 - 0.0004)  # x = F·x: u gained dt·u̇
    for z, (hu, hv, hr), r in rows:
        compiled._scalar_update(state, z, hu, hv, hr, r)
    x_ref, p_ref = reference.state()
    np.testing.assert_allclose(state[:6], x_ref, rtol=0, atol=1e-12)
    np.testing.assert_allclose(state[6:42].reshape(6, 6), p_ref, rtol=0, atol=1e-12)
    assert state[0] != pytest.approx(12.0004, abs=1e-6)  # the frame moved the state


def _disturbed(records: list[Record]) -> list[Record]:
    """The drive with what a real bus brings: gyro spikes, an optical dropout (a restart), frames
    out of order by a few ms, and the log's time jumping back (another restart)."""
    out: list[Record] = []
    start = records[0].t
    for k, record in enumerate(records):
        since = record.t - start
        signals = dict(record.signals)
        if "yaw_rate" in signals and k % 997 == 0:
            signals["yaw_rate"] += 0.8
        if 20.0 < since < 21.5 and {"vx", "vy", "beta"} & signals.keys():
            continue
        t = record.t - 0.004 if k % 1511 == 0 else record.t
        out.append(Record(t - 30.0 if since > 40.0 else t, record.channel, record.frame_id, signals))
    return out


def _settings(name: str) -> FilterSettings:
    return {
        "default": FilterSettings(),
        "vy": FilterSettings(sideslip_source="vy"),
        "beta, fixed σ": FilterSettings(sideslip_source="beta", sigma_beta_deg=0.05),
        "too slow": FilterSettings(q_u=1e-7, q_r=1e-9),  # cannot follow the sweep or the turn-in
    }[name]


@pytest.mark.parametrize(
    ("scenario", "lateral_m", "settings", "roles_dropped", "disturbed"),
    [
        ("constant_radius", 0.0, "default", (), False),
        ("radii", 0.0, "vy", (), True),
        ("step_steer", 0.45, "default", (), True),
        ("constant_radius", 0.45, "beta, fixed σ", ("yaw_rate",), True),  # r from a_y/u
        ("constant_radius", 0.0, "default", ("yaw_rate", "ay"), False),  # no yaw information
        ("step_steer", 0.0, "too slow", (), False),  # the model loses the car
    ],
)
def test_the_compiled_filter_gives_filterpys_estimates_over_a_drive(
    scenario: str, lateral_m: float, settings: str, roles_dropped: tuple[str, ...], disturbed: bool
) -> None:
    """Every estimate of a whole drive (gating, learned noise, angle linearisation, late frames,
    restarts included) within 1e-9 of the reference filter on filterpy's KalmanFilter."""
    config = load_config()
    decoder = Decoder(config)
    records = [r for r in map(decoder.decode, cached_drive(scenario).messages) if r is not None]
    records = [
        Record(r.t, r.channel, r.frame_id, {k: v for k, v in r.signals.items() if k not in roles_dropped})
        for r in (_disturbed(records) if disturbed else records)
    ]
    roles = frozenset(config.roles) - set(roles_dropped)
    resolutions = {role: spec.resolution for role, spec in config.roles.items()}
    chosen = dataclasses.replace(config.filter, **dataclasses.asdict(_settings(settings)))
    fast = CompiledMotionFilter(chosen, lateral_m, roles, resolutions)
    reference = MotionFilter(chosen, lateral_m, roles, resolutions)
    compared = 0
    for record in records:
        estimate, expected = fast.step(record), reference.step(record)
        assert (estimate is None) == (expected is None)
        if estimate is None or expected is None:
            continue
        for name, value in estimate._asdict().items():
            other = getattr(expected, name)
            if value is None or other is None:
                assert value is other, name
            else:
                assert value == pytest.approx(other, rel=0, abs=1e-9), name
        compared += 1
    assert compared > 1000
    assert fast.counts == reference.counts
    if disturbed:
        counts = fast.counts
        assert (
            counts.resets >= 2 and counts.time_jumps == 1 and counts.late_frames > 0 and counts.outliers > 0
        )
    # A spike is one frame and a dropout a restart: neither loses the car. A model too slow for the
    # drive does, and so does a fixed σ_β of 0.05° (not learned) at the turn-in's sideslip
    # transient, twice, disturbed or not.
    assert bool(fast.counts.lost) == (settings in ("too slow", "beta, fixed σ"))
    assert fast.noise_sigma() == pytest.approx(reference.noise_sigma(), rel=1e-9)
    assert fast.health == pytest.approx(reference.health, rel=1e-9)
    for ours, theirs in zip(fast.state(), reference.state(), strict=True):
        np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-9)
    for ours, theirs in zip(fast.last_transition, reference.last_transition, strict=True):
        np.testing.assert_array_equal(ours, theirs)
    assert math.isfinite(fast.health)


def test_the_step_is_compiled_once_for_floats_and_takes_ints() -> None:
    """A signal that arrives as an int gives the float's estimate and no second compilation
    (which would stall a live drive for seconds)."""
    signals = {"vx": 12.0, "vy": 0.0, "yaw_rate": 0.0, "speed": 12.0}
    estimates = []
    for values in (signals, {k: int(v) for k, v in signals.items()}):
        motion = CompiledMotionFilter(FilterSettings(), 0.0, frozenset(signals))
        motion.step(Record(0.0, 0, 0x7E5, values))
        estimates.append(motion.step(Record(0.01, 0, 0x7E5, values)))
    assert estimates[0] == estimates[1]
    assert estimates[0] is not None and estimates[0].u_mps == pytest.approx(12.0)
    assert len(compiled._step.signatures) == 1  # type: ignore[attr-defined]
