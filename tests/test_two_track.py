"""The two-track model against closed forms: the paper's eq. 6 with every effect off, and each
vehicle or road effect by the amount its parameter says."""

import math
from dataclasses import replace

import numpy as np
import pytest

from app import paper
from app.config import Config
from app.sim.effects import EFFECTS, Effect, apply_to_vehicle
from app.sim.scenarios import Scenario, Segment, Steer, SweepPlan, constant_radius
from app.sim.two_track import TwoTrackParams, TwoTrackTrace, simulate_two_track


@pytest.fixture(scope="module")
def car(config: Config) -> TwoTrackParams:
    return TwoTrackParams.from_config(config)


def circle(params: TwoTrackParams, u: float, radius: float, hold_s: float = 12.0) -> TwoTrackTrace:
    """Straight for 2 s, then a constant radius at constant speed."""
    segments = (Segment(2.0, u, Steer("straight")), Segment(hold_s, u, Steer("radius", radius)))
    return simulate_two_track(params, Scenario("circle", u, segments), 15.0)


def straight(params: TwoTrackParams, u: float, duration_s: float = 30.0) -> TwoTrackTrace:
    return simulate_two_track(
        params, Scenario("straight", u, (Segment(duration_s, u, Steer("straight")),)), 15.0
    )


def last(trace: TwoTrackTrace, seconds: float = 3.0) -> np.ndarray:
    return np.asarray(trace.t > trace.t[-1] - seconds)


def rear_slip(trace: TwoTrackTrace, params: TwoTrackParams) -> np.ndarray:
    """α2 = δ2 − (v − b·r)/u (the bicycle model's rear slip angle)."""
    return np.asarray(trace.delta_rear - (trace.v - params.b_m * trace.r) / trace.u)


def test_axle_stiffnesses_equal_the_truth_at_small_lateral_acceleration(car: TwoTrackParams) -> None:
    trace = circle(car, 8.0, 150.0)  # 0.43 m/s²
    steady = last(trace)
    assert abs(np.mean(trace.ay[steady])) < 0.5
    forces = trace.tyre_force_n[steady]
    alpha1 = trace.delta - (trace.v + car.a_m * trace.r) / trace.u
    c1n = np.mean(forces[:, 0] + forces[:, 1]) / np.mean(alpha1[steady]) / car.w1_n
    c2n = np.mean(forces[:, 2] + forces[:, 3]) / np.mean(rear_slip(trace, car)[steady]) / car.w2_n
    assert c2n == pytest.approx(car.c2n, rel=2e-3)
    assert c1n == pytest.approx(car.c1n, rel=2e-3)


@pytest.mark.parametrize("u", [8.0, 14.0])
@pytest.mark.parametrize("radius", [150.0, -150.0])
def test_steady_sideslip_at_the_sensor_is_eq6(
    config: Config, car: TwoTrackParams, u: float, radius: float
) -> None:
    """β_d = d/R − u²/(R·g·C2n) within 0.003° (a third of the sensor's Angle resolution) up to 1.3 m/s²."""
    trace = circle(car, u, radius)
    steady = last(trace)
    x_s = config.d_m - car.b_m
    beta_d = np.mean(trace.lateral_velocity_at(x_s, config.vehicle.sensor_height_m)[steady] / trace.u[steady])
    driven_radius = float(np.mean(trace.u[steady] / trace.r[steady]))
    assert driven_radius == pytest.approx(radius, rel=2e-3)  # the driver holds the circle
    expected = paper.sideslip_at_sensor(u, driven_radius, config.d_m, car.c2n, car.g)
    assert beta_d == pytest.approx(expected, abs=5e-5)


def test_sideslip_changes_sign_at_eq10_speed(config: Config, car: TwoTrackParams) -> None:
    u0 = paper.crossing_speed(car.c2n, config.d_m, car.g)
    plan = SweepPlan(car.bicycle(), 15.0, 0.8 * u0, 1.2 * u0, sweep_mps2=0.15)
    trace = simulate_two_track(car, constant_radius(plan, 150.0), 15.0)
    lateral = trace.lateral_velocity_at(config.d_m - car.b_m)
    sweeping = (np.abs(trace.r) > 0.02) & (np.abs(trace.u_dot) > 0.01)
    change = np.nonzero((np.sign(lateral[1:]) != np.sign(lateral[:-1])) & sweeping[1:])[0]
    speeds = [
        float(trace.u[i] + lateral[i] / (lateral[i] - lateral[i + 1]) * (trace.u[i + 1] - trace.u[i]))
        for i in change
    ]
    assert len(speeds) == 4  # left up, left down, right up, right down
    for speed in speeds:
        assert speed == pytest.approx(u0, rel=0.01)
    assert math.sqrt(np.mean(np.square(speeds))) == pytest.approx(u0, rel=0.003)


def test_roll_follows_its_gradient_and_the_accelerometer_reads_it(car: TwoTrackParams) -> None:
    trace = circle(car, 14.0, 60.0)
    steady = last(trace)
    ay = float(np.mean(trace.ay[steady]))
    roll = float(np.mean(trace.roll[steady]))
    assert roll == pytest.approx(car.roll_gradient_rad_per_mps2 * ay, rel=0.01)  # φ > 0: leaning right
    accelerometer = float(np.mean(trace.ay_accelerometer[steady]))
    assert accelerometer == pytest.approx(ay * math.cos(roll) + car.g * math.sin(roll), rel=1e-3)
    assert accelerometer > 1.03 * ay  # DESIGN §1: several per cent too high in a turn


def test_load_sensitivity_range_gives_2_to_8_percent_at_3mps2(car: TwoTrackParams) -> None:
    spec = EFFECTS["load_transfer_nonlinearity"]
    low = 1.0 - replace(car, load_sensitivity=spec.low).rear_stiffness_ratio(3.0)
    high = 1.0 - replace(car, load_sensitivity=spec.high).rear_stiffness_ratio(3.0)
    assert low == pytest.approx(0.02, abs=0.001)
    assert high == pytest.approx(0.08, abs=0.001)


def test_load_transfer_nonlinearity_lowers_c2n_by_its_closed_form(car: TwoTrackParams) -> None:
    """At 3 m/s² the axle's stiffness (F2/α2) and the method's view of it (a_y/(g·α2)) fall by
    k·(ΔF_z/F_z0)² against the same car with k = 0 (the Magic Formula's own softening cancels)."""
    effect = Effect.of("load_transfer_nonlinearity", 1.0)
    sensitive = apply_to_vehicle(effect, car)
    base, soft = circle(car, 13.4, 60.0), circle(sensitive, 13.4, 60.0)
    steady = last(base)

    def axle(trace: TwoTrackTrace) -> float:
        force = np.mean(trace.tyre_force_n[steady][:, 2:].sum(axis=1))
        return float(force / np.mean(rear_slip(trace, car)[steady]))

    def seen(trace: TwoTrackTrace) -> float:
        return float(np.mean(trace.ay[steady]) / np.mean(rear_slip(trace, car)[steady]))

    ay = float(np.mean(soft.ay[steady]))
    assert ay == pytest.approx(3.0, abs=0.05)
    drop = 1.0 - sensitive.rear_stiffness_ratio(ay)
    assert drop == pytest.approx(0.061, abs=0.002)
    assert 1.0 - axle(soft) / axle(base) == pytest.approx(drop, rel=0.05)
    assert 1.0 - seen(soft) / seen(base) == pytest.approx(drop, abs=0.01)
    # at small lateral acceleration the effect fades: the linear value is still the truth C2n
    gentle = circle(sensitive, 8.0, 150.0)
    steady = last(gentle)
    assert axle(gentle) / car.w2_n == pytest.approx(car.c2n, rel=3e-3)


def test_cross_slope_gives_a_once_per_lap_lateral_velocity_that_scales_with_the_grade(
    car: TwoTrackParams,
) -> None:
    """Quasi-static: the rear axle carries a/L of the road-plane gravity m·g·sin θ·sin(ψ_s − ψ), so
    v moves by u·sin θ·sin(ψ_s − ψ)/C2n, once per lap."""
    u, radius = 10.0, 60.0
    amplitudes = []
    for grade in (2.0, 4.0):
        sloped = apply_to_vehicle(Effect.of("road_cross_slope", grade), car)
        trace = circle(sloped, u, radius, hold_s=90.0)  # two laps
        turning = trace.t > 12.0
        assert (trace.heading[-1] - trace.heading[turning][0]) / (2 * math.pi) > 1.9
        relative = sloped.slope_downhill_rad - trace.heading[turning]
        design = np.column_stack([np.ones(len(relative)), np.sin(relative), np.cos(relative)])
        coef, *_ = np.linalg.lstsq(design, trace.v[turning], rcond=None)
        amplitude = math.hypot(coef[1], coef[2])
        assert amplitude == pytest.approx(u * math.sin(sloped.cross_slope_rad) / car.c2n, rel=0.1)
        amplitudes.append(amplitude)
    flat = circle(car, u, radius, hold_s=30.0)
    assert np.ptp(flat.v[flat.t > 12.0]) < 0.03 * amplitudes[0]  # no slope: only the settling
    assert amplitudes[1] / amplitudes[0] == pytest.approx(2.0, rel=0.02)


@pytest.mark.parametrize("grade", [3.0, -3.0])
def test_cross_slope_biases_the_accelerometer_on_a_straight(car: TwoTrackParams, grade: float) -> None:
    """Road falling to the right (+): the body-fixed accelerometer reads g·sin θ to the left, plus
    the body's roll downhill: g·sin(θ + φ); the car's kinematic a_y stays zero."""
    sloped = apply_to_vehicle(Effect.of("road_cross_slope", grade), car)
    trace = straight(sloped, 12.0, 20.0)
    steady = last(trace, 5.0)
    theta = math.copysign(sloped.cross_slope_rad, grade)
    roll = float(np.mean(trace.roll[steady]))
    specific = car.g * math.sin(theta)
    assert roll == pytest.approx(car.roll_gradient_rad_per_mps2 * specific, rel=0.02)
    expected = specific * math.cos(roll) + car.g * math.cos(theta) * math.sin(roll)
    assert np.mean(trace.ay_accelerometer[steady]) == pytest.approx(expected, rel=2e-3)
    assert abs(np.mean(trace.ay[steady])) < 1e-3
    assert abs(np.mean(trace.heading[steady])) < 0.01  # still heading along the start


def test_roll_steer_changes_the_understeer_gradient_by_its_sign(car: TwoTrackParams) -> None:
    """δ = L/R + K·a_y: rear roll steer ε adds ε·G_φ to K (ε > 0 roll understeer)."""

    def gradient(params: TwoTrackParams) -> float:
        steers, lateral = [], []
        for u in (8.0, 14.0):
            trace = circle(params, u, 80.0)
            steady = last(trace)
            steers.append(np.mean(trace.delta[steady]))
            lateral.append(np.mean(trace.ay[steady]))
        return float((steers[1] - steers[0]) / (lateral[1] - lateral[0]))

    base = gradient(car)
    for epsilon in (0.2, -0.2):
        changed = gradient(apply_to_vehicle(Effect.of("roll_steer", epsilon), car)) - base
        assert math.copysign(1.0, changed) == math.copysign(1.0, epsilon)
        assert changed == pytest.approx(epsilon * car.roll_gradient_rad_per_mps2, rel=0.1)


@pytest.mark.parametrize("size_deg", [0.3, -0.3])
def test_ply_steer_crabs_the_car_and_the_driver_steers_it_out(
    config: Config, car: TwoTrackParams, size_deg: float
) -> None:
    """A rear slip-angle offset α: straight ahead needs zero rear slip, so the body crabs by α
    (the sensor's sideslip) and the front wheels steer α to keep the front slip at zero."""
    trace = straight(apply_to_vehicle(Effect.of("tyre_ply_steer", size_deg), car), 12.0)
    steady = last(trace, 5.0)
    beta_d = trace.lateral_velocity_at(config.d_m - car.b_m)[steady] / trace.u[steady]
    assert math.degrees(np.mean(beta_d)) == pytest.approx(size_deg, rel=0.02)
    assert math.degrees(np.mean(trace.delta[steady])) == pytest.approx(size_deg, rel=0.03)
    none = straight(car, 12.0, 5.0)
    assert np.max(np.abs(none.v)) < 1e-12 and np.max(np.abs(none.delta)) < 1e-12
