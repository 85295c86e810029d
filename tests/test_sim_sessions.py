"""The track-laps and one-speed-circles sessions: what they drive, measured on the two-track
model's trace, and ``c2n simulate --session`` for both generators."""

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from rich.console import Console

from app import paper
from app.cli import main
from app.config import Config
from app.sim.laps_and_circles import CIRCUIT, TRACK_PLAN, track_session
from app.sim.simulated_drive import SimulatedDrive, truth_path
from app.sim.standard import QUICK_PLAN, TIGHT_PLAN, StandardOptions, simulate_standard
from app.sources.logs import open_log


@pytest.fixture(scope="module")
def u0(config: Config) -> float:
    return paper.crossing_speed(config.tyres.c2n_per_rad or 0.0, config.d_m, config.vehicle.gravity_mps2)


@pytest.fixture(scope="module")
def track(config: Config) -> SimulatedDrive:
    return simulate_standard(config, StandardOptions(seed=5, session="track"))


@pytest.fixture(scope="module")
def circles(config: Config) -> SimulatedDrive:
    return simulate_standard(config, StandardOptions(seed=5, session="circles"))


def parts(drive: SimulatedDrive, kind: str) -> list[dict[str, Any]]:
    return [part for part in drive.truth["parts"] if part["kind"] == kind]


def during(drive: SimulatedDrive, part: dict[str, Any], after_s: float = 0.0) -> np.ndarray:
    """The samples of a part, from ``after_s`` after its start."""
    t = drive.trace.t  # type: ignore[union-attr]
    return np.asarray((t >= part["start_s"] + after_s) & (t <= part["end_s"]))


def test_track_corners_stay_above_u0_so_the_sideslip_never_changes_sign(
    config: Config, track: SimulatedDrive, u0: float
) -> None:
    """Above u0 the sensor's sideslip points out of the turn (β = d/R − u²/(R·g·C2n) < 0 on a left
    turn): once the car has turned in, no corner has a crossing."""
    trace = track.trace
    assert trace is not None
    lateral = trace.lateral_velocity_at(config.d_m - trace.params.b_m)
    corners = parts(track, "corner")
    assert len(corners) == 6 * len(CIRCUIT)
    for corner in corners:
        inside = during(track, corner)
        assert np.min(trace.u[inside]) > 1.1 * u0
        turned_in = during(track, corner, after_s=0.5)
        assert np.all(np.sign(lateral[turned_in]) == -corner["direction"])


def test_track_corners_spread_lateral_acceleration_both_ways(track: SimulatedDrive, u0: float) -> None:
    trace = track.trace
    assert trace is not None
    corners = parts(track, "corner")
    steady = [float(np.median(np.abs(trace.ay[during(track, c, after_s=1.5)]))) for c in corners]
    assert max(steady) - min(steady) > 3.0  # 1–4.4 m/s²
    assert min(steady) > 0.8 and max(steady) < 5.0
    assert sum(1 for c in corners if c["direction"] > 0) > sum(1 for c in corners if c["direction"] < 0) > 0
    speeds = [c["speed_mps"] / u0 for c in corners]
    assert min(speeds) < 1.25 and max(speeds) > 2.3
    for corner in corners:  # the driver holds the circuit's radius
        held = during(track, corner, after_s=2.0)
        radius = trace.u[held] / trace.r[held]
        assert np.all(np.abs(radius / (corner["direction"] * corner["radius_m"]) - 1.0) < 0.1)
    assert track.truth["max_ay_mps2"] < 5.5


def test_track_speeds_change_as_a_driver_changes_them(track: SimulatedDrive) -> None:
    """Acceleration 1–2.5 m/s², braking 2–4 m/s² on the straights; within ±5 % of a corner's speed
    through it; corners of 4–12 s, short straights of 3–10 s; six laps in 8–10 minutes."""
    trace = track.trace
    assert trace is not None
    assert np.min(trace.u_dot) >= -4.0 - 1e-9 and np.max(trace.u_dot) <= 2.5 + 1e-9
    for corner in parts(track, "corner"):
        inside = during(track, corner)
        assert np.all(np.abs(trace.u[inside] / corner["speed_mps"] - 1.0) <= 0.05)
        assert np.all(np.abs(trace.u_dot[inside]) < 0.6)  # slowly: against 1–4 m/s² on the straights
        assert 4.0 <= corner["end_s"] - corner["start_s"] <= 12.0
    straights = [s["end_s"] - s["start_s"] for s in parts(track, "straight")]
    assert min(straights) >= 3.0 - 1e-9 and max(straights) == pytest.approx(10.0)
    assert 480.0 <= track.truth["duration_s"] <= 600.0
    assert track.truth["session"] == "track"
    laps = (trace.heading[-1] - trace.heading[0]) / (2.0 * math.pi)  # the corners turn 360° a lap
    assert laps == pytest.approx(6.0, abs=0.05)


def test_each_lap_scatters_the_corner_speeds_with_the_seed(u0: float) -> None:
    def corner_speeds(seed: int) -> list[float]:
        return [p.speed_mps or 0.0 for p in track_session(u0, seed=seed).parts if p.kind == "corner"]

    first, again, other = corner_speeds(1), corner_speeds(1), corner_speeds(2)
    assert first == again and first != other
    nominal = [corner.speed_factor * u0 for corner, _ in CIRCUIT] * TRACK_PLAN.laps
    scatter = np.array(first) / np.array(nominal) - 1.0
    assert np.max(np.abs(scatter)) <= TRACK_PLAN.lap_scatter
    laps = np.reshape(scatter, (TRACK_PLAN.laps, len(CIRCUIT)))
    assert len({tuple(lap) for lap in laps.round(6)}) == TRACK_PLAN.laps  # no two laps alike


def test_circles_hold_one_speed_on_three_radii_both_ways(circles: SimulatedDrive, u0: float) -> None:
    trace = circles.trace
    assert trace is not None
    rings = parts(circles, "circle")
    assert sorted((c["radius_m"], c["direction"]) for c in rings) == sorted(
        (r, s) for r in {c["radius_m"] for c in rings} for s in (1, -1)
    )
    assert len({c["radius_m"] for c in rings}) == 3
    speed = rings[0]["speed_mps"]
    assert 1.1 * u0 < speed < 1.4 * u0
    for ring in rings:
        inside = during(circles, ring)
        assert np.all(np.abs(trace.u[inside] / speed - 1.0) < 0.01)
        settled = during(circles, ring, after_s=6.0)
        assert 30.0 <= trace.t[settled][-1] - trace.t[settled][0] <= 40.0
        expected = speed * speed / ring["radius_m"]  # a_y = u²·κ: the one speed fixes it
        assert np.median(np.abs(trace.ay[settled])) == pytest.approx(expected, rel=0.02)
    assert 270.0 <= circles.truth["duration_s"] <= 330.0
    assert circles.truth["session"] == "circles"


def test_a_small_pad_sweeps_radii_of_25_to_36_m_each_to_7_mps2(config: Config, u0: float) -> None:
    """Issue 23's small pad: the Mondeo's u0 takes 6.5, 5.4 and 4.5 m/s² on its radii, and no sweep
    runs past 7 m/s²: each passes u0, the tightest by 4 %."""
    drive = simulate_standard(config, StandardOptions(seed=5, plan=TIGHT_PLAN))
    trace = drive.trace
    assert trace is not None
    sweeps = parts(drive, "sweep")
    assert sorted({s["radius_m"] for s in sweeps}) == [25.0, 30.0, 36.0]
    assert sorted(s["direction"] for s in sweeps) == [-1, -1, -1, 1, 1, 1]
    for sweep in sweeps:
        inside = during(drive, sweep, after_s=6.0)
        top = np.max(np.abs(trace.ay[inside]))
        assert 6.5 < top <= 7.05
        assert np.min(trace.u[inside]) == pytest.approx(0.6 * u0, rel=0.01)
        assert np.max(trace.u[inside]) > u0


@pytest.mark.parametrize(("session", "model"), [("track", "two_track"), ("circles", "commonroad")])
def test_simulate_writes_a_session_log(tmp_path: Path, session: str, model: str) -> None:
    out = tmp_path / "x.blf"
    argv = ["simulate", "--session", session, "--model", model, "--quick", "--seed", "3", "--out", str(out)]
    console = Console(record=True, width=200)
    assert main(argv, console) == 0
    truth = json.loads(truth_path(out).read_text())
    assert truth["session"] == session and truth["model"] == model
    assert f"wrote {out}" in console.export_text()
    first = [m for m, _ in zip(open_log(out), range(100), strict=False)]
    assert len(first) == 100 and truth["frames"] > 10_000


def test_a_pack_of_track_sessions_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["simulate", "--pack", "2", "--session", "track", "--out", str(tmp_path / "pack")]
    assert main(argv, Console(record=True)) == 1
    assert "--pack writes standard sessions" in capsys.readouterr().err
    assert not (tmp_path / "pack").exists()


def test_the_rear_axle_s_own_c2n_is_read_from_sweeps_only(config: Config, track: SimulatedDrive) -> None:
    """The truth a driving test should find, from the car's state: on the two-track model it is
    the tyres' C2n (load transfer softens it only beyond zero a_y); track corners, 1–4.4 m/s², do
    not reach low enough to say it."""
    standard = simulate_standard(config, StandardOptions(seed=5))
    assert standard.truth["c2n_axle"] == pytest.approx(standard.truth["c2n"], rel=0.005)
    assert track.truth["c2n_axle"] is None
    # --quick's sweeps, at 1 m/s², run faster than the steady gate lets a sample through: its few
    # samples under it are the speed's turns, and read 7.30 for 14.87
    quick = simulate_standard(config, StandardOptions(seed=5, plan=QUICK_PLAN))
    assert quick.truth["c2n_axle"] is None


def test_the_cars_own_figures_are_the_simulated_cars(config: Config) -> None:
    """StandardOptions.car sets the two-track car's own figures over the config's (bench case n's
    soft body): its roll per g is that car's, as the drive's truth and its trace show."""
    from app.sim.two_track import DEFAULT_ROLL_GRADIENT_DEG_PER_G

    soft = simulate_standard(config, StandardOptions(seed=3, car={"roll_gradient_deg_per_g": 6.5}))
    assert soft.truth["vehicle"]["roll_gradient_deg_per_g"] == 6.5
    ay, roll = np.abs(soft.trace.ay), np.degrees(np.abs(soft.trace.roll))
    steady = (ay > 2.0) & (ay < 4.0)
    per_g = np.median(roll[steady] / ay[steady]) * config.vehicle.gravity_mps2
    assert per_g == pytest.approx(6.5, rel=0.05) and abs(per_g - DEFAULT_ROLL_GRADIENT_DEG_PER_G) > 1.0
