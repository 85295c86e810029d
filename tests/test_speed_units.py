"""A speed in the wrong unit: the vehicle speed and the optical vx compared (``app/detect/speeds.py``).

A vx read in mph gave C2n 23.40 [21.92, 25.09] for 14.87, and the warnings blamed d and the
filter's q_u. The two speeds measure one u; their ratio is bounded by a tyre's rolling radius
(±3 %), a wheel's place in the turn (±4 %) and a speedometer's tolerance (UNECE R39: up to
10 % + 4 km/h high)."""

import json
from pathlib import Path

import numpy as np
import pytest

from app.config import load_config
from app.detect.signs import MIN_VOTES, VOTE_EVERY_S
from app.detect.speeds import SpeedVotes, band, speed_backwards, speed_unit_problem
from app.pipeline import Pipeline
from app.run_loop import run
from tests.simulated import REPO
from tests.test_campaign import run_cli


def _votes(ratio: float, n: int, speed: float = 12.0) -> SpeedVotes:
    votes = SpeedVotes(4.0)
    t = (np.arange(n) + 0.5) * VOTE_EVERY_S  # one in each vote's slot
    votes.add_block(t, np.full(n, ratio * speed), np.full(n, speed))
    return votes


def test_the_band_is_a_tyre_a_wheel_and_a_speedometer() -> None:
    low, high = band(10.0)
    assert low == pytest.approx(0.97 * 0.96)
    assert high == pytest.approx(1.03 * 1.04 * (1.10 + (4.0 / 3.6) / 10.0))


@pytest.mark.parametrize(
    ("ratio", "unit"),
    [
        (0.44704 / (1 / 3.6), "mph against km/h"),
        ((1 / 3.6) / 0.44704, "km/h against mph"),
        (3.6, "m/s against km/h"),
    ],
)
def test_a_unit_mistake_is_named(ratio: float, unit: str) -> None:
    problem = speed_unit_problem(_votes(ratio, MIN_VOTES))
    assert problem is not None and problem.startswith("the vehicle speed reads ")
    said = float(problem.split("reads ")[1].split()[0])
    assert said == pytest.approx(ratio, rel=0.01)  # the median, to 1 %
    assert f"{said:.2f} is {unit}" in problem


def test_what_a_tyre_and_a_speedometer_allow_is_no_problem() -> None:
    assert speed_unit_problem(_votes(0.94, 10 * MIN_VOTES)) is None  # a worn tyre on the inside wheel
    assert (
        speed_unit_problem(_votes(1.20, 10 * MIN_VOTES, speed=20.0)) is None
    )  # a speedometer's +10 % + 4 km/h
    at_20 = band(20.0)[1]
    outside = speed_unit_problem(_votes(at_20 * 1.02, MIN_VOTES, speed=20.0))
    assert outside is not None and " is " not in outside.split("allow)")[1].split("—")[0]  # no unit's ratio


def test_too_few_votes_or_a_split_vote_is_no_problem() -> None:
    assert speed_unit_problem(_votes(1.609, MIN_VOTES - 1)) is None
    votes = _votes(1.609, MIN_VOTES)
    votes.add_block(
        np.arange(MIN_VOTES) * VOTE_EVERY_S + 1e3, np.full(MIN_VOTES, 12.0), np.full(MIN_VOTES, 12.0)
    )
    assert speed_unit_problem(votes) is None  # half the drive agrees: a sensor's fault, not a unit


def test_frames_and_blocks_vote_alike() -> None:
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.005, 0.015, 5000))
    vx = 10.0 + np.sin(t / 5.0)
    speed = 1.609 * vx
    blocks, frames = SpeedVotes(4.0), SpeedVotes(4.0)
    for part in np.array_split(np.arange(len(t)), 17):
        blocks.add_block(t[part], speed[part], vx[part])
    for k in range(len(t)):
        if t[k] >= frames.next_t:
            frames.add(float(t[k]), float(speed[k]), float(vx[k]))
    seconds = t[-1] - t[0]
    for votes in (blocks, frames):
        assert votes.inside == 0 and votes.outside == pytest.approx(seconds / VOTE_EVERY_S, rel=0.1)
        assert votes.median() == pytest.approx(1.609, rel=0.01)


def _config(tmp_path: Path, role: str, line: str) -> Path:
    text = (REPO / "config" / "mondeo.toml").read_text().replace('"../dbc/', f'"{REPO}/dbc/')
    lines = [line if row.startswith(f"{role} = ") else row for row in text.splitlines()]
    path = tmp_path / f"{role}.toml"
    path.write_text("\n".join(lines) + "\n")
    return path


def test_a_vx_in_the_wrong_unit_gives_no_c2n_and_says_so(drive_log: Path, tmp_path: Path) -> None:
    """The vx read as mph: 23.40 for 14.87, blamed on d and q_u. Now no C2n, and the line names
    the units; the filter's losing the car, which the unit causes, is not blamed on q_u."""
    config = _config(tmp_path, "vx", 'vx = {signal = "Correvit.VelX_cor", unit = "mph"}')
    summary = tmp_path / "s.json"
    code, out, err = run_cli(["analyze", str(drive_log), "--config", str(config), "--json", str(summary)])
    assert code == 0 and "C2n =" not in out, out  # no result of the drive, as for a role's sign
    assert (
        "C2n: no result (the vehicle speed reads 0.62 × the optical vx" in out
        and "0.62 is km/h against mph" in out
    )
    assert "q_u" not in err and "Traceback" not in err
    assert "0.62 is km/h against mph" in json.loads(summary.read_text())["no_result"]
    config = _config(tmp_path, "speed", 'speed = {signal = "BrakeSysFeatures.Veh_V_ActlBrk", unit = "mph"}')
    code, out, err = run_cli(["analyze", str(drive_log), "--config", str(config)])
    assert (
        code == 0
        and "C2n: no result (the vehicle speed reads 1.61 × the optical vx" in out
        and "1.61 is mph against km/h" in out
    )


def test_a_drive_in_the_right_units_is_not_questioned(drive_log: Path) -> None:
    code, out, err = run_cli(["analyze", str(drive_log)])
    assert code == 0 and float(out.split("C2n = ")[1].split()[0]) == pytest.approx(15.1, rel=0.02), err
    assert "vehicle speed reads" not in out + err


def test_a_vehicle_speed_the_wrong_way_round_gives_no_c2n_and_is_named(
    drive_log: Path, tmp_path: Path
) -> None:
    """`scale = -1` on a forward-only speed: C2n read 14.772 [14.577, 14.983] for 15.121, and the
    warning said the filter lost the car on it — raise q_u. Now no C2n, the sign named with the
    scale that turns it."""
    config = _config(tmp_path, "speed", 'speed = {signal = "BrakeSysFeatures.Veh_V_ActlBrk", scale = -1.0}')
    code, out, err = run_cli(["analyze", str(drive_log), "--config", str(config)])
    assert code == 0 and "C2n =" not in out, out
    assert (
        "C2n: no result (the vehicle speed reads backwards while the optical vx reads forwards (100 % of"
        in out
    )
    assert "set [roles] speed's scale = 1 (" in out and "q_u" not in err


def test_reversing_or_a_flipped_vx_is_no_vote_on_the_vehicle_speed_s_sign() -> None:
    n = MIN_VOTES
    t = (np.arange(n) + 0.5) * VOTE_EVERY_S
    for speed, vx in ((-8.0, -8.0), (8.0, -8.0)):  # reversing, signed; a head facing the rear
        votes = SpeedVotes(4.0)
        votes.add_block(t, np.full(n, speed), np.full(n, vx))
        assert votes.backwards == 0 and speed_backwards(votes, 1.0) is None
    votes = SpeedVotes(4.0)
    votes.add_block(t, np.full(n, -8.0), np.full(n, 8.0))
    said = speed_backwards(votes, 1.0)
    assert said is not None and "set [roles] speed's scale = -1 (" in said


def test_a_vehicle_speed_that_went_quiet_is_no_vote(tmp_path: Path) -> None:
    """The vehicle bus sends its speed only while the car stands, 0 for 2 s (a gateway then
    asleep): that 0 was held for the whole drive and read as a unit mistake (`reads 0.05 ×`), the
    drive's C2n lost. A vote now takes the speed only while it is fresh ([filter]
    status_timeout_s)."""
    import can

    from tests.simulated import cached_drive

    messages = cached_drive("constant_radius", 41, 15.1).messages
    t0, speed_id = messages[0].timestamp, 0x415  # BrakeSysFeatures, the role speed's frame
    standing = [
        can.Message(
            timestamp=t0 - 2.0 + k * 0.02, arbitration_id=speed_id, data=bytes(8), is_extended_id=False
        )
        for k in range(100)
    ]
    kept = standing + [m for m in messages if m.arbitration_id != speed_id]
    log = tmp_path / "quiet.blf"
    with can.Logger(log) as writer:
        for m in kept:
            writer.on_message_received(m)
    code, out, err = run_cli(["analyze", str(log)])
    assert code == 0 and float(out.split("C2n = ")[1].split()[0]) == pytest.approx(15.1, rel=0.02), err
    assert "vehicle speed reads" not in out + err
    pipeline = Pipeline(load_config())  # frame by frame, as live reads a bus
    run(iter(kept), pipeline, [])
    snapshot = pipeline.snapshot()
    assert snapshot.unit_problem is None and snapshot.headline is not None


def test_a_yaw_rate_in_the_wrong_unit_is_named_not_the_driving(drive_log: Path, tmp_path: Path) -> None:
    """`[units] yaw_rate = "rad/s"` over the DBC's deg/s (helper-32): 57.3× the yaw rate, every
    turn at u·r far beyond any tyre's grip, and the result said `drive steady circles …` — in
    analyze and in gap. Now both name the yaw rate's unit and blame no driving."""
    from app.detect.quasi_steady import Cornering
    from app.results.refusal import beyond_grip

    line = 'yaw_rate = {signal = "AngVelHor.AngVelZ_hor", unit = "rad/s"}'
    config = _config(tmp_path, "yaw_rate", line)
    summary = tmp_path / "s.json"
    code, out, err = run_cli(["analyze", str(drive_log), "--config", str(config), "--json", str(summary)])
    said = " ".join(out.split())
    assert code == 0 and "C2n: no result (of " in said and "C2n =" not in said, out
    assert "over 3 g, which no tyre holds — the yaw rate reads too large: check its unit" in said
    assert "sweep" not in err and "drive steady circles" not in said, err
    result = json.loads(summary.read_text())
    assert result["cornering"]["beyond_grip_s"] > 0.5 * result["cornering"]["turning_s"] > 10.0
    code, _, err = run_cli(["gap", str(drive_log), "--config", str(config)])
    assert code == 1 and "the yaw rate reads too large: check its unit" in err, err
    # a drive within grip, and a track day's few seconds beyond it (a kerb, a spike), say nothing
    assert beyond_grip(Cornering(turning_s=100.0, beyond_grip_s=49.0)) is None
    assert beyond_grip(Cornering(turning_s=100.0, beyond_grip_s=51.0)) is not None
    code, _, _ = run_cli(["analyze", str(drive_log), "--json", str(summary)])
    assert code == 0 and json.loads(summary.read_text())["cornering"]["beyond_grip_s"] == 0.0
