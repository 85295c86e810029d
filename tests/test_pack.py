"""The effect vocabulary, the sensor-side effects, the standard session and blind packs."""

import json
import math
import re
from collections import Counter
from dataclasses import replace
from pathlib import Path
from typing import Any, get_args

import numpy as np
import pytest
from rich.console import Console

from app.cli import main
from app.config import Config, load_config
from app.dbc import load_dbc
from app.errors import C2nError
from app.sim import commonroad
from app.sim.effects import (
    EFFECT_NAMES,
    EFFECTS,
    NO_EFFECT,
    Effect,
    EffectName,
    apply_to_sensor,
    draw_effect,
    effect_name,
)
from app.sim.imperfections import NO_IMPERFECTIONS, of_session
from app.sim.pack import LOG_NAME, case_seed, plan_pack, write_pack
from app.sim.scenarios import Scenario, Segment, Steer
from app.sim.sensors import SensorSetup, frames
from app.sim.simulated_drive import DBC_DIR
from app.sim.standard import StandardOptions, StandardPlan, simulate_standard, standard_session
from app.sim.two_track import TwoTrackParams, TwoTrackTrace, simulate_two_track
from app.sources.logs import open_log

DESIGN_EFFECTS = (
    "none",
    "sensor_yaw_misalignment",
    "sensor_position_error",
    "speed_scale_error",
    "signal_latency",
    "road_cross_slope",
    "load_transfer_nonlinearity",
    "roll_steer",
    "tyre_ply_steer",
)
# a standard session cut to about a minute of driving: enough to check files, not a diagnosis
TINY_PLAN = StandardPlan(
    radius_factors=(1.0,),
    sweep_mps2=2.0,
    settle_s=3.0,
    hold_s=1.0,
    straight_s=3.0,
    straight_accel_mps2=2.0,
    step_speed_factors=(1.0,),
    step_hold_s=3.0,
)


def test_vocabulary_is_design_section_6() -> None:
    assert EFFECT_NAMES == DESIGN_EFFECTS
    for spec in EFFECTS.values():
        assert 0.0 <= spec.low <= spec.high
        assert Effect.of(spec.name).size == pytest.approx(0.5 * (spec.low + spec.high))


def test_the_effects_type_is_the_vocabulary() -> None:
    """``EffectName``, what the type checker holds every effect to, names exactly the registry's
    effects; CommonRoad's car carries some of them; a name read from a file is checked."""
    assert get_args(EffectName) == EFFECT_NAMES
    assert set(commonroad.EFFECTS) < set(EFFECT_NAMES)
    assert effect_name("roll_steer") == "roll_steer"
    with pytest.raises(C2nError, match="unknown effect 'Roll_steer'"):
        effect_name("Roll_steer")


def test_draws_cover_every_effect_with_sizes_in_range() -> None:
    rng = np.random.default_rng(3)
    draws = [draw_effect(rng) for _ in range(2700)]
    counts = Counter(effect.name for effect in draws)
    assert set(counts) == set(DESIGN_EFFECTS)
    assert all(200 <= count <= 400 for count in counts.values())  # 1/9 each
    for effect in draws:
        spec = EFFECTS[effect.name]
        assert effect.unit == spec.unit
        assert spec.low <= abs(effect.size) <= spec.high
    for name, spec in EFFECTS.items():
        signs = {math.copysign(1.0, e.size) for e in draws if e.name == name and e.size != 0}
        assert signs == ({-1.0, 1.0} if spec.signed else ({1.0} if spec.high > 0 else set()))


def test_a_pack_of_one_effect_draws_only_its_sizes_and_keeps_each_case_s_test_day() -> None:
    mixed = plan_pack(20, 808)
    nones = plan_pack(20, 808, only="none")
    slopes = plan_pack(20, 808, model="commonroad", only="road_cross_slope")
    assert {case.effect for case in nones} == {NO_EFFECT}
    assert {case.effect.name for case in slopes} == {"road_cross_slope"}
    assert len({case.effect.size for case in slopes}) == 20
    assert all(1.0 <= abs(case.effect.size) <= 4.0 for case in slopes)
    # the test day's imperfections and handbook configs are the mixed pack's, case by case
    assert [(c.seed, c.imperfections, c.handbook) for c in nones] == [
        (c.seed, c.imperfections, c.handbook) for c in mixed
    ]
    with pytest.raises(C2nError, match="commonroad model cannot carry it"):
        plan_pack(2, 808, model="commonroad", only="roll_steer")


@pytest.mark.parametrize(
    ("make", "message"),
    [
        (lambda: Effect("wind", 1.0, ""), "unknown effect 'wind'"),
        (lambda: Effect("roll_steer", 0.1, "deg"), "in 'deg/deg'"),
        (lambda: Effect.of("signal_latency", -0.1), "must be ≥ 0"),
        (lambda: Effect("none", 1.0, ""), "no size"),
    ],
)
def test_effects_are_checked(make: Any, message: str) -> None:
    with pytest.raises(C2nError, match=re.escape(message)):
        make()


# ---- sensor-side effects: exactly the signals they should change ----


@pytest.fixture(scope="module")
def manoeuvre(config: Config) -> TwoTrackTrace:
    """Straight, speeding up into a left turn, slowing, straight again: every signal moves."""
    segments = (
        Segment(2.0, 10.0, Steer("straight")),
        Segment(6.0, 14.0, Steer("radius", 80.0)),
        Segment(4.0, 11.0, Steer("radius", 80.0)),
        Segment(3.0, 11.0, Steer("straight")),
    )
    return simulate_two_track(TwoTrackParams.from_config(config), Scenario("m", 10.0, segments), 15.0)


def decoded(trace: TwoTrackTrace, setup: SensorSetup) -> dict[str, np.ndarray]:
    """'Message.Signal' → its values in order, from noise-free frames."""
    kistler = load_dbc(DBC_DIR / "kistler_smotion.dbc").database
    ford = load_dbc(DBC_DIR / "vehicle_ford.dbc").database
    columns: dict[str, list[float]] = {}
    for message in frames(trace, setup, kistler, ford, np.random.default_rng(1)):
        db = kistler if message.channel == setup.sensor_channel else ford
        frame = db.get_message_by_frame_id(message.arbitration_id)
        values = db.decode_message(message.arbitration_id, message.data, decode_choices=False)
        for name, value in values.items():
            columns.setdefault(f"{frame.name}.{name}", []).append(float(value))
    return {name: np.array(values) for name, values in columns.items()}


@pytest.fixture(scope="module")
def quiet(config: Config) -> SensorSetup:
    return SensorSetup(
        d_m=config.d_m,
        height_m=config.vehicle.sensor_height_m,
        sigma_velocity_mps=0.0,
        sigma_yaw_rate_degps=0.0,
        sigma_ay_mps2=0.0,
        sigma_speed_kph=0.0,
        jitter_s=0.0,
    )


@pytest.fixture(scope="module")
def baseline(manoeuvre: TwoTrackTrace, quiet: SensorSetup) -> dict[str, np.ndarray]:
    return decoded(manoeuvre, quiet)


def changed(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> set[str]:
    assert a.keys() == b.keys()
    return {name for name in a if len(a[name]) != len(b[name]) or not np.array_equal(a[name], b[name])}


def optical(*signals: str) -> set[str]:
    return {f"Correvit.{s}_cor" for s in signals} | {f"Vel_Angle.{s}" for s in signals}


def test_sensor_yaw_misalignment_turns_only_the_optical_velocity(
    manoeuvre: TwoTrackTrace, quiet: SensorSetup, baseline: dict[str, np.ndarray]
) -> None:
    turned = decoded(manoeuvre, apply_to_sensor(Effect.of("sensor_yaw_misalignment", 0.8), quiet))
    assert changed(baseline, turned) <= optical("VelX", "VelY", "Vel", "Angle")
    assert optical("VelY", "Angle") <= changed(baseline, turned)
    # head turned left: the sideslip reads 0.8° low (to the Angle's 0.01° and the straight's quantisation)
    offset = turned["Correvit.Angle_cor"] - baseline["Correvit.Angle_cor"]
    assert np.median(offset) == pytest.approx(-0.8, abs=0.011)


def test_sensor_position_error_moves_only_the_lateral_velocity(
    manoeuvre: TwoTrackTrace, quiet: SensorSetup, baseline: dict[str, np.ndarray]
) -> None:
    moved = decoded(manoeuvre, apply_to_sensor(Effect.of("sensor_position_error", 0.2), quiet))
    assert changed(baseline, moved) <= optical("VelY", "Vel", "Angle")
    # further forward: v + r·x grows by r·Δd where the car turns
    gain = moved["Correvit.VelY_cor"] - baseline["Correvit.VelY_cor"]
    r = np.radians(baseline["AngVelHor.AngVelZ_hor"])
    turning = np.abs(r) > 0.1
    assert np.allclose(gain[turning] / 3.6, 0.2 * r[turning], atol=0.011)


def test_speed_scale_error_scales_only_the_vehicle_and_wheel_speeds(
    manoeuvre: TwoTrackTrace, quiet: SensorSetup, baseline: dict[str, np.ndarray]
) -> None:
    scaled = decoded(manoeuvre, apply_to_sensor(Effect.of("speed_scale_error", -3.0), quiet))
    speeds = {"BrakeSysFeatures.Veh_V_ActlBrk"} | {
        f"WheelSpeed.Whl{w}_W_Meas" for w in ("Fl", "Fr", "Rl", "Rr")
    }
    assert changed(baseline, scaled) == speeds
    for name in speeds:
        assert np.allclose(scaled[name], 0.97 * baseline[name], atol=0.011)


def test_signal_latency_delays_the_vehicle_frames_by_tau(
    manoeuvre: TwoTrackTrace, quiet: SensorSetup, baseline: dict[str, np.ndarray]
) -> None:
    tau = 0.2  # 20 frames of the 100 Hz vehicle bus, 10 of the 50 Hz speed
    late = decoded(manoeuvre, apply_to_sensor(Effect.of("signal_latency", tau), quiet))
    moved = changed(baseline, late)
    assert not any(name.split(".")[0] in ("Correvit", "Vel_Angle", "AngVelHor", "Status") for name in moved)
    for name in (
        "Yaw_Data_FD1.VehYaw_W_Actl",
        "Accel_Data_FD1.VehLat2_A_Actl",
        "SteeringPinion_Data.StePinComp_An_Est",
    ):
        assert name in moved
        resolution = {"Yaw": 0.0002, "Acc": 0.01, "Ste": 0.1}[name[:3]]
        assert np.allclose(late[name][20:], baseline[name][:-20], atol=resolution * 1.01)
        assert np.all(late[name][:20] == late[name][0])  # before the drive: its first value
    speed = "BrakeSysFeatures.Veh_V_ActlBrk"
    assert np.allclose(late[speed][10:], baseline[speed][:-10], atol=0.0101)


def test_vehicle_and_road_effects_leave_the_sensors_alone(quiet: SensorSetup) -> None:
    for name, spec in EFFECTS.items():
        if spec.applies_to != "sensor":
            assert apply_to_sensor(Effect.of(name), quiet) == quiet


def test_the_accelerometer_frames_read_the_cross_slope(config: Config) -> None:
    """On a straight with the road falling right by 3 %, the decoded a_y is g·sin(θ + φ) high."""
    params = TwoTrackParams.from_config(config)
    sloped = replace(params, cross_slope_grade=0.03)
    trace = simulate_two_track(sloped, Scenario("s", 12.0, (Segment(12.0, 12.0, Steer("straight")),)), 15.0)
    setup = SensorSetup(d_m=config.d_m, jitter_s=0.0)
    values = decoded(trace, setup)["Accel_Data_FD1.VehLat2_A_Actl"]
    roll = float(np.mean(trace.roll[trace.t > 6.0]))
    expected = params.g * math.sin(math.atan(0.03) + roll)
    assert np.mean(values[600:]) == pytest.approx(expected, abs=0.01)


# ---- the standard session ----


def test_standard_session_layout(config: Config) -> None:
    params = TwoTrackParams.from_config(config)
    u0 = math.sqrt(params.c2n * params.g * config.d_m)
    session = standard_session(u0, params.bicycle(), 15.0)
    parts = session.parts
    assert [p.kind for p in parts] == ["straight"] + ["sweep"] * 6 + ["step_steer"] * 4
    assert parts[0].speed_mps == pytest.approx(u0) and parts[0].end_s - parts[0].start_s == 30.0
    radii = [p.radius_m for p in parts if p.kind == "sweep"]
    assert radii == [68.0, 68.0, 96.0, 96.0, 137.0, 137.0]
    assert [p.direction for p in parts if p.kind != "straight"] == [1, -1] * 5
    top = 1.3 * u0
    assert top**2 / radii[0] == pytest.approx(4.0, abs=0.05)  # the smallest circle's top speed
    assert 0.6 * u0 < u0 < top  # the sweeps cross u0
    steps = sorted({round(p.speed_mps or 0.0, 3) for p in parts if p.kind == "step_steer"})
    assert steps == [round(0.8 * u0, 3), round(1.2 * u0, 3)]
    assert 9 * 60 < session.scenario.duration_s < 15 * 60


# ---- packs ----


def read_frames(log: Path) -> list[tuple[float, int, bytes]]:
    with open_log(log) as reader:
        return [(m.timestamp, m.arbitration_id, bytes(m.data)) for m in reader]


@pytest.fixture(scope="module")
def pack(tmp_path_factory: pytest.TempPathFactory, config: Config) -> Path:
    out = tmp_path_factory.mktemp("packs") / "pack"
    result = write_pack(out, 3, 11, config.path, TINY_PLAN, workers=2, realistic=False)
    assert [case.name for case in result.cases] == ["case_001", "case_002", "case_003"]
    return out


def test_pack_layout_and_sealed_truth(pack: Path) -> None:
    files = sorted(str(p.relative_to(pack)) for p in pack.rglob("*") if p.is_file())
    assert files == [f"case_00{i}/{LOG_NAME}" for i in (1, 2, 3)] + ["sealed/truth.json"]
    truth = json.loads((pack / "sealed" / "truth.json").read_text())
    assert truth["pack_seed"] == 11 and list(truth["cases"]) == ["case_001", "case_002", "case_003"]
    for index, (name, case) in enumerate(truth["cases"].items(), start=1):
        assert case["seed"] == case_seed(11, index)
        assert case["effect"]["name"] in DESIGN_EFFECTS
        assert {"c2n", "d_m", "config_d_m", "u0_mps"} <= set(case)
        assert case["effect"] == {
            "name": plan_pack(3, 11)[index - 1].effect.name,
            "size": plan_pack(3, 11)[index - 1].effect.size,
            "unit": plan_pack(3, 11)[index - 1].effect.unit,
        }
        log = pack / name / LOG_NAME
        assert log.stat().st_size > 0
        data = log.read_bytes()
        assert b"effect" not in data and case["effect"]["name"].encode() not in data


def test_pack_is_reproducible_case_by_case(pack: Path, tmp_path: Path, config: Config) -> None:
    again = write_pack(tmp_path / "again", 1, 11, config.path, TINY_PLAN, workers=1, realistic=False)
    assert (again.out / "case_001" / LOG_NAME).read_bytes() == (pack / "case_001" / LOG_NAME).read_bytes()
    other = write_pack(tmp_path / "other", 1, 12, config.path, TINY_PLAN, workers=1, realistic=False)
    assert read_frames(other.out / "case_001" / LOG_NAME) != read_frames(pack / "case_001" / LOG_NAME)


def test_pack_needs_a_new_folder(pack: Path, config: Config) -> None:
    with pytest.raises(C2nError, match="not an empty folder"):
        write_pack(pack, 1, 1, config.path, TINY_PLAN)


def test_pack_with_another_config_carries_it(tmp_path: Path, config: Config) -> None:
    """Its DBC paths are relative to it: the copy in the case folder names them absolutely."""
    text = config.path.read_text().replace("c2n_per_rad = 14.87", "c2n_per_rad = 13.5")
    (tmp_path / "cars").mkdir()
    (tmp_path / "dbc").symlink_to(DBC_DIR, target_is_directory=True)
    other = tmp_path / "cars" / "car.toml"
    other.write_text(text)
    result = write_pack(tmp_path / "pack", 1, 5, other, TINY_PLAN, workers=1, realistic=False)
    copied = result.out / "case_001" / "config.toml"
    assert "c2n_per_rad = 13.5" in copied.read_text()
    assert str(DBC_DIR / "kistler_smotion.dbc") in copied.read_text()
    assert result.cases[0].truth["c2n"] == 13.5


# ---- the command line ----


def test_cli_session_writes_the_log_and_its_truth(tmp_path: Path) -> None:
    console = Console(record=True, width=200)
    log = tmp_path / "drive.blf"
    code = main(
        ["simulate", "--session", "standard", "--quick", "--effect", "roll_steer", "--effect-size", "-0.1",
         "--seed", "4", "--optical-hz", "50", "--out", str(log)],
        console,
    )  # fmt: skip
    assert code == 0
    truth = json.loads(log.with_name("drive.blf.truth.json").read_text())
    assert truth["effect"] == {"name": "roll_steer", "size": -0.1, "unit": "deg/deg"}
    assert truth["session"] == "standard" and truth["seed"] == 4 and truth["sensor"]["optical_hz"] == 50.0
    assert "roll_steer -0.1 deg/deg" in console.export_text()


def test_cli_pack_prints_a_line_per_case_and_keeps_the_effect_sealed(tmp_path: Path) -> None:
    console = Console(record=True, width=200)
    out = tmp_path / "pack"
    assert main(["simulate", "--pack", "1", "--quick", "--seed", "2", "--out", str(out)], console) == 0
    text = console.export_text()
    assert re.search(r"case_001: \d+ s of driving, [\d,]+ frames \(\d+\.\d s\)", text)
    assert "truth sealed in" in text
    assert not any(name in text for name in DESIGN_EFFECTS[1:])


@pytest.mark.parametrize(
    "argv",
    [
        ["--pack", "2", "--c2n", "14"],
        ["--session", "standard", "--misalignment", "0.5"],
        ["--session", "standard", "--scenario", "radii"],
        ["--effect", "roll_steer"],
        ["--session", "standard", "--effect-size", "0.1"],
        ["--pack", "2", "--effect", "roll_steer", "--effect-size", "0.1"],
        ["--pack", "2", "--model", "commonroad", "--effect", "roll_steer"],
    ],
)
def test_cli_refuses_options_that_do_not_fit(
    argv: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["simulate", *argv, "--out", str(tmp_path / "x.blf")], Console(record=True)) == 1
    assert capsys.readouterr().err.startswith("c2n: error: ")


def test_none_is_the_default_effect() -> None:
    assert NO_EFFECT == Effect() == Effect.of("none")
    assert NO_EFFECT.describe() == "none"


# ---- a real test day ----


def test_a_test_days_imperfections_are_reproducible_and_in_their_ranges() -> None:
    days = [of_session(seed) for seed in range(200)]
    assert of_session(7) == of_session(7) and of_session(7) != of_session(8)
    assert all(0.02 <= abs(d.gyro_bias_degps) <= 0.08 for d in days)
    assert all(abs(d.gyro_scale - 1.0) <= 0.005 for d in days)
    assert all(0.5 <= abs(d.steer_offset_deg) <= 2.0 for d in days)
    assert all(abs(d.steering_ratio_error) <= 0.03 for d in days)
    assert all(0.02 <= abs(d.c1n_error) <= 0.05 and 0.02 <= abs(d.c2n_error) <= 0.05 for d in days)
    assert {d.optical_hz for d in days} == {50.0, 100.0, 200.0, 250.0}
    assert {np.sign(d.steer_offset_deg) for d in days} == {-1.0, 1.0}
    overrides = days[0].sensor(15.0)
    assert overrides["steering_ratio"] == pytest.approx(15.0 * (1.0 + days[0].steering_ratio_error))
    assert NO_IMPERFECTIONS.sensor(15.0)["gyro_bias_degps"] == 0.0


def test_a_realistic_pack_gives_each_case_a_handbook_config_and_seals_the_car(
    tmp_path: Path, config: Config
) -> None:
    """Each case's config has C1n and C2n each within ±20 % of the car's nominal values (what a
    handbook gives); the seal keeps the car's own, the config's and the test day's imperfections,
    and the effects are those of the same pack made ideal."""
    result = write_pack(tmp_path / "pack", 3, 21, config.path, TINY_PLAN, workers=2)
    ideal = plan_pack(3, 21, realistic=False)
    truth = json.loads(result.truth_path.read_text())
    assert truth["realistic"] is True and truth["model"] == "two_track"
    for index, case in enumerate(result.cases):
        sealed = truth["cases"][case.name]
        own = load_config(result.out / case.name / "config.toml")
        factors = own.tyres.c1n_per_rad / 13.0, own.tyres.c2n_per_rad / 14.87  # type: ignore[operator]
        assert all(0.8 <= f <= 1.2 for f in factors) and factors != (1.0, 1.0)
        assert sealed["config_tyres"]["c2n_per_rad"] == pytest.approx(own.tyres.c2n_per_rad, abs=1e-4)
        day = sealed["imperfections"]
        assert sealed["c2n"] == pytest.approx(14.87 * (1.0 + day["c2n_error"]))
        assert sealed["sensor"]["gyro_bias_degps"] == day["gyro_bias_degps"] != 0.0
        assert sealed["sensor"]["steer_offset_deg"] == day["steer_offset_deg"]
        assert sealed["effect"]["name"] == ideal[index].effect.name


def test_a_steering_offset_reads_on_the_straight(config: Config) -> None:
    """The session's opening straight: the car goes straight, the steering wheel reads the offset."""
    day = replace(NO_IMPERFECTIONS, steer_offset_deg=1.5, vehicle_hz=50.0)
    drive = simulate_standard(config, StandardOptions(seed=3, plan=TINY_PLAN, imperfections=day))
    steer = load_dbc(DBC_DIR / "vehicle_ford.dbc").database.get_message_by_name("SteeringPinion_Data")
    start = drive.messages[0].timestamp
    readings = [
        steer.decode(m.data)["StePinComp_An_Est"]
        for m in drive.messages
        if m.arbitration_id == steer.frame_id and m.timestamp - start < 4.0
    ]
    assert len(readings) > 100 and np.median(readings) == pytest.approx(1.5, abs=0.2)
