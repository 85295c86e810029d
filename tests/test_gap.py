"""`c2n gap`: the nominal model against the paper's closed form, effects found in simulated drives,
and the blind check's scoring."""

import dataclasses
import io
import json
import math
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import can
import numpy as np
import pytest

from app import paper
from app.cli import main
from app.config import load_config
from app.gap.candidates import CANDIDATES
from app.gap.check import CaseAnswer, score
from app.gap.diagnose import diagnose
from app.gap.forked import Later
from app.gap.measured import Measured, Method, measure
from app.gap.method_effects import BY_RIG
from app.gap.nominal_model import Mods, prepare, run_model, run_model_reference, simulate
from app.gap.problem import problem, roll_lever_m
from app.gap.result import BeforeAfter, C2nEffect, Effect, GapC2n, GapNoise, GapResult
from app.sim.simulated_drive import DriveOptions, simulate_drive, write_drive
from app.sim.vehicle_model import BicycleParams
from app.sinks.summary import Summary
from tests.simulated import FAST_SENSORS, REPO, cached_drive


def steady_drive(u: float, delta: float, seconds: float = 20.0, dt: float = 0.02) -> Measured:
    """Constant speed and steering: what the model is driven by, with nothing to compare."""
    n = int(seconds / dt)
    ones = np.ones(n)
    return Measured(
        dt=dt,
        t=np.arange(n) * dt,
        u_vehicle=u * ones,
        u_optical=u * ones,
        delta=delta * ones,
        ay=np.zeros(n),
        r=np.zeros(n),
        p=np.zeros(n),
        beta=np.zeros(n),
        steady=np.ones(n, dtype=bool),
        speed_source="vehicle speed",
        vehicle_roles=frozenset({"speed", "steer"}),
        method=Later.now(Method((), None, Summary(), None)),
    )


@pytest.mark.parametrize("u", [9.0, 12.7, 16.0])
@pytest.mark.parametrize("side", [1.0, -1.0])
def test_nominal_model_settles_on_the_papers_steady_state(u: float, side: float) -> None:
    """β_d = d/R − u²/(R·g·C2n) (eq. 6) on the radius the model drives, and R = (L + K·u²)/δ."""
    config = load_config()
    p = BicycleParams.from_config(config)
    delta = side * math.radians(2.0)
    sim = simulate(p, steady_drive(u, delta), config.d_m)
    radius = u / sim.r[-1]
    assert radius == pytest.approx((p.wheelbase_m + p.understeer_rad_per_mps2 * u * u) / delta, rel=1e-6)
    expected = paper.sideslip_at_sensor(u, radius, config.d_m, p.c2n, p.g)
    assert sim.beta[-1] == pytest.approx(math.atan(expected), abs=1e-6)
    assert np.sign(sim.beta[-1]) == (side if u < paper.crossing_speed(p.c2n, config.d_m, p.g) else -side)


def test_output_effects_move_the_sideslip_as_their_closed_forms_say() -> None:
    config = load_config()
    p = BicycleParams.from_config(config)
    drive = steady_drive(12.0, math.radians(1.5))
    base = simulate(p, drive, config.d_m)
    yawed = simulate(p, drive, config.d_m, Mods(misalignment_rad=math.radians(0.4)))
    moved = simulate(p, drive, config.d_m, Mods(d_error_m=0.2))
    assert yawed.beta[-1] - base.beta[-1] == pytest.approx(-math.radians(0.4), abs=1e-9)
    # the sensor 0.2 m further forward sees 0.2·r more lateral velocity: Δβ ≈ 0.2·κ
    assert moved.beta[-1] - base.beta[-1] == pytest.approx(0.2 * base.r[-1] / 12.0, rel=1e-3)


def test_longitudinal_load_transfer_moves_the_steady_state_as_the_shifted_loads_say() -> None:
    """Speeding up at a_x moves m·h·a_x/L of load rearward: Cᵢ = Cᵢn·Wᵢ' in R = (L + K·u²)/δ and
    eq. 6 with the rear stiffness Cᵢ/W₂ normalised by the static load; never more than 70 % of an
    axle's load moves (a wrong CG height in the config must not leave an axle with no grip)."""
    config = load_config()
    p = BicycleParams.from_config(config)
    u, delta, accel, height = 12.0, math.radians(1.5), 1.0, 0.55
    base = steady_drive(u, delta, seconds=40.0)
    # the acceleration comes from the optical speed
    accelerating = dataclasses.replace(base, u_optical=u + accel * base.t)
    shifted = prepare(p, accelerating, cg_height_m=height)
    transfer = p.mass_kg * height * accel / p.wheelbase_m
    c1, c2 = p.c1n * (p.w1_n - transfer), p.c2n * (p.w2_n + transfer)
    mid = len(base.t) // 2  # away from the smoothing's edges
    assert shifted.c1_nominal[mid] == pytest.approx(c1, rel=1e-6)
    assert shifted.c2_nominal[mid] == pytest.approx(c2, rel=1e-6)
    n = len(base.t)
    steady = dataclasses.replace(prepare(p, base), c1_nominal=np.full(n, c1), c2_nominal=np.full(n, c2))
    sim = run_model(steady, config.d_m)
    understeer = p.mass_kg / p.wheelbase_m * (p.b_m / c1 - p.a_m / c2)
    radius = u / sim.r[-1]
    assert radius == pytest.approx((p.wheelbase_m + understeer * u * u) / delta, rel=1e-6)
    expected = paper.sideslip_at_sensor(u, radius, config.d_m, c2 / p.w2_n, p.g)
    assert sim.beta[-1] == pytest.approx(math.atan(expected), abs=1e-6)
    braking = dataclasses.replace(base, u_optical=u - 30.0 * base.t)  # 3 g: more than the front's load
    clipped = prepare(p, braking, cg_height_m=height)
    assert clipped.c2_nominal[mid] == pytest.approx(p.c2n * 0.3 * p.w2_n, rel=1e-6)
    assert clipped.c1_nominal[mid] == pytest.approx(p.c1n * (p.w1_n + 0.7 * p.w2_n), rel=1e-6)


def test_a_slope_s_gravity_along_the_heading_moves_load_as_braking_does() -> None:
    """Heading 0 on a pad falling ahead (the lateral component zero): at constant speed the car
    holds back m·g_x, which moves m·h·g_x/L of load forward; the steady state is eq. 6 and
    R = (L + K·u²)/δ with the axle stiffnesses of the shifted loads."""
    config = load_config()
    p = BicycleParams.from_config(config)
    u, delta, downhill, height = 12.0, math.radians(1.5), 0.4, 0.55  # g_x = 0.4 m/s² ahead
    drive = prepare(p, steady_drive(u, delta, seconds=40.0), cg_height_m=height)
    sim = run_model(drive, config.d_m, Mods(slope_sin_mps2=-downhill))
    forward = p.mass_kg * height * downhill / p.wheelbase_m
    c1, c2 = p.c1n * (p.w1_n + forward), p.c2n * (p.w2_n - forward)
    understeer = p.mass_kg / p.wheelbase_m * (p.b_m / c1 - p.a_m / c2)
    radius = u / sim.r[-1]
    assert radius == pytest.approx((p.wheelbase_m + understeer * u * u) / delta, rel=1e-6)
    expected = paper.sideslip_at_sensor(u, radius, config.d_m, c2 / p.w2_n, p.g)
    assert sim.beta[-1] == pytest.approx(math.atan(expected), abs=1e-6)
    level = run_model(drive, config.d_m)
    assert abs(sim.beta[-1] - level.beta[-1]) > 1e-4  # the shift is not lost in the tolerance


def test_a_force_that_follows_the_turn_follows_the_body_s_lean_across_a_slope() -> None:
    """Driving straight (no yaw rate) across a pad whose gravity pulls g_y sideways: the body
    leans with the specific force a_y − g_y = −g_y, so the force that follows the turn pushes
    g·f·tanh(−g_y/TURN_AY) — the same drive as a slope that much steeper and no such force; g
    the car's own (the config's gravity_mps2, here a pole's), not a constant of the model's."""
    from app.gap.nominal_model import TURN_AY_MPS2

    config = load_config()
    p = dataclasses.replace(BicycleParams.from_config(config), g=9.83)
    drive = prepare(p, steady_drive(12.0, 0.0, seconds=20.0))
    pull, force = 0.3, 0.025
    leaning = run_model(drive, config.d_m, Mods(slope_cos_mps2=pull, turn_force_g=force))
    extra = p.g * force * math.tanh(-pull / TURN_AY_MPS2)
    steeper = run_model(drive, config.d_m, Mods(slope_cos_mps2=pull + extra))
    assert np.allclose(leaning.beta, steeper.beta, rtol=0, atol=1e-15)
    assert abs(leaning.beta[-1] - run_model(drive, config.d_m, Mods(slope_cos_mps2=pull)).beta[-1]) > 1e-4
    level = run_model(drive, config.d_m, Mods(turn_force_g=force))  # nothing to lean with
    assert np.allclose(level.beta, run_model(drive, config.d_m).beta, rtol=0, atol=1e-15)


def test_the_roll_rate_moves_the_sensor_by_its_height_above_the_roll_axis() -> None:
    """A head h above the roll axis, rolling at p: its lateral velocity is v_s − p·h, so the
    sideslip it reads is atan((v_s − p·h)/u); h = sensor height − roll-axis height from the config."""
    config = load_config()
    p = BicycleParams.from_config(config)
    u, roll_rate = 12.0, math.radians(6.0)
    drive = steady_drive(u, math.radians(1.5))
    rolling = dataclasses.replace(drive, p=np.full(len(drive.t), roll_rate))
    lever = roll_lever_m(config)
    assert lever == pytest.approx(config.vehicle.sensor_height_m - config.vehicle.roll_axis_height_m)
    base = simulate(p, rolling, config.d_m)
    swayed = simulate(p, rolling, config.d_m, roll_lever_m=lever)
    v_sensor = u * math.tan(base.beta[-1])
    assert swayed.beta[-1] == pytest.approx(math.atan((v_sensor - roll_rate * lever) / u), abs=1e-12)
    assert abs(swayed.beta[-1] - base.beta[-1]) > math.radians(
        0.1
    )  # 6°/s at 0.35 m: 0.037 m/s, 0.18° at 12 m/s
    no_height = dataclasses.replace(config, vehicle=dataclasses.replace(config.vehicle, sensor_height_m=0.0))
    assert roll_lever_m(no_height) == 0.0
    default_axis = dataclasses.replace(
        config, vehicle=dataclasses.replace(config.vehicle, roll_axis_height_m=None)
    )
    assert roll_lever_m(default_axis) == pytest.approx(config.vehicle.sensor_height_m - 0.10)


def test_the_sideslip_gap_leaves_white_sensor_noise_out() -> None:
    """A residual of pure white noise of the estimated σ has no systematic part; a constant offset
    under the same noise is measured at its size."""
    config = load_config()
    drive = steady_drive(12.0, math.radians(1.5), seconds=600.0)
    pb = problem(drive, config)
    sim = pb.simulate()
    rng = np.random.default_rng(5)
    sigma = math.radians(0.3)
    noisy = dataclasses.replace(drive, beta=sim.beta + rng.normal(0.0, sigma, len(drive.t)))
    pb = dataclasses.replace(pb, measured=noisy, sigma_beta=sigma)
    rows = np.ones(len(drive.t), dtype=bool)
    raw = math.degrees(sigma) / math.sqrt(1.0 / drive.dt)  # what plain 1-s means would leave: 0.042°
    assert pb.rms_beta_deg(sim, rows) < raw / 3
    offset = dataclasses.replace(noisy, beta=noisy.beta + math.radians(0.2))
    assert dataclasses.replace(pb, measured=offset).rms_beta_deg(sim, rows) == pytest.approx(0.2, abs=0.01)


def measured_drive(tmp_path: Path, **sensor: float) -> Measured:
    config = load_config()
    drive = simulate_drive(config, DriveOptions(scenario="radii", seed=11, sensor=FAST_SENSORS | sensor))
    log = tmp_path / "drive.blf"
    write_drive(drive, log)
    return measure([log], config)


def test_a_yawed_sensor_head_is_named_and_sized(tmp_path: Path) -> None:
    result = diagnose(measured_drive(tmp_path, yaw_misalignment_deg=0.5), load_config()).result.to_json()
    assert result["diagnosis"] == "sensor_yaw_misalignment"
    best = result["candidates"][0]
    assert best["params"]["misalignment_deg"] == pytest.approx(0.5, abs=0.02)
    assert result["shrink_heldout"] > 0.7
    assert result["located"][0]["share"] > 0
    # the effects list: the head first, sized with an interval that holds the truth, in the
    # sideslip, beyond the drive's spread; it moves single crossings, the paired headline hardly
    head = result["effects"][0]
    assert head["effect"] == "sensor_yaw_misalignment" and head["matters"] and head["channel"] == "sideslip"
    low, high = head["ci95"]["misalignment_deg"]
    assert low < head["params"]["misalignment_deg"] < high and high - low < 0.1
    assert head["gain_sigmas"] > 2.5 and head["shrink_heldout"] > 0.7
    assert abs(head["c2n_effect_pct"]["crossing"]) > 10 * abs(head["c2n_effect_pct"]["headline"])
    assert result["tolerances"]["c2n_pct"] == 0.5


def test_a_drive_the_model_explains_is_none(tmp_path: Path) -> None:
    result = diagnose(measured_drive(tmp_path), load_config()).result.to_json()
    assert result["diagnosis"] == "none"
    # the rear steer the calibration would absorb is measured against the tyre's C2n the config
    # gives: none here, its interval holding zero, so it is not named as hidden
    roll = next(e for e in result["effects"] if e["effect"] == "roll_steer")
    low, high = roll["ci95"]["rear_steer_deg_per_mps2"]
    assert low < 0.0 < high and roll["measured_by"] == BY_RIG and roll["heldout_before"] is None
    assert result["confounded_with"] == [] and "roll steer" not in result["verdict"]
    # the camber step is CommonRoad's option, not calibrated on a config that does not ask for it
    assert "turn_force_pct" not in result["calibration"]
    assert result["shrink_heldout"] == 0.0
    # nothing found matters: every effect listed is within tolerance or not present, with its size
    assert all(not e["matters"] for e in result["effects"])
    assert all(e["judged"].startswith(("within tolerance", "not present")) for e in result["effects"])
    assert result["c2n"]["sim"] == pytest.approx(load_config().tyres.c2n_per_rad, rel=0.01)


def answered(
    effect: str, shrink: float, confounded: list[str] | None = None, total: float | None = None
) -> GapResult:
    """A diagnosis as gap-check scores it: the verdict, its confounded group, its shrink (alone and
    with a secondary effect beside it)."""
    return GapResult(
        diagnosis=effect,
        confounded_with=tuple(confounded or ()),
        secondary=(),
        calibration={},
        located=(),
        candidates=(),
        c2n=GapC2n(None, None, None, None, None, None, None),
        shrink_heldout=shrink,
        shrink_heldout_with_secondary=shrink if total is None else total,
        heldout_rms_deg=BeforeAfter(0.0, 0.0),
        heldout_yaw_rms_degps=BeforeAfter(0.0, 0.0),
        verdict=effect,
        action=None,
        separate_by={},
        noise=GapNoise(0.0, 0.0, 0.0),
        manoeuvres=0,
        speed_input="vehicle speed",
    )


def test_gap_check_scoring() -> None:
    truth = {
        "cases": {
            name: {"effect": {"name": effect, "size": 1.0}}
            for name, effect in [
                ("case_001", "none"),
                ("case_002", "none"),
                ("case_003", "roll_steer"),
                ("case_004", "speed_scale_error"),
                ("case_005", "signal_latency"),
            ]
        }
    }

    def said(
        effect: str, confounded: list[str] | None = None, shrink: float = 0.8, total: float | None = None
    ) -> GapResult:
        return answered(effect, shrink, confounded, total)

    answers = [
        CaseAnswer("case_001", said("none", shrink=0.0)),
        CaseAnswer("case_002", said("tyre_ply_steer", shrink=0.1)),  # a false alarm
        CaseAnswer("case_003", said("speed_scale_error", ["roll_steer"], 0.6, 0.85)),  # right, confounded
        CaseAnswer("case_004", said("speed_scale_error", shrink=0.9)),  # nothing secondary
        CaseAnswer("case_005", said("none", shrink=0.0)),  # missed
    ]
    scores = score(answers, truth)
    assert scores["accuracy"] == pytest.approx(3 / 5)
    assert scores["false_alarm_rate"] == pytest.approx(1 / 2)
    assert scores["shrink_heldout_median"] == pytest.approx(0.6)
    assert scores["shrink_with_secondary_median"] == pytest.approx(0.85)  # of 0.1, 0.85, 0.9
    assert scores["confusion"]["none -> tyre_ply_steer"] == 1


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main(argv)
    return code, out.getvalue(), err.getvalue()


def test_gap_cli_writes_json_and_report(tmp_path: Path) -> None:
    config = load_config()
    drive = simulate_drive(
        config,
        DriveOptions(scenario="constant_radius", seed=4, sensor=FAST_SENSORS | {"yaw_misalignment_deg": 0.6}),
    )
    log = tmp_path / "drive.blf"
    write_drive(drive, log)
    code, out, err = run_cli(
        ["gap", str(log), "--json", str(tmp_path / "gap.json"), "--report", str(tmp_path / "gap.html")]
    )
    assert code == 0, err
    result = json.loads((tmp_path / "gap.json").read_text())
    assert set(result) >= {"diagnosis", "confounded_with", "located", "candidates", "c2n", "shrink_heldout"}
    assert result["diagnosis"] == "sensor_yaw_misalignment" and "gap: sensor_yaw_misalignment" in out
    html = (tmp_path / "gap.html").read_text()
    assert html.count("<img") == 5 and "://" not in html  # self-contained: nothing fetched


def test_gap_on_a_log_without_the_optical_sensor_is_one_error_line(tmp_path: Path) -> None:
    log = tmp_path / "vehicle.log"
    log.write_text("(1700000000.000000) can0 415#0000000000000000\n" * 50)
    code, _, err = run_cli(["gap", str(log)])
    assert code == 1
    assert err.strip().startswith("c2n: error: ") and "optical" in err and "\n" not in err.strip()


# -- a real test day: calibrate the nuisances, bound the effects, name only what shrinks the gap --

HANDBOOK = {
    "c1n_per_rad = 13.0": "c1n_per_rad = 11.05",
    "c2n_per_rad = 14.87": "c2n_per_rad = 17.84",
    "c2n_tolerance_pct = 5.0": "c2n_tolerance_pct = 20.0",  # a handbook's figure, said so
}
TEST_DAY = {"gyro_bias_degps": 0.06, "steer_offset_deg": 1.5, "steering_ratio": 15.4}


def handbook_config(tmp_path: Path) -> Path:
    """The default car with C1n 15 % low and C2n 20 % high: a handbook's values, not the car's."""
    text = (REPO / "config" / "mondeo.toml").read_text().replace('"../dbc/', f'"{REPO}/dbc/')
    for old, new in HANDBOOK.items():
        assert old in text
        text = text.replace(old, new)
    path = tmp_path / "handbook.toml"
    path.write_text(text)
    return path


def test_the_nuisances_of_a_test_day_are_calibrated_not_diagnosed(tmp_path: Path) -> None:
    """Gyro bias, steering-wheel offset, a steering ratio 3 % off and C1n/C2n 15–20 % off the
    config: each is fitted near its truth, inside its interval, and the verdict is none."""
    config = load_config(handbook_config(tmp_path))
    result = diagnose(measured_drive(tmp_path, **TEST_DAY), config).result
    calibration = result.calibration
    truth = {
        "yaw_rate_bias_degps": 0.06,
        "steering_offset_deg": 1.5,
        "steering_ratio": 15.4,
        "c1n_per_rad": 13.0,
        "c2n_per_rad": 14.87,
    }
    for name, value in truth.items():
        fitted = calibration[name]
        assert fitted.nominal == pytest.approx(
            {"steering_ratio": 15.0, "c1n_per_rad": 11.05, "c2n_per_rad": 17.84}.get(name, 0.0)
        )
        assert fitted.fitted == pytest.approx(value, rel=0.03, abs=0.02), name
        assert fitted.ci95[0] < fitted.fitted < fitted.ci95[1] and not fitted.at_bound, name
    assert result.diagnosis == "none" and result.shrink_heldout == 0.0 and result.action is None
    assert result.c2n.calibrated == pytest.approx(14.87, rel=0.03)


def test_a_yawed_head_is_named_on_a_test_day_with_a_handbook_config(tmp_path: Path) -> None:
    """The issue's case: 0.3° of misalignment with C1n 15 % low and C2n 20 % high (it used to
    be named roll_steer, shrink 1 %): named, sized, with what to do, and C2n with it taken out."""
    config = load_config(handbook_config(tmp_path))
    result = diagnose(measured_drive(tmp_path, yaw_misalignment_deg=0.3, **TEST_DAY), config).result
    assert result.diagnosis == "sensor_yaw_misalignment"
    named = next(c for c in result.candidates if c.named)
    assert named.params["misalignment_deg"] == pytest.approx(0.3, abs=0.02)
    assert result.shrink_heldout > 0.7 and named.at_bound == ()
    assert result.action is not None and "0.30° to the left" in result.action
    assert result.c2n.corrected == pytest.approx(14.87, rel=0.03)
    assert all(not c.named or c.shrink_heldout >= 0 for c in result.candidates)


def test_a_fit_on_its_physical_bound_is_reported_and_never_named(tmp_path: Path) -> None:
    """A head yawed 4° is beyond the ±3° a mount allows: the fit ends on the bound, says so, and
    the verdict is not that effect (the drive is unexplained by the vocabulary)."""
    result = diagnose(measured_drive(tmp_path, yaw_misalignment_deg=4.0), load_config()).result
    yawed = next(c for c in result.candidates if c.effect == "sensor_yaw_misalignment")
    assert "misalignment_deg" in yawed.at_bound and yawed.params["misalignment_deg"] == pytest.approx(3.0)
    assert not yawed.named and "physical bound" in (yawed.why_not or "")
    assert result.diagnosis == "unexplained" and "no candidate effect" in result.verdict
    assert all(not (set(c.at_bound) and c.named) for c in result.candidates)


def test_a_speed_scale_error_is_named_from_the_vehicle_speed_signal(tmp_path: Path) -> None:
    """The optical speed is right; the vehicle's reads 3 % high. The calibration cannot absorb
    it in that signal, so it is named there, with its size, and the sideslip gap does not grow."""
    result = diagnose(measured_drive(tmp_path, speed_scale=1.03), load_config()).result
    assert result.diagnosis == "speed_scale_error"
    named = next(c for c in result.candidates if c.named)
    assert named.params["speed_scale_pct"] == pytest.approx(3.0, abs=0.1)
    assert result.shrink_heldout >= 0.0 and "vehicle speed signal" in result.verdict
    [scale] = [e for e in result.effects if e.effect == "speed_scale_error"]
    assert scale.channel == "speed" and scale.matters and scale.c2n_effect_pct.headline in (0.0, None)


def test_an_effect_beside_the_dominant_one_is_secondary(tmp_path: Path) -> None:
    """A yawed head and a vehicle bus 0.15 s late: the head is named; the latency, seen in the
    vehicle speed signal once the sideslip is explained, is listed beside it with its size."""
    result = diagnose(
        measured_drive(tmp_path, yaw_misalignment_deg=0.6, vehicle_latency_s=0.15), load_config()
    ).result
    assert result.diagnosis == "sensor_yaw_misalignment"
    [also] = [s for s in result.secondary if s.effect == "signal_latency"]
    assert also.params["latency_s"] == pytest.approx(0.15, abs=0.03) and also.shrink_heldout >= 0.0
    assert "lags the optical sensor" in also.action


def test_the_gap_command_says_what_it_found_and_what_to_do(tmp_path: Path) -> None:
    config_path = handbook_config(tmp_path)
    drive = simulate_drive(
        load_config(config_path),
        DriveOptions(
            scenario="radii", seed=11, sensor=FAST_SENSORS | TEST_DAY | {"yaw_misalignment_deg": 0.3}
        ),
    )
    log = tmp_path / "drive.blf"
    write_drive(drive, log)
    code, out, err = run_cli(
        ["gap", str(log), "--config", str(config_path), "--json", str(tmp_path / "g.json")]
    )
    assert code == 0, err
    assert out.startswith("gap: sensor_yaw_misalignment")
    assert "what it means: the sensor head is yawed 0.3" in out
    assert "steering-wheel centre offset" in out and "C2n (rear axle)" in out
    assert "sensor_yaw_misalignment     MATTERS: misalignment_deg +0.3" in out and "what to do:" in out
    result = json.loads((tmp_path / "g.json").read_text())
    assert set(result) >= {
        "diagnosis",
        "confounded_with",
        "secondary",
        "calibration",
        "located",
        "candidates",
        "c2n",
        "shrink_heldout",
        "effects",
    }
    for effect in result["effects"]:
        assert set(effect) >= {
            "effect",
            "channel",
            "params",
            "ci95",
            "shrink_heldout",
            "c2n_effect_pct",
            "matters",
        }
        assert set(effect["c2n_effect_pct"]) == {"crossing", "headline"}
    assert set(result["calibration"]["c2n_per_rad"]) == {"nominal", "fitted", "ci95", "at_bound", "held"}
    assert all(c["at_bound"] == [] or not c["named"] for c in result["candidates"])


def test_gap_check_scores_each_generator_and_counts_a_missing_case_as_failed() -> None:
    truth = {
        "cases": {
            "case_001": {"effect": {"name": "none", "size": 0.0}, "model": "two_track"},
            "case_002": {"effect": {"name": "roll_steer", "size": 0.1}, "model": "two_track"},
            "case_003": {"effect": {"name": "signal_latency", "size": 0.2}, "model": "commonroad"},
            "case_004": {"effect": {"name": "none", "size": 0.0}, "model": "commonroad"},
        }
    }

    def said(effect: str, shrink: float) -> GapResult:
        return answered(effect, shrink)

    answers = [  # case_004's log was deleted: it has no answer
        CaseAnswer("case_001", said("none", 0.0)),
        CaseAnswer("case_002", said("roll_steer", 0.8)),
        CaseAnswer("case_003", said("signal_latency", 0.6)),
    ]
    scores = score(answers, truth)
    assert scores["n"] == 4 and scores["accuracy"] == pytest.approx(3 / 4) and scores["errors"] == 1
    assert scores["generators"]["two_track"]["accuracy"] == 1.0
    commonroad = scores["generators"]["commonroad"]
    assert commonroad["n"] == 2 and commonroad["accuracy"] == 0.5 and commonroad["none_cases"] == 1
    [missing] = [row for row in scores["cases"] if row["case"] == "case_004"]
    assert missing["diagnosis"] == "error" and "no drive log" in missing["error"]


def test_a_car_without_stiffness_or_a_drive_too_short_is_one_error_line(tmp_path: Path) -> None:
    text = (REPO / "config" / "mondeo.toml").read_text().replace('"../dbc/', f'"{REPO}/dbc/')
    zero = tmp_path / "zero.toml"
    zero.write_text(text.replace("c2n_per_rad = 14.87", "c2n_per_rad = 0.0"))
    drive = simulate_drive(load_config(), DriveOptions(scenario="radii", seed=11, sensor=FAST_SENSORS))
    log = tmp_path / "drive.blf"
    write_drive(drive, log)
    code, _, err = run_cli(["gap", str(log), "--config", str(zero)])
    assert (
        code == 1
        and err.strip()
        == f"c2n: error: {zero}: [tyres] c2n_per_rad = 0.0 is out of range — use above 0 up to 200"
    )
    short = tmp_path / "short.blf"
    write_drive(dataclasses.replace(drive, messages=drive.messages[: len(drive.messages) // 20]), short)
    code, _, err = run_cli(["gap", str(short)])
    assert code == 1 and "too short to diagnose" in err and "\n" not in err.strip()


@pytest.mark.parametrize(
    ("downhill_deg", "said"),
    [(-90.0, "90° right of the start"), (30.0, "30° left of"), (0.0, "straight ahead"), (180.0, "behind")],
)
def test_a_slope_is_said_to_fall_where_its_gravity_points(downhill_deg: float, said: str) -> None:
    """A pad falling towards D (from the start heading, left positive) pulls the car sideways by
    g·s·sin(D − ψ) at heading ψ: the components the fit gives are A = −s·cos D, B = s·sin D."""
    slope = next(c for c in CANDIDATES if c.effect == "road_cross_slope")
    grade, d = 2.5, math.radians(downhill_deg)
    text = slope.action((-grade * math.cos(d), grade * math.sin(d)))
    assert "slopes 2.5 %" in text and said in text


def test_a_constant_sideslip_offset_moves_a_crossing_by_r_delta_over_d_and_pairing_cancels_it() -> None:
    """A crossing on radius R reads C2n·(1 + R·Δ/d) with Δ added to the sideslip: 0.02° at R = 30 m,
    d = 1 m is 1.05 %; left and right turns move opposite ways, so the paired headline stays."""
    from app.gap.effects import c2n_shift

    n, d, c2n, g, radius = 400, 1.0, 15.0, 9.81, 30.0
    u = np.full(n, math.sqrt(g * d * c2n))  # at the crossing's speed
    r = np.r_[np.full(n // 2, u[0] / radius), np.full(n // 2, -u[0] / radius)]
    m = Measured.__new__(Measured)
    object.__setattr__(m, "u_optical", u)
    object.__setattr__(m, "r", r)
    object.__setattr__(m, "steady", np.ones(n, dtype=bool))
    object.__setattr__(m, "dt", 0.02)
    delta = np.full(n, math.radians(0.02))
    shift = c2n_shift(m, np.ones(n, dtype=bool), delta, d, c2n, g)
    expected = 100 * radius * math.radians(0.02) / d
    assert abs(shift.crossing or 0.0) == pytest.approx(expected, rel=1e-3)
    assert shift.headline == pytest.approx(0.0, abs=1e-6)
    # a sensor 5 cm off (Δ = Δd·κ) moves every crossing and the headline by Δd/d alike
    shift = c2n_shift(m, np.ones(n, dtype=bool), 0.05 * r / u, d, c2n, g)
    assert shift.crossing == pytest.approx(5.0, rel=1e-3) and shift.headline == pytest.approx(5.0, rel=1e-3)


def test_the_held_out_gain_counts_manoeuvres_as_samples() -> None:
    """Per manoeuvre, a gain equal everywhere stands infinitely far above zero; gains of ±1 around
    a mean of 0.5 over 16 manoeuvres stand 0.5/(σ/4) standard errors above it."""
    from app.gap.effects import Z_TEST, gain_z, unit_gaps

    t = np.arange(0.0, 16.0, 0.02)
    ids = (t // 1.0).astype(int)  # 16 one-second manoeuvres
    res = np.ones_like(t)
    per_unit = unit_gaps(t, res, np.ones(len(t), dtype=bool), ids)
    assert per_unit == pytest.approx(np.full(16, 50.0))  # one block of 50 samples of 1: 50²/50
    assert gain_z(per_unit, per_unit / 2) == math.inf
    d = np.where(np.arange(16) % 2 == 0, 1.5, -0.5)
    assert gain_z(d + 10, np.full(16, 10.0)) == pytest.approx(0.5 / (np.std(d, ddof=1) / 4))
    assert 2.4 < Z_TEST < 2.6  # 95 % shared among the eight candidates


def test_the_camber_step_is_calibrated_only_where_the_config_asks(tmp_path: Path) -> None:
    from app.gap.candidates import nuisances

    assert "turn_force_pct" not in {p.name for p in nuisances(load_config())}
    commonroad = load_config(REPO / "config" / "commonroad_vehicle2.toml")
    assert commonroad.gap.turn_force and "turn_force_pct" in {p.name for p in nuisances(commonroad)}


@pytest.mark.parametrize(
    ("line", "says"),
    [
        ("c2n_pct = -1", "[gap] c2n_pct = -1.0 is out of range"),
        ("turn_force = 1", "[gap] turn_force must be true or false"),
        ("sideslip = 0.1", "unknown key 'sideslip' in [gap]"),
    ],
)
def test_a_bad_gap_tolerance_is_one_line_naming_it(tmp_path: Path, line: str, says: str) -> None:
    text = (REPO / "config" / "mondeo.toml").read_text().replace('"../dbc/', f'"{REPO}/dbc/')
    path = tmp_path / "bad.toml"
    path.write_text(text + f"\n[gap]\n{line}\n")
    code, _, err = run_cli(["gap", str(tmp_path / "none.blf"), "--config", str(path)])
    assert code == 1 and says in err and "Traceback" not in err


def test_gap_check_counts_the_tyres_softening_as_held_and_other_findings_on_a_clean_drive_false() -> None:
    """Every generator's tyres soften with slip: a clean drive whose report leads with that
    softening names what the drive holds; one that also finds a yawed head names what it does not."""
    truth = {"cases": {f"case_00{k}": {"effect": {"name": "none", "size": 0.0}} for k in (1, 2)}}

    def with_findings(*names: str) -> GapResult:
        found = tuple(
            Effect(
                effect=name,
                channel="sideslip",
                params={},
                ci95={},
                shrink_heldout=0.0,
                heldout_before=None,
                heldout_after=None,
                gain_sigmas=6.0,
                c2n_effect_pct=C2nEffect(-1.2, 0.0),
                matters=True,
                judged="matters",
                confounded_with=(),
                action="",
            )
            for name in names
        )
        return dataclasses.replace(answered(names[0], 0.0), effects=found)

    answers = [
        CaseAnswer("case_001", with_findings("load_transfer_nonlinearity")),
        CaseAnswer("case_002", with_findings("load_transfer_nonlinearity", "sensor_yaw_misalignment")),
    ]
    scores = score(answers, truth)
    rows = {row["case"]: row for row in scores["cases"]}
    assert rows["case_001"]["correct"] and not rows["case_002"]["correct"]
    assert rows["case_002"]["false_findings"] == ["sensor_yaw_misalignment"]
    assert scores["false_alarms"] == 1


def test_the_compiled_model_is_the_numpy_reference_step_for_step() -> None:
    """``run_model`` (one compiled loop) against ``run_model_reference`` (numpy around ``step_lateral``) on a
    turning, speeding-up drive with gaps in its yaw rate, with no modification, with every one
    at once and with the vehicle bus early or late: every output within 1e-12 of its range."""
    config = load_config()
    p = BicycleParams.from_config(config)
    base = steady_drive(12.0, math.radians(1.5), seconds=30.0)
    n = len(base.t)
    wobble = np.sin(base.t / 3.0)
    r = 0.2 * (1.0 + 0.3 * wobble)  # rad/s
    r[n // 3 : n // 3 + 40] = np.nan  # a stretch the yaw rate was not read
    drive = dataclasses.replace(
        base, u_optical=12.0 + 0.2 * base.t, delta=base.delta * (1.0 + 0.5 * wobble), r=r, p=0.02 * wobble
    )
    prepared = prepare(p, drive, cg_height_m=0.55, roll_lever_m=0.4)
    prepared = dataclasses.replace(prepared, delta_late=True, r_late=True)
    every = Mods(
        yaw_bias_radps=0.002,
        yaw_scale=0.01,
        steer_offset_rad=0.001,
        ratio_error=0.03,
        c1n_factor=1.1,
        c2n_factor=0.9,
        turn_force_g=0.01,
        misalignment_rad=0.002,
        d_error_m=0.05,
        speed_scale=0.02,
        latency_s=0.05,
        slope_sin_mps2=0.1,
        slope_cos_mps2=-0.05,
        softening1_per_mps4=0.01,
        softening2_per_mps4=0.02,
        roll_steer_rad_per_mps2=0.001,
        ply_rad=0.0005,
    )
    for mods in (Mods(), every, Mods(latency_s=-0.033), Mods(latency_s=0.013, softening2_per_mps4=0.5)):
        compiled, reference = (
            run_model(prepared, config.d_m, mods),
            run_model_reference(prepared, config.d_m, mods),
        )
        for name in ("beta", "r", "r_measured", "ay", "speed_reading"):
            a, b = getattr(compiled, name), getattr(reference, name)
            assert np.array_equal(np.isnan(a), np.isnan(b)), name
            assert np.nanmax(np.abs(a - b)) <= 1e-12 * np.nanmax(np.abs(b)), (name, mods)


def test_gap_of_two_drives_or_one_drive_twice_is_refused_as_analyze_refuses(
    drive_log: Path, tmp_path: Path
) -> None:
    """`c2n gap` merges its logs as one drive's channels: two drives on two sets of tyres gave a
    confident `roll_steer`, the axle's C2n +9 % from the tyre's, with no word; a drive and a copy
    of part of it were diagnosed as one. Each is now analysed alone first, as analyze does."""
    other = tmp_path / "other tyres.blf"
    with can.Logger(other) as writer:
        for m in cached_drive("constant_radius", 42, 18.0).messages:
            writer.on_message_received(m)
    code, out, err = run_cli(["gap", str(drive_log), str(other), "--json", str(tmp_path / "g.json")])
    assert code == 1 and err.startswith("c2n: error: the drives disagree, each alone: ") and out == "", err
    assert err.endswith("diagnose each drive alone (the logs of one gap are one drive's channels, merged)\n")
    copy = tmp_path / "copy.blf"
    copy.write_bytes(drive_log.read_bytes())
    code, _, err = run_cli(["gap", str(drive_log), str(copy)])
    assert code == 1 and "hold the same driving" in err and not (tmp_path / "g.json").exists()
