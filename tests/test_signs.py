"""Do the yaw rate, the lateral acceleration and the steering agree in sign? Circles at one speed
hold d at the tape's value, so a flipped yaw rate moved C2n without a trace in the fit (55.7 for
14.9, no warning): the car's own a_y and steering now vote, and the odd one out is named."""

import json
from pathlib import Path

import pytest

from app.detect.signs import MIN_VOTES, SignVotes, odd_sign, yaw_rate_flipped
from tests.test_reliability_inputs import FLIPPED_SIDESLIP, FLIPPED_YAW, config_with, run_cli

STEER = 'steer = "SteeringPinion_Data.StePinComp_An_Est"'
AY = 'ay = "Accel_Data_FD1.VehLat2_A_Actl"'
FLIPPED_AY = (AY, 'ay = {signal = "Accel_Data_FD1.VehLat2_A_Actl", scale = -1.0}')
FLIPPED_STEER = (STEER, 'steer = {signal = "SteeringPinion_Data.StePinComp_An_Est", scale = -1.0}')
NO_STEER = (STEER, "")
NO_AY = (AY, "")
NO_YAW = ('yaw_rate = "AngVelHor.AngVelZ_hor"', "")


def test_one_sample_votes_per_tenth_of_a_second_and_only_in_a_corner() -> None:
    votes = SignVotes()
    for k in range(100):  # 1 s at 100 Hz, turning left, a_y and steering with the yaw rate
        t = 0.01 * k
        if t >= votes.next_t:
            votes.add(t, 20.0, 0.1, 2.0, 0.3)
    assert (votes.ay_with, votes.ay_against, votes.steer_with, votes.steer_against) == (10, 0, 10, 0)
    assert 1.0 <= votes.next_t <= 1.02  # the last vote at 0.9 s, or a sample after it
    votes.add(2.0, 20.0, 0.01, -2.0, -0.3)  # |u·r| 0.2 m/s²: not a corner
    votes.add(3.0, 20.0, -0.1, float("nan"), 0.01)  # a_y missing, the wheel inside its offset
    votes.add(4.0, 20.0, -0.1, 2.0, None)  # right turn, a_y to the left: against
    assert (votes.ay_with, votes.ay_against, votes.steer_with, votes.steer_against) == (10, 1, 10, 0)


def test_the_odd_one_out_is_named() -> None:
    n = MIN_VOTES
    assert yaw_rate_flipped(SignVotes(0, n, 0, n)) is True  # a_y and steering against it
    assert yaw_rate_flipped(SignVotes(0, n)) is True  # a_y against, no steering to tell: not trusted
    assert yaw_rate_flipped(SignVotes(0, n, n, 0)) is False  # the steering sides with it: a_y is odd
    assert "role ay" in (odd_sign(SignVotes(0, n, n, 0), False) or "")
    assert "role steer" in (odd_sign(SignVotes(n, 0, 0, n), False) or "")
    assert yaw_rate_flipped(SignVotes(n, 0, n, 0)) is False and odd_sign(SignVotes(n, 0, n, 0), False) is None
    assert yaw_rate_flipped(SignVotes(0, n - 1, 0, n - 1)) is None  # too few votes
    assert yaw_rate_flipped(SignVotes(n, n, n, n)) is None  # split: a noisy sensor, not a sign
    assert "is the role ay the car's lateral axis" in (odd_sign(SignVotes(n, n, n, 0), False) or "")


@pytest.fixture(scope="module")
def circles(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """Circles at 1.25·u0 on three radii both ways (two-track, C2n 14.87): no sweep, d held."""
    out = tmp_path_factory.mktemp("signs") / "circles.blf"
    code, _, err = run_cli(["simulate", "--session", "circles", "--seed", "3", "--out", str(out)])
    assert code == 0, err
    return out


def analyse(log: Path, tmp_path: Path, *flips: tuple[str, str]) -> tuple[str, dict]:
    config = config_with(tmp_path, *flips)
    result = tmp_path / "result.json"
    code, out, err = run_cli(["analyze", str(log), "--config", str(config), "--json", str(result)])
    assert code == 0 and "Traceback" not in err, err
    return out, json.loads(result.read_text())


def test_circles_at_one_speed_with_the_yaw_rate_flipped_give_no_c2n_but_the_role(
    circles: Path, tmp_path: Path
) -> None:
    out, result = analyse(circles, tmp_path, FLIPPED_YAW)
    assert result["c2n"] is None  # the fit alone read 55.7 for 14.87, and said nothing
    votes = result["sign_votes"]
    assert votes["ay_with"] == votes["steer_with"] == 0 and votes["ay_against"] >= 1000
    assert "C2n: no result (the yaw rate turns against the lateral acceleration and the steering" in out
    assert "the yaw rate is the wrong way round, or ay and steer both are (a vehicle bus in SAE axes" in out
    assert "check `scale` of the role yaw_rate (+ turning left), or of ay and steer (+ to the left)" in out
    assert result["warnings"][0].startswith("the yaw rate turns against")
    assert not any("soften" in w or "d is the config's" in w for w in result["warnings"])  # no fit's terms


def test_without_steering_a_yaw_rate_against_a_y_names_both(circles: Path, tmp_path: Path) -> None:
    out, result = analyse(circles, tmp_path, FLIPPED_YAW, NO_STEER)
    assert result["c2n"] is None
    assert "check `scale` of the roles yaw_rate (+ turning left) and ay (+ to the left)" in out


def test_without_a_y_the_steering_alone_names_both(circles: Path, tmp_path: Path) -> None:
    out, result = analyse(circles, tmp_path, FLIPPED_YAW, NO_AY)
    assert result["c2n"] is None and "the yaw rate turns against the steering in 100 %" in out
    assert "check `scale` of the roles yaw_rate (or ay, where it gives the yaw rate" in out
    assert result["sign_votes"]["ay_with"] + result["sign_votes"]["ay_against"] == 0


def test_where_a_y_gives_the_yaw_rate_it_does_not_vote_and_the_steering_does(
    circles: Path, tmp_path: Path
) -> None:
    """No gyro: the filter's yaw rate is a_y/u, which agrees with a_y by construction. A flipped a_y
    there is a flipped yaw rate (C2n 3.7 times the truth at one speed): the steering says so."""
    _, plain = analyse(circles, tmp_path, NO_YAW)
    assert plain["c2n"] == pytest.approx(14.87, rel=0.03) and plain["sign_votes"]["ay_with"] == 0
    out, result = analyse(circles, tmp_path, NO_YAW, FLIPPED_AY)
    assert result["c2n"] is None and "the yaw rate turns against the steering in 100 %" in out


def test_without_steering_on_sweeps_the_yaw_rate_is_the_likely_one(drive_log: Path, tmp_path: Path) -> None:
    """The sensor behind the axle and a_y against the yaw rate: one flip (the yaw rate) explains
    both; the sideslip alone would leave a_y with it."""
    out, result = analyse(drive_log, tmp_path, FLIPPED_YAW, NO_STEER)
    assert result["c2n"] is None
    assert "most likely the yaw rate (it turns against the lateral acceleration in 100 %" in out


@pytest.mark.parametrize(("flip", "role"), [(FLIPPED_AY, "role ay"), (FLIPPED_STEER, "role steer")])
def test_a_y_or_steering_flipped_leave_c2n_and_say_so(
    circles: Path, tmp_path: Path, flip: tuple[str, str], role: str
) -> None:
    _, plain = analyse(circles, tmp_path)
    assert plain["c2n"] == pytest.approx(14.87, rel=0.02)
    assert not any("wrong way round" in w or "check `scale`" in w for w in plain["warnings"])
    _, result = analyse(circles, tmp_path, flip)
    assert result["c2n"] == plain["c2n"]
    assert sum(role in w for w in result["warnings"]) == 1


def test_circles_at_one_speed_with_the_sideslip_flipped_are_held_against_the_nominal(
    circles: Path, tmp_path: Path
) -> None:
    """Nothing in circles at one speed shows a flipped sideslip (the votes are the car's a_y,
    steering and yaw rate, which agree): the reading, 3.7 times the config's nominal, is kept,
    and what the other sign would read is said."""
    _, result = analyse(circles, tmp_path, *FLIPPED_SIDESLIP)
    assert result["c2n"] > 3.0 * 14.87
    [warning] = [w for w in result["warnings"] if "with the sideslip the other way round" in w]
    assert "check `scale` of the roles vy and beta" in warning
    other = float(warning.split("would read ")[1].split(":")[0])
    assert other == pytest.approx(14.87, rel=0.03)
    assert not any("drive a circle of radius" in w for w in result["warnings"])  # advice from the reading


@pytest.mark.parametrize(
    ("flips", "named"),
    [
        ((FLIPPED_YAW,), "the yaw rate is the one (it turns against the lateral acceleration and the"),
        (FLIPPED_SIDESLIP, "the sideslip is the wrong way round (the yaw rate turns with the lateral"),
    ],
    ids=["yaw rate", "vy and beta"],
)
def test_on_sweeps_the_votes_say_which_role_put_the_sensor_behind_the_axle(
    drive_log: Path, tmp_path: Path, flips: tuple[tuple[str, str], ...], named: str
) -> None:
    out, result = analyse(drive_log, tmp_path, *flips)
    assert result["c2n"] is None and named in out
    assert not any("soften" in w or "slopes" in w for w in result["warnings"])  # the flipped fit's terms


def test_yaw_rate_and_sideslip_both_flipped_cancel_and_are_named(drive_log: Path, tmp_path: Path) -> None:
    _, plain = analyse(drive_log, tmp_path)
    _, result = analyse(drive_log, tmp_path, FLIPPED_YAW, *FLIPPED_SIDESLIP)
    assert result["c2n"] == pytest.approx(plain["c2n"], rel=1e-9) and result["c2n"] is not None
    assert any("so C2n stands" in w and "both yaw_rate and vy/beta" in w for w in result["warnings"])


def test_a_vehicle_bus_in_sae_axes_is_named_beside_the_yaw_rate(
    drive_log: Path, circles: Path, tmp_path: Path
) -> None:
    """ay and steer both + to the right (one bus, its axes): on sweeps the sideslip sides with the
    yaw rate, so C2n stands and the bus is named; at one speed nothing tells the bus from a flipped
    yaw rate, so there is no C2n and both fixes are named."""
    _, plain = analyse(drive_log, tmp_path)
    _, result = analyse(drive_log, tmp_path, FLIPPED_AY, FLIPPED_STEER)
    assert result["c2n"] == plain["c2n"]
    assert any("so C2n stands: ay and steer (a vehicle bus in SAE axes)" in w for w in result["warnings"])
    out, result = analyse(circles, tmp_path, FLIPPED_AY, FLIPPED_STEER)
    assert result["c2n"] is None and "or ay and steer both are (a vehicle bus in SAE axes" in out


@pytest.mark.parametrize(
    ("flips", "role"), [((FLIPPED_YAW,), "role yaw_rate"), (FLIPPED_SIDESLIP, "roles vy and beta")]
)
def test_gap_with_a_role_the_wrong_way_round_names_the_role_and_diagnoses_nothing(
    drive_log: Path, tmp_path: Path, flips: tuple[tuple[str, str], ...], role: str
) -> None:
    """A yaw rate or a sideslip the wrong way round read as an effect: `sensor_position_error`,
    the sensor 1.1 m behind the rear axle, `measure d again`, and a C2n line printing Python's
    None. The gap now refuses as analyze does, naming the role."""
    config = config_with(tmp_path, *flips)
    out_json = tmp_path / "gap.json"
    code, out, err = run_cli(["gap", str(drive_log), "--config", str(config), "--json", str(out_json)])
    assert code == 1 and err.count("\n") == 1 and f"{drive_log}: no diagnosis — " in err, err
    assert f"check `scale` of the {role}" in err and not out_json.exists()
    assert "None" not in out + err and "sensor_position_error" not in out + err


VX = 'vx = "Correvit.VelX_cor"'
FLIPPED_VX = (VX, 'vx = {signal = "Correvit.VelX_cor", scale = -1.0}')


def test_a_flipped_optical_speed_is_named_not_blamed_on_the_driving(drive_log: Path, tmp_path: Path) -> None:
    """vx the wrong way round read `no cornering in the drive: drive steady circles …` and told the
    driver to drive again: the drive moved backwards by the optical speed, which a test drive
    does not, and the result says which role and how to turn it."""
    _, plain = analyse(drive_log, tmp_path)
    assert plain["cornering"]["backwards_s"] == 0.0 and plain["c2n"] is not None
    out, result = analyse(drive_log, tmp_path, FLIPPED_VX)
    assert result["c2n"] is None and result["cornering"]["backwards_s"] > 30.0
    assert "C2n: no result (the optical speed reads backwards (" in out
    assert "s forwards): vx's sign is the wrong way round, or the head faces the rear" in out
    assert "set [roles] vx's scale = 1 (and vy's turned too" in out  # the config's -1.0, turned back
    assert not result["warnings"] or not any(  # nothing else blamed: the driving, the filter's noise
        "sweep the speed" in w or "lost the car" in w for w in result["warnings"]
    )
    assert "drive steady circles" not in out


@pytest.mark.parametrize(
    ("change", "said"),
    [
        (
            NO_STEER,
            "no steering angle in the drive: the model is driven by it — give its signal as [roles] steer",
        ),
        (FLIPPED_VX, "the optical speed reads backwards ("),
    ],
)
def test_gap_names_what_the_drive_lacks_not_its_length(
    drive_log: Path, tmp_path: Path, change: tuple[str, str], said: str
) -> None:
    """Both said `too short to diagnose: 0 s of usable driving … drive the standard session`."""
    config = config_with(tmp_path, change)
    code, _, err = run_cli(["gap", str(drive_log), "--config", str(config)])
    assert code == 1 and err.count("\n") == 1, err
    assert f"c2n: error: {said}" in err and "too short" not in err


def test_gap_names_a_role_whose_frames_the_log_lacks(drive_log: Path, tmp_path: Path) -> None:
    """The steering's role set but its message not in the log: gap said `give its signal as
    [roles] steer` of a role the config gives."""
    import can

    steer_id = 0x7E  # SteeringPinion_Data (vehicle_ford.dbc)
    log = tmp_path / "no-steer-frames.blf"
    with can.LogReader(drive_log) as reader, can.Logger(log) as writer:
        for message in reader:
            if message.arbitration_id != steer_id:
                writer.on_message_received(message)
    code, _, err = run_cli(["gap", str(log)])
    assert code == 1 and err.count("\n") == 1, err
    assert "no steering angle in the drive: the log has no frames of [roles] steer's " in err
    assert "SteeringPinion_Data.StePinComp_An_Est — the model is driven by it: record it" in err
