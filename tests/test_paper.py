"""The paper's equations, checked against the numbers printed in it."""

import math

import pytest

from app import paper


def test_eq10_mondeo_tyre1_gives_14_99() -> None:
    """Table 2 / eq. 10: u0 = 46 km/h, d = 1.11 m → C2n = 14.99 1/rad."""
    assert round(paper.c2n_from_crossing(46 / 3.6, 1.11), 2) == 14.99


def test_eq7_and_eq10_are_inverses() -> None:
    for c2n, d in [(14.99, 1.11), (11.37, 1.265), (7.95, 0.8)]:
        assert paper.c2n_from_crossing(paper.crossing_speed(c2n, d), d) == pytest.approx(c2n, rel=1e-12)


def test_eq8_eq9_simulation_tyre() -> None:
    """C2 = 502.1 N / (0.6188°/57.3) = 46494 N/rad; C2n = 46494/4090 = 11.37."""
    c2 = 502.1 / (0.6188 / paper.DEG_PER_RAD)
    assert c2 == pytest.approx(46494, abs=1.0)
    assert round(paper.normalised_stiffness(46494, 4090), 2) == 11.37


def test_eq10_simulation_car_crossing_speed() -> None:
    """u0 = √(C2n·g·d2) = 11.88 m/s = 42.8 km/h for C2n = 11.37 (the paper's simulated car)."""
    d2 = 11.88**2 / (11.37 * paper.G)
    assert paper.crossing_speed(11.37, d2) * 3.6 == pytest.approx(42.8, abs=0.05)


def test_eq6_changes_sign_at_eq7_speed_for_any_radius() -> None:
    c2n, d = 14.99, 1.11
    u0 = paper.crossing_speed(c2n, d)
    for radius in (30.0, 80.0, -120.0, 400.0):
        assert paper.sideslip_at_sensor(u0, radius, d, c2n) == pytest.approx(0.0, abs=1e-15)
        below = paper.sideslip_at_sensor(0.9 * u0, radius, d, c2n)
        above = paper.sideslip_at_sensor(1.1 * u0, radius, d, c2n)
        assert below * above < 0
        assert math.copysign(1, below) == math.copysign(1, radius)  # left turn: positive at low speed
    # at walking pace the sideslip is the geometric d/R
    assert paper.sideslip_at_sensor(0.0, 50.0, d, c2n) == pytest.approx(d / 50.0)


def test_eq4_rear_slip_equals_eq5_geometry() -> None:
    """β_d + α2 = d/R (eq. 5) with α2 from eq. 4 and β_d from eq. 6."""
    c2n, d, radius, u = 12.0, 1.2, 60.0, 10.0
    alpha2 = paper.rear_slip_angle(u * u / radius, c2n)
    assert paper.sideslip_at_sensor(u, radius, d, c2n) + alpha2 == pytest.approx(d / radius)


def test_eq1_is_eq7_with_the_sensor_at_the_cg() -> None:
    """Eq. 1 (C_r per degree) gives the same speed as eq. 7 with d = c, C2n = 57.3·C_r/W_r."""
    c_r_per_deg, w_r, c = 1000.0, 5734.0, 1.6
    c2n = paper.DEG_PER_RAD * c_r_per_deg / w_r
    assert paper.zero_sideslip_speed_at_cg(c_r_per_deg, w_r, c) == pytest.approx(paper.crossing_speed(c2n, c))


def test_the_paper_tables_tool_s_workers_send_their_results_back() -> None:
    """tools/paper_tables.py runs its drives in worker processes: what a worker returns must
    pickle (a snapshot's read-only views did not), and Table 2's Mondeo reads its rig value."""
    import importlib.util
    import pickle

    from tests.real_data import REPO_ROOT

    spec = importlib.util.spec_from_file_location(
        "paper_tables_tool", REPO_ROOT / "tools" / "paper_tables.py"
    )
    assert spec is not None and spec.loader is not None
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    c2n, state = pickle.loads(pickle.dumps(tool.run_mondeo((14.87, 3))))
    assert c2n == 14.87 and state.headline is not None
    assert state.headline.c2n == pytest.approx(14.87, rel=0.005)
