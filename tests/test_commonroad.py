"""The cross-check generator: CommonRoad's multi-body model (a model nobody here wrote) driven
through our manoeuvres and sensors."""

import math
from pathlib import Path

import numpy as np
import pytest
from rich.console import Console

from app.cli import main
from app.config import COMMONROAD_CONFIG, load_config
from app.dbc import load_dbc
from app.errors import C2nError
from app.sim.commonroad import CommonRoadCar, Road, parameters, simulate_commonroad
from app.sim.effects import Effect
from app.sim.scenarios import Scenario, Segment, Steer
from app.sim.sensors import SensorSetup, frames
from app.sim.session import DBC_DIR
from app.sim.standard import StandardOptions, simulate_standard
from app.sim.two_track import TwoTrackTrace

RADIUS = 60.0


@pytest.fixture(scope="module")
def car() -> CommonRoadCar:
    return CommonRoadCar("vehicle2", parameters("vehicle2"))


@pytest.fixture(scope="module")
def circle(car: CommonRoadCar) -> TwoTrackTrace:
    """A straight, then a left circle of 60 m held while the speed rises from 8 to 14 m/s."""
    segments = (
        Segment(3.0, 8.0, Steer("straight")),
        Segment(8.0, 8.0, Steer("radius", RADIUS)),
        Segment(12.0, 14.0, Steer("radius", RADIUS)),
    )
    return simulate_commonroad(car, Scenario("circle", 8.0, segments), 15.0)


def test_the_car_is_the_parameter_sets(car: CommonRoadCar) -> None:
    p = car.p
    assert car.wheelbase_m == pytest.approx(p.a + p.b)
    assert car.w1_n + car.w2_n == pytest.approx(p.m * 9.81)
    assert car.w1_n * (p.a + p.b) == pytest.approx(p.m * 9.81 * p.b)  # moments about the rear axle
    assert car.cn_per_rad == pytest.approx(21.92)  # |p_ky1|: K_y = p_ky1·F_z at small slip
    config = load_config(COMMONROAD_CONFIG)
    assert config.vehicle.wheelbase_m == pytest.approx(car.wheelbase_m, rel=1e-4)
    assert config.tyres.c2n_per_rad == pytest.approx(car.cn_per_rad)
    assert config.vehicle.rear_axle_load_N == pytest.approx(car.w2_n, rel=1e-4)


def test_the_driver_holds_the_radius_and_the_speed_plan(circle: TwoTrackTrace) -> None:
    held = (circle.t > 6.0) & (circle.t < 22.0)
    radius = circle.u[held] / circle.r[held]
    assert np.all(np.abs(radius / RADIUS - 1.0) < 0.03)
    plan = np.interp(circle.t, [0.0, 11.0, 23.0], [8.0, 8.0, 14.0])
    assert np.max(np.abs(circle.u - plan)[circle.t > 1.0]) < 0.3
    late = circle.t > 20.0
    assert np.all(circle.roll[late] > 0)  # a left turn leans the body right (ISO: φ > 0)
    assert np.all(circle.ay[late] == pytest.approx(circle.u[late] ** 2 / RADIUS, rel=0.05))
    # at 8 m/s the rear axle barely slips: the body's lateral velocity there is about zero, and
    # ahead of it grows with the distance (v + r·x)
    slow = (circle.t > 8.0) & (circle.t < 11.0)
    b = circle.params.b_m
    rear = circle.lateral_velocity_at(-b)[slow]
    assert np.all(np.abs(rear) < 0.02 * circle.u[slow])


def test_a_yawed_head_reads_the_commonroad_sideslip_turned_by_its_angle(circle: TwoTrackTrace) -> None:
    """The sensor layer is the same for both generators: a head yawed 0.5° left reads the sideslip
    0.5° low."""
    config = load_config(COMMONROAD_CONFIG)
    kistler = load_dbc(DBC_DIR / "kistler_smotion.dbc").database
    ford = load_dbc(DBC_DIR / "vehicle_ford.dbc").database
    angle = kistler.get_message_by_name("Correvit")

    def angles(misalignment: float) -> np.ndarray:
        setup = SensorSetup.from_config(config, yaw_misalignment_deg=misalignment, sigma_velocity_mps=0.0)
        messages = frames(circle, setup, kistler, ford, np.random.default_rng(1))
        return np.array(
            [angle.decode(m.data)["Angle_cor"] for m in messages if m.arbitration_id == angle.frame_id]
        )

    assert np.median(angles(0.5) - angles(0.0)) == pytest.approx(-0.5, abs=0.01)


def test_a_cross_slope_is_gravity_on_every_mass(car: CommonRoadCar) -> None:
    """Straight ahead on a 4 % slope falling to the right, the driver holds the line: the tyres
    push the car uphill, and the accelerometer reads it, g·sin θ to the left (and the body's lean
    on its springs a little more)."""
    segments = (Segment(10.0, 12.0, Steer("straight")),)
    trace = simulate_commonroad(car, Scenario("slope", 12.0, segments), 15.0, Road(0.04))
    late = trace.t > 6.0
    uphill = 9.81 * math.sin(math.atan(0.04))
    assert uphill <= np.median(trace.ay_accelerometer[late]) <= 1.25 * uphill
    assert np.max(np.abs(trace.r[late])) < 0.01  # held straight


def test_effects_the_model_cannot_carry_and_a_config_of_another_car_are_refused() -> None:
    config = load_config(COMMONROAD_CONFIG)
    with pytest.raises(C2nError, match="roll_steer is not in CommonRoad's model"):
        simulate_standard(config, StandardOptions(effect=Effect.of("roll_steer"), model="commonroad"))
    with pytest.raises(C2nError, match=r"use config/commonroad_vehicle2\.toml"):
        simulate_standard(load_config(), StandardOptions(model="commonroad"))


def test_the_command_line_offers_the_model_only_for_sessions(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["simulate", "--model", "bicycle", "--session", "standard"], Console(record=True)) == 2
    out = str(tmp_path / "x.blf")
    assert main(["simulate", "--model", "commonroad", "--out", out], Console(record=True)) == 1
    assert "--model is for --session standard or --pack N" in capsys.readouterr().err
