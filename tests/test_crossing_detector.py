"""Crossing detection and the local fit, on synthetic steady cornering from eq. 6."""

import math
from collections.abc import Iterator

import numpy as np
import pytest

from app import paper
from app.config import DetectorSettings
from app.detect.crossings import CrossingDetector
from app.records import Crossing, CrossingRejected, Estimate, Event, SignChange, SteadyState
from app.results.turn_step import without_step

C2N, D, G = 14.99, 1.11, 9.81
U0 = paper.crossing_speed(C2N, D, G)


def estimate(u: float, radius: float, noise: float = 0.0, yaw: bool = True, sigma: float = 2e-4) -> Estimate:
    v = u * paper.sideslip_at_sensor(u, radius, D, C2N, G)  # eq. 6 is v/u: linear in the model
    beta = math.atan2(v, u)
    r = u / radius
    v_meas = v + noise
    return Estimate(
        u_mps=u,
        u_dot_mps2=0.2,
        v_mps=v,
        v_dot_mps2=0.0,
        r_radps=r if yaw else None,
        r_dot_radps2=0.0 if yaw else None,
        sideslip_rad=beta,
        sideslip_sigma_rad=sigma,
        ay_mps2=u * r,
        health=1.0,
        v_meas_mps=v_meas,
        sideslip_meas_rad=math.atan2(v_meas, u),
    )


def sweep(u_from: float, u_to: float, radius: float, hz: float = 100.0, rate: float = 0.3) -> Iterator[float]:
    n = int(abs(u_to - u_from) / rate * hz)
    yield from np.linspace(u_from, u_to, n)


def run(
    detector: CrossingDetector,
    speeds: Iterator[float],
    radius: float,
    t0: float = 0.0,
    noise: float = 0.0,
    yaw: bool = True,
    seed: int = 0,
) -> tuple[list[Event], float]:
    rng = np.random.default_rng(seed)
    events: list[Event] = []
    t = t0
    direction = "left" if radius > 0 else "right"
    for u in speeds:
        e = estimate(float(u), radius, float(rng.normal(0, noise)) if noise else 0.0, yaw)
        events += detector.step(t, e, SteadyState(True, direction if yaw else None))  # type: ignore[arg-type]
        t += 0.01
    return events, t


def crossings(events: list[Event]) -> list[Crossing]:
    return [e for e in events if isinstance(e, Crossing)]


@pytest.mark.parametrize("radius", [60.0, -100.0, 250.0])
def test_noise_free_sweep_gives_eq7_exactly(radius: float) -> None:
    detector = CrossingDetector(DetectorSettings(), D, G)
    events, _ = run(detector, sweep(0.7 * U0, 1.3 * U0, radius), radius)
    assert any(isinstance(e, SignChange) for e in events)
    [c] = crossings(events)
    assert c.u0_mps == pytest.approx(U0, rel=1e-9)
    assert c.c2n == pytest.approx(C2N, rel=1e-9)
    assert c.method == "v/r" and c.sweep == "up" and c.direction == ("left" if radius > 0 else "right")
    assert c.ay_mps2 == pytest.approx(U0 * U0 / abs(radius), rel=0.01)


def test_without_yaw_rate_fits_the_sideslip_and_infers_the_direction() -> None:
    detector = CrossingDetector(DetectorSettings(), D, G)
    events, _ = run(detector, sweep(1.3 * U0, 0.7 * U0, -80.0), -80.0, yaw=False)
    [c] = crossings(events)
    assert c.method == "beta" and c.direction == "right" and c.sweep == "down"
    assert c.c2n == pytest.approx(C2N, rel=1e-9)


def test_noisy_crossing_lies_within_its_interval() -> None:
    hits = 0
    for seed in range(20):
        detector = CrossingDetector(DetectorSettings(), D, G)
        events, _ = run(detector, sweep(0.7 * U0, 1.3 * U0, 80.0), 80.0, noise=0.02, seed=seed)
        [c] = crossings(events)
        assert abs(c.c2n / C2N - 1) < 0.02
        hits += c.ci95[0] <= C2N <= c.ci95[1]
    assert hits >= 17


def test_up_then_down_gives_two_crossings_and_reversal_splits_the_runs() -> None:
    detector = CrossingDetector(DetectorSettings(), D, G)
    up, t = run(detector, sweep(0.7 * U0, 1.3 * U0, 80.0), 80.0)
    down, _ = run(detector, sweep(1.3 * U0, 0.7 * U0, 80.0), 80.0, t0=t)
    found = crossings(up + down)
    assert [c.sweep for c in found] == ["up", "down"]
    assert all(c.c2n == pytest.approx(C2N, rel=1e-9) for c in found)


def test_constant_speed_circle_never_gives_a_crossing() -> None:
    """Driving a circle at u0 with noisy sideslip flips the sign, but u² does not vary: no fit."""
    detector = CrossingDetector(DetectorSettings(hysteresis_sigmas=0.0), D, G)
    events, _ = run(detector, iter([U0] * 3000), 80.0, noise=0.02)
    events += detector.finish()
    assert not crossings(events)


def test_step_steer_plateaus_use_a_wider_window() -> None:
    """Steady plateaus 1.1 m/s apart with transients between (not steady) still give eq. 7."""
    detector = CrossingDetector(DetectorSettings(), D, G)
    events: list[Event] = []
    t = 0.0
    for u in np.arange(0.65, 1.36, 0.0875) * U0:
        for _ in range(300):
            events += detector.step(t, estimate(float(u), 80.0 * u / U0), SteadyState(True, "left"))
            t += 0.01
        t += 6.0  # straight between steps
    events += detector.finish()
    [c] = crossings(events)
    assert c.c2n == pytest.approx(C2N, rel=1e-6)


def test_pending_sign_change_is_fitted_at_the_end_of_input() -> None:
    detector = CrossingDetector(DetectorSettings(), D, G)
    events, _ = run(detector, sweep(0.8 * U0, 1.1 * U0, 80.0), 80.0)  # stops 1.3 m/s past u0
    assert not crossings(events) and detector.pending
    [c] = crossings(detector.finish())
    assert c.c2n == pytest.approx(C2N, rel=1e-9)


def test_a_second_sign_change_in_one_sweep_is_not_used() -> None:
    detector = CrossingDetector(DetectorSettings(), D, G)
    _, t = run(detector, sweep(0.7 * U0, 1.3 * U0, 80.0), 80.0)
    # the sideslip flips back while the speed keeps rising (a transient the gate let through)
    flipped = estimate(1.31 * U0, 80.0)
    flipped = flipped._replace(sideslip_rad=0.01)
    later = detector.step(t, flipped, SteadyState(True, "left"))
    assert [type(e) for e in later] == [CrossingRejected]
    assert "second sign change" in later[0].reason  # type: ignore[union-attr]


def test_a_slope_the_regression_found_is_taken_out_of_the_crossing() -> None:
    """A pad sloping so that the sideslip gains A·sin ψ + B·cos ψ as the heading ψ turns: told
    the slope (the regression's terms), the local fit finds eq. 7's u0 exactly; not told, the
    crossing carries the slope's pull at the headings it was driven through."""
    tilt_a, tilt_b, radius = 0.0012, -0.0007, 80.0
    found: dict[bool, Crossing] = {}
    for told in (False, True):
        detector = CrossingDetector(DetectorSettings(), D, G)
        detector.tilt = (tilt_a, tilt_b, 0.0, 0.0) if told else None
        events: list[Event] = []
        t = heading = 0.0
        for u in sweep(0.7 * U0, 1.3 * U0, radius):
            e = estimate(float(u), radius)
            pull = tilt_a * math.sin(heading) + tilt_b * math.cos(heading)
            v = e.v_meas_mps + e.u_mps * pull
            e = e._replace(
                v_meas_mps=v, sideslip_meas_rad=math.atan2(v, e.u_mps), sideslip_rad=e.sideslip_rad + pull
            )
            events += detector.step(t, e, SteadyState(True, "left"), heading)
            t += 0.01
            heading += e.r_radps * 0.01
        events += detector.finish()
        (found[told],) = [event for event in events if isinstance(event, Crossing)]
    assert found[True].slope_corrected and not found[False].slope_corrected
    assert found[True].c2n == pytest.approx(C2N, rel=1e-6)
    assert abs(found[False].c2n / C2N - 1) > 0.01


def test_a_turn_step_the_regression_found_is_taken_out_of_every_crossing() -> None:
    """A force that follows the turn adds a step δ·sign(κ) to the sideslip at every speed: on a
    circle of radius R the sign change moves to u0² = g·C2n·(d + δ·R), both ways round (a yawed
    head moves them apart and the pairing cancels it; a step it cannot). Told δ afterwards, each
    crossing reads eq. 7's C2n exactly, its error widened by δ's own: C2n·R/d per radian."""
    step, radius = 0.0009, 80.0
    read: dict[str, Crossing] = {}
    for direction, signed in (("left", radius), ("right", -radius)):
        detector = CrossingDetector(DetectorSettings(), D, G)
        events: list[Event] = []
        t = 0.0
        for u in sweep(0.7 * U0, 1.3 * U0, radius):
            e = estimate(float(u), signed)
            v = e.v_meas_mps + e.u_mps * step * (1 if signed > 0 else -1)  # δ·sign(κ) in β = v/u
            e = e._replace(
                v_meas_mps=v, sideslip_meas_rad=math.atan2(v, e.u_mps), sideslip_rad=math.atan2(v, e.u_mps)
            )
            events += detector.step(t, e, SteadyState(True, direction))  # type: ignore[arg-type]
            t += 0.01
        events += detector.finish()
        (read[direction],) = [event for event in events if isinstance(event, Crossing)]
    for crossing in read.values():
        assert crossing.c2n == pytest.approx(C2N * (1 + step * radius / D), rel=1e-6)  # the step's share
        assert crossing.u0sq_per_step == pytest.approx(-radius * G * C2N, rel=1e-6)
        fixed = without_step(crossing, step, 0.0, D, G)
        assert fixed.step_corrected and fixed.c2n == pytest.approx(C2N, rel=1e-6)
        assert fixed.u0_mps == pytest.approx(U0, rel=1e-6)
        widened = without_step(crossing, step, 1e-4, D, G)
        assert widened.c2n_se == pytest.approx(math.hypot(crossing.c2n_se, 1e-4 * radius * C2N / D), rel=1e-6)
        assert widened.ci95[0] < C2N < widened.ci95[1]
