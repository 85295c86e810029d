"""The dashboard, rendered into a recording console and read as text."""

from dataclasses import replace

from rich.console import Console

from app.pipeline import Pipeline
from app.records import Reason, SteadyState
from app.sinks.dashboard import Dashboard, guidance


def shown(pipeline: Pipeline, title: str) -> Dashboard:
    """A dashboard fed the pipeline's snapshot, as the run loop feeds it."""
    dashboard = Dashboard(title)
    dashboard.on_snapshot(pipeline.snapshot())
    return dashboard


def render(dashboard: Dashboard, width: int = 200) -> str:
    console = Console(record=True, width=width, force_terminal=False)
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
    assert fit is not None and f"d {fit.d_m:.3f} m" in text and "(config 1.11)" in text
    assert "pairing: head misalignment" in text and "lag" in text
    assert "0x7E5" in text and "Correvit" in text and "0x415" in text and "BrakeSysFeatures" in text
    assert f"total {analysed.decoder.counts.total}" in text
    last = analysed.state.crossings[-1]
    assert f"{last.c2n:.3f}" in text and f"{last.u0_kmh:.2f}" in text
    assert "status: " in text and "HeadStatus 1" in text


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
