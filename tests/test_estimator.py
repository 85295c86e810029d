"""The Kalman filter stage: the measurement models, time handling, gating and the learned noise,
on both filters (the compiled one the pipeline runs, and the reference on filterpy)."""

import math
from collections.abc import Callable

import numpy as np
import pytest

from app.config import FilterSettings
from app.estimate.compiled import CompiledMotionFilter
from app.estimate.reference import MotionFilter
from app.records import Record

ROLES = frozenset({"vx", "vy", "beta", "yaw_rate", "speed"})
Filter = type[CompiledMotionFilter] | type[MotionFilter]


@pytest.fixture(params=[CompiledMotionFilter, MotionFilter], ids=["compiled", "reference"])
def motion_filter(request: pytest.FixtureRequest) -> Filter:
    return request.param  # type: ignore[no-any-return]


def record(t: float, **signals: float) -> Record:
    return Record(t, 0, 0x7E5, signals)


def steady_stream(
    u: float, v: float, r: float, y_s: float = 0.0, seconds: float = 5.0, hz: float = 100.0
) -> list[Record]:
    vx = u - r * y_s
    return [
        record(k / hz, vx=vx, vy=v, beta=math.atan2(v, vx), yaw_rate=r, speed=u)
        for k in range(int(seconds * hz))
    ]


def test_converges_to_the_motion_and_its_sideslip(motion_filter: Filter) -> None:
    f = motion_filter(FilterSettings(), 0.0, ROLES)
    for rec in steady_stream(12.0, 0.06, 0.15):
        e = f.step(rec)
    assert e is not None
    assert e.u_mps == pytest.approx(12.0, abs=1e-6)
    assert e.v_mps == pytest.approx(0.06, abs=1e-6)
    assert e.r_radps == pytest.approx(0.15, abs=1e-6)
    assert e.sideslip_rad == pytest.approx(math.atan2(0.06, 12.0), abs=1e-7)
    assert e.ay_mps2 == pytest.approx(12.0 * 0.15, rel=1e-6)


def test_lateral_offset_moves_vx_to_the_centre_line(motion_filter: Filter) -> None:
    """A head 0.9 m left of the centre sees vx = u − r·y_s; the filter reports u."""
    f = motion_filter(FilterSettings(), 0.9, ROLES - {"speed"})
    for rec in steady_stream(12.0, 0.0, 0.2, y_s=0.9):
        e = f.step(Record(rec.t, 0, 0, {k: v for k, v in rec.signals.items() if k != "speed"}))
    assert e is not None
    assert e.u_mps == pytest.approx(12.0, abs=1e-5)


def test_angle_alone_gives_lateral_velocity(motion_filter: Filter) -> None:
    """With sideslip_source 'beta' the EKF update recovers v from the angle."""
    f = motion_filter(FilterSettings(sideslip_source="beta"), 0.0, frozenset({"vx", "beta"}))
    for k in range(500):
        e = f.step(record(k / 100, vx=10.0, beta=math.atan2(-0.08, 10.0)))
    assert e is not None
    assert e.v_mps == pytest.approx(-0.08, abs=1e-6)
    assert e.r_radps is None  # no yaw information at all
    assert e.v_meas_mps == pytest.approx(-0.08, abs=1e-9)


def test_time_going_backwards_restarts_the_filter(motion_filter: Filter) -> None:
    f = motion_filter(FilterSettings(), 0.0, ROLES)
    for rec in steady_stream(10.0, 0.0, 0.1, seconds=1.0):
        f.step(rec)
    f.step(record(0.2, vx=20.0, vy=0.0, yaw_rate=0.1))
    assert f.counts.time_jumps == 1
    e = f.step(record(0.21, vx=20.0, vy=0.0, yaw_rate=0.1))
    assert e is not None and e.u_mps == pytest.approx(20.0, abs=0.05)


def test_reversing_with_an_unsigned_wheel_speed_loses_nothing(motion_filter: Filter) -> None:
    """Braking at 3 m/s² through a stop into reversing at 3 m/s, the wheel speed reading |u| (the
    Ford's Veh_V_ActlBrk is unsigned): the speed row was u, so the filter rejected the wheels'
    +3 m/s against the optical −3 and lost the car on them 265 times; it is −u there now."""
    f = motion_filter(FilterSettings(), 0.0, ROLES)
    e = None
    for k in range(3000):
        t = k / 100
        u = 10.0 if t < 5 else max(10.0 - 3.0 * (t - 5), -3.0)
        signals = {"vx": u, "vy": 0.0, "yaw_rate": 0.0} | ({"speed": abs(u)} if k % 2 == 0 else {})
        e = f.step(record(t, **signals))
    assert e is not None and e.u_mps == pytest.approx(-3.0, abs=1e-6)
    assert "speed" not in f.counts.lost


@pytest.mark.parametrize("angle", [math.atan2, lambda v, u: math.atan(v / u)], ids=["atan2", "atan"])
def test_reversing_the_optical_angle_loses_nothing_whichever_quadrant_it_reads(
    motion_filter: Filter, angle: Callable[[float, float], float]
) -> None:
    """Reversing at 3 m/s, the lateral velocity's noise σ 0.02 m/s: a head that reads its angle as
    atan2(vy, vx) flips between +179.6° and −179.6° from frame to frame, one that reads atan(vy/vx)
    (the S-Motion's Angle is ±45°) gives −0.4°…+0.4°. The filter's model was atan2 without its
    innovation wrapped: the first lost the car on the lateral channel at every flip and the second
    throughout (469 times in 12 s of a real-rate drive); both are the same angle modulo 180°."""
    rng = np.random.default_rng(7)
    f = motion_filter(FilterSettings(), 0.0, frozenset({"vx", "beta", "yaw_rate"}))
    e = None
    for k in range(1500):
        u, v = -3.0, rng.normal(0.0, 0.02)
        e = f.step(record(k / 100, vx=u, beta=angle(v, u), yaw_rate=0.0))
    assert e is not None and e.u_mps == pytest.approx(-3.0, abs=0.01)
    assert e.v_mps == pytest.approx(0.0, abs=0.01)
    assert f.counts.lost == {}


def test_optical_dropout_restarts_and_late_frames_are_applied_now(motion_filter: Filter) -> None:
    f = motion_filter(FilterSettings(gap_reset_s=1.0), 0.0, ROLES)
    for rec in steady_stream(10.0, 0.0, 0.1, seconds=1.0):
        f.step(rec)
    f.step(record(0.985, vx=10.0, vy=0.0))  # 5 ms out of order
    assert f.counts.late_frames == 1
    f.step(record(5.0, vx=15.0, vy=0.0))  # 4 s without optical frames
    assert f.counts.resets == 1


def test_a_spike_is_gated_but_a_real_jump_is_believed(motion_filter: Filter) -> None:
    f = motion_filter(FilterSettings(), 0.0, ROLES)
    for rec in steady_stream(10.0, 0.0, 0.1, seconds=2.0):
        f.step(rec)
    e = f.step(record(2.0, yaw_rate=0.9))  # one wild gyro sample
    assert f.counts.outliers == 1
    assert f.counts.lost == {}  # one frame: a glitch, not the car lost
    assert e is not None and e.r_radps == pytest.approx(0.1, abs=1e-3)
    for k in range(1, 20):  # the gyro insists: the model lost the car, believe the sensor
        e = f.step(record(2.0 + k / 100, yaw_rate=0.9))
    assert e is not None and e.r_radps == pytest.approx(0.9, abs=0.05)
    assert set(f.counts.lost) == {"yaw"}  # believed from the fourth frame beyond the gate on


def test_health_is_about_one_when_the_noise_model_fits(motion_filter: Filter) -> None:
    rng = np.random.default_rng(3)
    sigma = 0.02
    f = motion_filter(
        FilterSettings(sigma_velocity_mps=sigma, sideslip_source="vy"), 0.0, frozenset({"vx", "vy"})
    )
    healths = []
    for k in range(6000):
        e = f.step(record(k / 100, vx=12.0 + rng.normal(0, sigma), vy=0.05 + rng.normal(0, sigma)))
        if k > 1000 and e is not None:
            healths.append(e.health)
    assert 0.8 < float(np.mean(healths)) < 1.2
    # a config that claims 4× less noise reads far worse at first, until the noise model learns
    g = motion_filter(
        FilterSettings(sigma_velocity_mps=sigma / 4, sideslip_source="vy"), 0.0, frozenset({"vx", "vy"})
    )
    early = []
    for k in range(6000):
        e = g.step(record(k / 100, vx=12.0 + rng.normal(0, sigma), vy=0.05 + rng.normal(0, sigma)))
        if e is not None and 50 < k < 150:
            early.append(e.health)
    assert max(early) > 3.0
    assert e is not None and 0.7 < e.health < 1.5
    assert g.noise_sigma()["lateral_mps"] == pytest.approx(sigma, rel=0.25)


def test_measured_noise_follows_the_sensor(motion_filter: Filter) -> None:
    """The noise model learns the optical noise from the innovations, whatever was configured."""
    for sigma in (0.005, 0.05):
        rng = np.random.default_rng(9)
        f = motion_filter(
            FilterSettings(sigma_velocity_mps=0.02, sideslip_source="vy"), 0.0, frozenset({"vx", "vy"})
        )
        for k in range(8000):
            f.step(record(k / 100, vx=12.0 + rng.normal(0, sigma), vy=0.05 + rng.normal(0, sigma)))
        measured = f.noise_sigma()
        assert abs(measured["vx_mps"] / sigma - 1) < 0.25, measured
        assert abs(measured["lateral_mps"] / sigma - 1) < 0.25, measured


def test_resolution_floor_keeps_a_noise_free_quantised_signal_sane(motion_filter: Filter) -> None:
    """Noise-free values on a 0.01 m/s grid: the noise model never claims less than one bit's
    quantisation (0.01/√12 m/s), so the filter stays consistent and converges."""
    f = motion_filter(
        FilterSettings(sideslip_source="vy"),
        0.0,
        frozenset({"vx", "vy"}),
        resolutions={"vx": 0.01, "vy": 0.01},
    )
    for k in range(5000):
        u = 10.0 + 0.3 * k / 100
        e = f.step(record(k / 100, vx=round(u, 2), vy=round(0.0337 * u, 2)))
    assert e is not None and e.health < 5.0
    assert e.u_mps == pytest.approx(10.0 + 0.3 * 4999 / 100, abs=0.01)
