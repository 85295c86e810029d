"""The simulator against closed forms, and its logs read back by python-can."""

import json
import math
from pathlib import Path

import can
import numpy as np
import pytest

from app import paper
from app.config import Config
from app.sim.drive import simulate
from app.sim.scenarios import SweepPlan, constant_radius, constant_steer
from app.sim.simulated_drive import DriveOptions, SimulatedDrive, simulate_drive, truth_path, write_drive
from app.sim.vehicle_model import BicycleParams
from app.sources.logs import open_log


def zero_crossings(speed: np.ndarray, lateral: np.ndarray, turning: np.ndarray) -> list[float]:
    """Speeds where the lateral velocity at the sensor changes sign while turning."""
    found = []
    for i in np.nonzero((np.sign(lateral[1:]) != np.sign(lateral[:-1])) & turning[1:])[0]:
        f = lateral[i] / (lateral[i] - lateral[i + 1])
        found.append(float(speed[i] + f * (speed[i + 1] - speed[i])))
    return found


@pytest.mark.parametrize("manoeuvre", [constant_radius, constant_steer])
def test_noise_free_sweep_crosses_at_eq10_speed(config: Config, manoeuvre: object) -> None:
    """The crossing speed of a noise-free sweep equals √(C2n·g·d): up and down sweeps are off by
    the same small dynamic lag in opposite directions (bounded by the sweep rate), their mean is exact."""
    params = BicycleParams.from_config(config, c2n=13.0)
    d = config.d_m
    u0 = paper.crossing_speed(params.c2n, d, params.g)
    plan = SweepPlan(params, 15.0, 0.7 * u0, 1.3 * u0, sweep_mps2=0.1)
    trace = simulate(params, manoeuvre(plan), 15.0)  # type: ignore[operator]
    lateral = trace.lateral_velocity_at(d - params.b_m)
    sweeping = (np.abs(trace.r) > 0.02) & (np.abs(trace.u_dot) > 0.01)  # not the turn-in and exit transients
    speeds = zero_crossings(trace.u, lateral, sweeping)
    assert len(speeds) == 4  # left up, left down, right up, right down
    for speed in speeds:
        assert speed == pytest.approx(u0, rel=0.002)
    assert np.mean(np.square(speeds)) == pytest.approx(u0**2, rel=2e-5)


def test_steady_state_of_the_model_is_eq6(config: Config) -> None:
    params = BicycleParams.from_config(config)
    d = config.d_m
    for u, delta in [(8.0, 0.04), (12.7, -0.03), (18.0, 0.02)]:
        v_cg, r = params.steady_state(u, delta)
        v_dot, r_dot = params.derivatives(u, v_cg, r, delta)
        assert abs(v_dot) < 1e-3 and abs(r_dot) < 1e-3  # it is an equilibrium (cos δ ≈ 1)
        radius = u / r
        beta_d = (v_cg + r * (d - params.b_m)) / u
        assert beta_d == pytest.approx(
            paper.sideslip_at_sensor(u, radius, d, params.c2n, params.g), abs=1e-12
        )


def test_magic_formula_tyre_is_linear_at_small_slip_and_saturates(config: Config) -> None:
    params = BicycleParams.from_config(config, tyre="magic", mu=0.9)
    c2, w2 = params.c2_n_per_rad, params.w2_n
    assert params.axle_force(1e-5, c2, w2) / 1e-5 == pytest.approx(c2, rel=1e-6)
    assert params.axle_force(math.radians(3), c2, w2) < 0.97 * c2 * math.radians(3)  # softer at 3°
    assert params.axle_force(math.radians(20), c2, w2) <= 0.9 * w2 + 1e-9


def test_simulated_drive_truth(config: Config, drive: SimulatedDrive) -> None:
    truth = drive.truth
    assert truth["c2n"] == pytest.approx(14.87)
    assert truth["d_m"] == 1.11
    assert truth["u0_mps"] == pytest.approx(math.sqrt(14.87 * 9.81 * 1.11))
    timestamps = [m.timestamp for m in drive.messages]
    assert timestamps == sorted(timestamps)
    assert {m.channel for m in drive.messages if m.arbitration_id == 0x7E5} == {1}
    assert {m.channel for m in drive.messages if m.arbitration_id == 0x415} == {0}
    assert truth["max_ay_mps2"] < 4.0


@pytest.mark.parametrize("suffix", [".blf", ".asc", ".log"])
def test_logs_read_back_frame_for_frame(config: Config, tmp_path: Path, suffix: str) -> None:
    drive = simulate_drive(config, DriveOptions(seed=1, scenario="step_steer"))
    short = SimulatedDrive(drive.messages[:3000], drive.truth)
    log = tmp_path / f"drive{suffix}"
    truth = write_drive(short, log)
    assert truth == truth_path(log) and json.loads(truth.read_text())["c2n"] == pytest.approx(14.87)
    back = list(open_log(log))
    assert len(back) == 3000
    for original, read in zip(short.messages, back, strict=True):
        assert read.arbitration_id == original.arbitration_id
        assert bytes(read.data) == bytes(original.data)
        assert read.timestamp == pytest.approx(original.timestamp, abs=2e-5)
    channels = {str(m.channel) for m in back}
    assert channels == ({"can0", "can1"} if suffix == ".log" else {"0", "1"})


def test_sensor_errors_show_in_the_frames(config: Config) -> None:
    """A 1° misalignment turns the measured angle by −1°; a speed scale error scales the speed."""
    plain = simulate_drive(config, DriveOptions(seed=3, sensor={"sigma_velocity_mps": 0.0}))
    turned = simulate_drive(
        config,
        DriveOptions(
            seed=3, sensor={"sigma_velocity_mps": 0.0, "yaw_misalignment_deg": 1.0, "speed_scale": 1.02}
        ),
    )
    kistler = config.dbcs[0].database.get_message_by_name("Correvit")
    ford = config.dbcs[1].database.get_message_by_name("BrakeSysFeatures")

    def first(drive: SimulatedDrive, frame_id: int, skip: int = 2000) -> can.Message:
        return [m for m in drive.messages if m.arbitration_id == frame_id][skip]

    a = kistler.decode(first(plain, 0x7E5).data)["Angle_cor"]
    b = kistler.decode(first(turned, 0x7E5).data)["Angle_cor"]
    assert b - a == pytest.approx(-1.0, abs=0.02)
    s0 = ford.decode(first(plain, 0x415).data)["Veh_V_ActlBrk"]
    s1 = ford.decode(first(turned, 0x415).data)["Veh_V_ActlBrk"]
    assert s1 / s0 == pytest.approx(1.02, abs=0.003)
