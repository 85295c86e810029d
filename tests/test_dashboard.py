"""The dashboard, rendered into a recording console and read as text."""

from dataclasses import replace

from rich.console import Console

from app.config import Config
from app.pipeline import Pipeline
from app.records import Reason, SteadyState
from app.sim.simulated_drive import SimulatedDrive
from app.sinks.dashboard import Dashboard, guidance


def shown(pipeline: Pipeline, title: str) -> Dashboard:
    """A dashboard fed the pipeline's snapshot, as the run loop feeds it."""
    dashboard = Dashboard(title)
    dashboard.on_snapshot(pipeline.snapshot())
    return dashboard


def render(dashboard: Dashboard, width: int = 200, height: int = 70) -> str:
    """The dashboard as text on a terminal of this size (by default one with room for every panel)."""
    console = Console(record=True, width=width, height=height, force_terminal=False)
    console.print(dashboard)
    return console.export_text()


def test_dashboard_after_a_drive(analysed: Pipeline) -> None:
    text = render(shown(analysed, "vcan0"))
    assert "c2n live — vcan0" in text
    for label in (
        "speed",
        "km/h",
        "sideslip",
        "lat. acc.",
        "yaw rate",
        "filter health",
        "Crossings",
        "Frames",
    ):
        assert label in text, label
    assert "C2n = " in text and "regression over" in text and "4 paired crossings" in text
    fit = analysed.state.regression
    assert fit is not None and f"d {fit.d.m:.3f} m" in text and "(config 1.11)" in text
    assert "pairing: head misalignment" in text and "lag" in text
    assert "0x7E5" in text and "Correvit" in text and "0x415" in text and "BrakeSysFeatures" in text
    assert f"total {analysed.decoder.counts.total}" in text
    last = analysed.state.crossings[-1]
    assert f"{last.c2n:.3f}" in text and f"{last.u0_kmh:.2f}" in text
    assert "status: " in text and "HeadStatus 1" in text


def test_the_dashboard_says_when_the_filter_lost_the_car(analysed: Pipeline) -> None:
    from app.estimate.motion_model import FilterCounts

    snapshot = analysed.snapshot()
    assert "lost the car" not in render(shown(analysed, "vcan0"))
    elsewhere = replace(snapshot.filter, counts=FilterCounts(outliers=9, lost_vx=2, lost_yaw=1))
    dashboard = Dashboard("can0")
    dashboard.on_snapshot(replace(snapshot, filter=elsewhere))  # a hard stop's: no sample touched
    assert "lost the car" not in render(dashboard)
    dashboard.on_snapshot(replace(snapshot, filter=replace(elsewhere, lost_in_samples=2)))
    assert "lost the car in 2 samples (vx, yaw)" in render(dashboard)


def test_guidance_for_the_driver() -> None:
    reasons = (
        "lateral acceleration too high: 4.3 m/s² > 4",
        "sweep too fast: 0.80 m/s² > 0.6",
        "sensor: Status.HeadStatus=0 (needs 1)",
    )
    causes = (Reason.AY_HIGH, Reason.SWEEP_FAST, Reason.SENSOR)
    assert guidance(SteadyState(False, None, reasons, causes)) == [
        "Too much lateral acceleration: slow down or widen the circle",
        "Change speed more gently",
        "Sensor status bad (sensor: Status.HeadStatus=0 (needs 1))",
    ]


def test_not_steady_shows_the_guidance(analysed: Pipeline) -> None:
    snapshot = analysed.snapshot()
    assert snapshot.last is not None
    straight = SteadyState(False, "left", ("driving straight (radius over 500 m)",), (Reason.STRAIGHT,))
    dashboard = Dashboard("can0")
    dashboard.on_snapshot(replace(snapshot, last=snapshot.last._replace(steady=straight)))
    text = render(dashboard)
    assert "not steady" in text and "Turn onto the circle" in text


def test_empty_dashboard_before_any_frame(config: object) -> None:
    from app.config import Config

    assert isinstance(config, Config)
    text = render(shown(Pipeline(config), "can0"))
    assert "no frames on the bus yet" in text and "no result" in text


def test_a_laptop_terminal_of_80_by_24_shows_the_c2n_line_the_latest_crossing_and_the_sensor(
    analysed: Pipeline,
) -> None:
    """At 80×24 nothing is cut that the driver needs: the whole C2n line (wrapped, not cut), the
    latest crossing, the steady state and the sensor status; the sideslip plot takes what is left."""
    from app.sinks.event_printer import result_line

    snapshot = analysed.snapshot()
    text = render(shown(analysed, "can0"), width=80, height=24)
    lines = text.splitlines()
    assert len(lines) <= 24 and max(len(line) for line in lines) <= 80
    assert result_line(snapshot) in " ".join(line.strip() for line in lines)
    last = snapshot.crossings[-1]
    assert f"u0 {last.u0_mps:.3f} m/s" in text and f"C2n {last.c2n:.3f}" in text
    assert ("STEADY" in text or "not steady" in text) and "HeadStatus 1" in text
    assert "sideslip β" in text and "×" in text and "─" in text


def test_the_dashboard_grows_into_panels_and_the_plot_on_a_larger_terminal(analysed: Pipeline) -> None:
    from app.sinks.event_printer import result_line

    snapshot = analysed.snapshot()
    last = snapshot.crossings[-1]
    for width, height in ((120, 40), (120, 50), (200, 70)):
        text = render(shown(analysed, "can0"), width=width, height=height)
        lines = text.splitlines()
        assert len(lines) <= height and max(len(line) for line in lines) <= width
        panels = ("Motion", "Steady state", "Crossings", "Frames")
        for title in (*panels, "Sideslip against speed") if height >= 50 else panels:
            assert title in text, (width, height, title)
        flat = " ".join(line.strip(" │") for line in lines)
        assert result_line(snapshot) in flat, (width, height)
        assert f"{last.c2n:.3f}" in text and f"{last.u0_kmh:.2f}" in text


def test_the_sideslip_plot_draws_eq_6_with_its_zero_crossing_at_u0() -> None:
    """Sideslip at the sensor on a circle, β = d/R − u²/(R·g·C2n) (eq. 6), as a left turn and the
    mirror image as a right one: both fall on one curve counted towards the turn's inside; it is
    above the zero line below u0 and under it above; a crossing at u0 sits on the zero line in
    the column u0 maps to."""
    import math

    import numpy as np

    from app import paper
    from app.records import Crossing
    from app.results.sideslip_profile import SideslipProfile
    from app.sinks.sideslip_plot import SideslipPlot

    c2n, d, radius, g = 15.0, 1.11, 80.0, 9.81
    u0 = paper.crossing_speed(c2n, d, g)
    profile = SideslipProfile()
    speeds = np.arange(0.65 * u0, 1.35 * u0, 0.01)
    for u in speeds:
        beta = d / radius - u * u / (radius * g * c2n)
        profile.add(u, u * beta, "left")
        profile.add(u, -u * beta, "right")
    crossing = Crossing(
        t=0.0,
        direction="left",
        sweep="up",
        u0_mps=u0,
        u0_ci95=(u0 - 0.05, u0 + 0.05),
        c2n=c2n,
        c2n_se=0.1,
        ci95=(c2n - 0.2, c2n + 0.2),
        ay_mps2=u0 * u0 / radius,
        radius_m=radius,
        sweep_rate_mps2=0.3,
        n_samples=100,
        method="v/r",
    )
    console = Console(record=True, width=108, height=30, force_terminal=False)
    console.print(SideslipPlot(profile.view(), [crossing], height=22))
    lines = console.export_text().splitlines()
    grid = lines[1:-1]  # between the title and the speed axis
    assert len(lines) == 22 and len(grid) == 20
    zero = next(k for k, line in enumerate(grid) if "─" in line)
    columns = 100
    u_lo, u_hi = float(profile.view().left[0].min()), float(profile.view().left[0].max())
    expected = round((u0 - u_lo) / (u_hi - u_lo) * (columns - 1))
    assert grid[zero][8 + expected] == "×"
    assert "∘" not in "".join(grid) and "•" not in "".join(grid)  # left and right on one curve: ◆
    for k, line in enumerate(grid):
        marks = [i - 8 for i, ch in enumerate(line) if ch == "◆"]
        for i in marks:
            u = u_lo + i / (columns - 1) * (u_hi - u_lo)
            if abs(u - u0) > 0.3:
                assert (k < zero) == (u < u0), (k, u)
    assert math.isclose(float(lines[-1].split()[0]), u_lo, abs_tol=0.05)


def test_a_live_dashboard_wraps_its_long_lines_on_the_commands_console(
    config: Config, drive: SimulatedDrive
) -> None:
    """The run loop draws the dashboard on the command's own console, which soft-wraps (a line of
    words is one line): the compact layout's C2n line, longer than 80 columns, is wrapped there —
    u0 and the paired crossings shown — not cut after "steady samples" (it was)."""
    import io

    from app.run_loop import run
    from tests.simulated import run_pipeline

    analysed = run_pipeline(config, drive)  # its own: the loop finishes it again
    console = Console(
        file=io.StringIO(), force_terminal=True, width=80, height=24, soft_wrap=True, record=True
    )
    run(iter(()), analysed, display=Dashboard("t"), console=console)
    text = console.export_text()
    assert "u0 = " in text and "paired crossings" in text
    assert console.soft_wrap  # the command's lines after it are soft-wrapped again
