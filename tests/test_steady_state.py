"""The steady-state gate: each limit, settling, debouncing of the noisy rate limits, direction."""

import math

import numpy as np

from app.config import DetectorSettings
from app.detect.steady_state import SteadyStateGate
from app.records import Estimate


def est(
    u: float = 12.0,
    radius: float = 80.0,
    u_dot: float = 0.2,
    v_dot: float = 0.0,
    r_dot: float = 0.0,
    yaw: bool = True,
    ay: float | None = None,
) -> Estimate:
    r = u / radius
    return Estimate(
        u_mps=u,
        u_dot_mps2=u_dot,
        v_mps=0.0,
        v_dot_mps2=v_dot,
        r_radps=r if yaw else None,
        r_dot_radps2=r_dot if yaw else None,
        sideslip_rad=0.0,
        sideslip_sigma_rad=1e-4,
        ay_mps2=u * r if yaw else ay,
        health=1.0,
    )


def settle(gate: SteadyStateGate, e: Estimate, seconds: float = 2.0, t0: float = 0.0) -> float:
    t = t0
    while t < t0 + seconds:
        gate.step(t, e, None, None)
        t += 0.01
    return t


def test_steady_after_settling_and_direction_from_yaw() -> None:
    gate = SteadyStateGate(DetectorSettings(settle_s=1.0))
    first = gate.step(0.0, est(), None, None)
    assert not first.steady and first.reasons[0].startswith("settling")
    assert not gate.step(0.99, est(), None, None).steady
    state = gate.step(1.0, est(), None, None)
    assert state.steady and state.direction == "left"
    assert gate.step(1.01, est(radius=-80.0), None, None).direction == "right"


def test_each_hard_limit_has_its_reason() -> None:
    s = DetectorSettings()
    cases = {
        "lateral acceleration too high: 4.5 m/s² > 4": est(u=15.0, radius=50.0),
        "speed 3.0 m/s below 4": est(u=3.0),
        "driving straight (radius over 500 m)": est(radius=800.0),
        "radius under 22 m (eight wheelbases)": est(u=5.0, radius=8.0),
    }
    for reason, e in cases.items():
        gate = SteadyStateGate(s)
        t = settle(gate, est())
        state = gate.step(t, e, None, None)
        assert not state.steady and reason in state.reasons, (reason, state.reasons)
        assert gate.step(t + 0.01, est(), None, None).reasons[0].startswith("settling")  # starts over
    state = SteadyStateGate(s).step(0.0, est(), None, "Status.HeadStatus=0 (needs 1)")
    assert "sensor: Status.HeadStatus=0 (needs 1)" in state.reasons


def test_a_brief_rate_excursion_drops_its_samples_but_not_the_spell() -> None:
    gate = SteadyStateGate(DetectorSettings(debounce_s=0.3, sweep_max_mps2=0.6))
    t = settle(gate, est())
    for k in range(10):  # 0.1 s of a noisy sweep-rate estimate
        state = gate.step(t + k * 0.01, est(u_dot=0.7), None, None)
        assert not state.steady and state.reasons[0].startswith("sweep too fast")
    assert gate.step(t + 0.11, est(), None, None).steady  # no new settling
    for k in range(50):  # 0.5 s of a real transient
        gate.step(t + 0.2 + k * 0.01, est(v_dot=0.5), None, None)
    assert gate.step(t + 0.8, est(), None, None).reasons[0].startswith("settling")


def test_without_yaw_rate_direction_and_limits_come_from_ay_or_steer() -> None:
    gate = SteadyStateGate(DetectorSettings())
    state = gate.step(0.0, est(yaw=False, ay=-1.5), None, None)
    assert state.direction == "right"
    state = gate.step(0.0, est(yaw=False, ay=None), math.radians(30), None)
    assert state.direction == "left"
    state = gate.step(0.0, est(yaw=False, ay=None), None, None)
    assert state.direction is None and not any("straight" in r for r in state.reasons)


def test_the_quick_check_agrees_with_the_worded_reasons_on_every_limit() -> None:
    """``_all_hold`` (no words, the common case) is true exactly when neither list of reasons
    has one: on estimates spread over every limit, each side of it, with and without a yaw rate."""
    rng = np.random.default_rng(7)
    gate = SteadyStateGate(DetectorSettings())
    agreed = {True: 0, False: 0}
    for _ in range(5000):
        yaw = bool(rng.random() < 0.7)
        e = est(
            u=float(rng.uniform(-1.0, 30.0)),
            radius=float(rng.choice([-1.0, 1.0]) * rng.uniform(5.0, 400.0)),
            u_dot=float(rng.normal(0.0, 0.2)),
            v_dot=float(rng.normal(0.0, 0.5)),
            r_dot=float(rng.normal(0.0, 0.1)),
            yaw=yaw,
            ay=None if rng.random() < 0.3 else float(rng.normal(0.0, 4.0)),
        )
        worded = not gate._hard_reasons(e, None) and not gate._soft_reasons(e)
        assert gate._all_hold(e) == worded, e
        agreed[worded] += 1
    assert min(agreed.values()) > 500, agreed  # both verdicts were exercised
