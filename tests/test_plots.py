"""Plots of ``c2n export``: four PNGs of the right size with something drawn on them, the
regression plot's points on the paper's line (eq. 6), decimation that keeps spikes, and the
edge cases (no data, NaN channels, no crossings, no regression) still drawn."""

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.image import imread
from matplotlib.lines import Line2D

from app.config import load_config
from app.errors import C2nError
from app.sinks.plots import (
    DPI,
    MAX_LINE_POINTS,
    MAX_SCATTER_POINTS,
    SIZE_IN,
    Draw,
    draw_sideslip_vs_speed,
    draw_timeseries,
    draw_vr_vs_u2,
    envelope,
    stride,
    write_plots,
)
from app.sinks.summary import Summary
from app.sinks.trace import Trace, TraceRecorder
from tests.exported import Exported, exported_drive

NAMES = ["sideslip_vs_speed.png", "vr_vs_u2.png", "c2n_per_crossing.png", "timeseries.png"]
HEIGHT_PX, WIDTH_PX = round(SIZE_IN[1] * DPI), round(SIZE_IN[0] * DPI)


@pytest.fixture(scope="module")
def exported() -> Exported:
    return exported_drive()


@pytest.fixture(scope="module")
def plots(exported: Exported, tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    return write_plots(exported.trace, exported.summary, tmp_path_factory.mktemp("plots"))


def rgb(path: Path) -> np.ndarray:
    image = imread(path)
    assert image.shape[:2] == (HEIGHT_PX, WIDTH_PX) == (750, 1200)
    return np.asarray(image[..., :3], dtype=np.float64)


def ink(pixels: np.ndarray) -> float:
    """The fraction of pixels that are not the white background."""
    return 1.0 - float((pixels > 0.98).all(axis=-1).mean())


def assert_drawn(path: Path, min_ink: float) -> None:
    pixels = rgb(path)
    assert pixels.std() > 0.05, f"{path.name} is blank"
    assert ink(pixels) > min_ink, f"{path.name}: only {ink(pixels):.1%} drawn"


def blue_and_red(pixels: np.ndarray) -> tuple[float, float]:
    """Fractions of clearly blue (left turns) and clearly red (right turns) pixels."""
    r, g, b = pixels[..., 0], pixels[..., 1], pixels[..., 2]
    return float(((b > r + 0.25) & (b > g + 0.1)).mean()), float(((r > b + 0.25) & (r > g + 0.25)).mean())


def empty_trace() -> Trace:
    return TraceRecorder(load_config().roles).trace(0.0)


def all_nan(trace: Trace) -> Trace:
    columns = {
        name: (v if name == "time" else np.full_like(v, math.nan)) for name, v in trace.columns.items()
    }
    return Trace(trace.t0, trace.channels, columns)


def xs(line: Line2D) -> np.ndarray:
    return np.asarray(line.get_xdata(), dtype=np.float64)


def ys(line: Line2D) -> np.ndarray:
    return np.asarray(line.get_ydata(), dtype=np.float64)


def drawn(draw: Draw, trace: Trace, summary: Summary) -> Figure:
    figure = Figure(figsize=SIZE_IN, dpi=DPI)
    FigureCanvasAgg(figure)
    draw(figure, trace, summary)
    return figure


def test_write_plots_writes_the_four_pngs_in_order(plots: list[Path]) -> None:
    assert [p.name for p in plots] == NAMES
    for path in plots:
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        assert_drawn(path, min_ink=0.08)
    assert not list(plots[0].parent.glob(".*partial*"))  # written atomically, nothing left over


def test_left_and_right_turns_have_their_own_colours(plots: list[Path]) -> None:
    for path in (plots[0], plots[1]):
        blue, red = blue_and_red(rgb(path))
        assert blue > 0.002 and red > 0.002, f"{path.name}: blue {blue:.2%}, red {red:.2%}"


def test_regression_points_lie_on_the_line_that_crosses_zero_at_u0(exported: Exported) -> None:
    summary = exported.summary.to_json()
    fit = summary["regression"]
    figure = drawn(draw_vr_vs_u2, exported.trace, exported.summary)
    ax = figure.axes[0]
    series = {line.get_label(): line for line in ax.get_lines()}
    g, c2n, d = summary["g_mps2"], fit["c2n_linear_model"], fit["d_m"]
    x = np.concatenate([xs(series[f"{s} turns"]) for s in ("left", "right")])
    y = np.concatenate([ys(series[f"{s} turns"]) for s in ("left", "right")])
    assert len(x) > 1000
    # y = v/r − ψ0·u/r = d − u²/(g·C2n): the points scatter about the regression's own line
    residual = y - (d - x / (g * c2n))
    assert abs(np.median(residual)) < 0.02
    slope, intercept = np.polyfit(x, y, 1)
    assert slope == pytest.approx(-1.0 / (g * c2n), rel=0.05)
    assert intercept == pytest.approx(d, abs=0.05)
    (u0_line,) = [line for line in ax.get_lines() if str(line.get_label()).startswith("u0²")]
    assert xs(u0_line)[0] == pytest.approx(d * g * c2n)
    low, high = ax.get_ylim()
    assert low < min(0.0, np.percentile(y, 1)) and high > max(d, np.percentile(y, 99))
    assert high - low < 10 * (np.percentile(y, 99) - np.percentile(y, 1))  # v/r's blow-ups clipped


def test_crossings_are_marked_at_u0_on_the_zero_line(exported: Exported) -> None:
    crossings = exported.summary.to_json()["crossings"]
    ax = drawn(draw_sideslip_vs_speed, exported.trace, exported.summary).axes[0]
    markers = [line for line in ax.get_lines() if len(xs(line)) == 1]
    got = sorted((float(xs(m)[0]), float(ys(m)[0]), m.get_marker()) for m in markers)
    want = sorted((c["u0_mps"], 0.0, {"up": "^", "down": "v"}[c["sweep"]]) for c in crossings)
    assert got == want and len(got) == 4
    # on the page the four kinds sit apart (they agree in u0 and would hide each other)
    on_page = {round(float(m.get_transform().transform((xs(m)[0], ys(m)[0]))[1]), 1) for m in markers}
    assert len(on_page) == 4


def test_timeseries_marks_each_crossing_on_every_panel(exported: Exported) -> None:
    figure = drawn(draw_timeseries, exported.trace, exported.summary)
    times = sorted(c["t"] for c in exported.summary.to_json()["crossings"])
    assert len(figure.axes) == 3
    for ax in figure.axes:
        vertical = sorted(
            float(xs(line)[0]) for line in ax.get_lines() if len(xs(line)) == 2 and xs(line)[0] == xs(line)[1]
        )
        assert vertical == times
    assert figure.axes[-1].get_xlabel() == "time [s]"


def test_long_traces_are_decimated_per_series(exported: Exported) -> None:
    n = 300_000
    t = np.arange(n) * 0.004
    speed = 8.0 + 9.0 * (t / t[-1])
    columns = {
        "time": t,
        "speed": speed,
        "sideslip": 0.5 - speed / 12.7 * 0.5,
        "sideslip_measured": 0.5 - speed / 12.7 * 0.5 + 0.01,
        "lateral_acceleration": np.full(n, 2.0),
        "steady": np.ones(n),
        "direction": np.where(np.arange(n) % 2, 1.0, -1.0),
    }
    columns["lateral_acceleration"][123_457] = 40.0  # a spike the decimation must keep
    trace = Trace(0.0, exported.trace.channels[:1], columns)
    scatter = drawn(draw_sideslip_vs_speed, trace, exported.summary).axes[0]
    sizes = [len(xs(line)) for line in scatter.get_lines() if "turns" in str(line.get_label())]
    assert sizes and all(MAX_SCATTER_POINTS // 2 <= size <= MAX_SCATTER_POINTS for size in sizes)
    panels = drawn(draw_timeseries, trace, exported.summary).axes
    for ax in panels:
        for line in ax.get_lines():
            assert len(xs(line)) <= MAX_LINE_POINTS
    (ay_line,) = [line for line in panels[2].get_lines() if line.get_label() == "filtered"]
    assert np.max(ys(ay_line)) == 40.0


def test_stride_and_envelope_keep_the_limit_and_the_extremes() -> None:
    assert stride(10, 20) == slice(None, None, 1)
    assert len(range(1_000_001)[stride(1_000_001, 50_000)]) <= 50_000
    rng = np.random.default_rng(3)
    t = np.arange(100_003, dtype=float)
    y = rng.normal(size=t.size)
    y[77_777], y[5] = 50.0, -50.0
    y[1000:3000] = math.nan
    x_out, y_out = envelope(t, y, 2000)
    assert len(x_out) <= 2000
    assert np.all(np.diff(x_out) > 0)  # time order
    assert np.nanmax(y_out) == 50.0 and np.nanmin(y_out) == -50.0
    assert np.isnan(y_out).any()  # the gap stays a gap
    same_t, same_y = envelope(t[:100], y[:100], 2000)
    assert np.array_equal(same_t, t[:100]) and np.array_equal(same_y, y[:100], equal_nan=True)


@pytest.mark.parametrize(
    "case",
    ["empty trace", "NaN channels", "no crossings", "no regression", "empty summary"],
)
def test_edge_cases_still_write_four_drawn_pngs(exported: Exported, tmp_path: Path, case: str) -> None:
    trace, summary = exported.trace, exported.summary
    if case == "empty trace":
        trace = empty_trace()
    elif case == "NaN channels":
        trace = all_nan(trace)
    elif case == "no crossings":
        summary = replace(summary, crossings=())
    elif case == "no regression":
        summary = replace(summary, regression=None)
    else:
        summary = Summary()
    paths = write_plots(trace, summary, tmp_path / "plots")
    assert [p.name for p in paths] == NAMES
    for path in paths:
        assert_drawn(path, min_ink=0.02)


def test_without_a_regression_the_points_are_drawn_and_the_title_says_so(exported: Exported) -> None:
    ax = drawn(draw_vr_vs_u2, exported.trace, replace(exported.summary, regression=None)).axes[0]
    assert "no regression" in ax.get_title()
    labels = [line.get_label() for line in ax.get_lines()]
    assert "left turns" in labels and "right turns" in labels
    assert not any(str(label).startswith(("d −", "u0²")) for label in labels)


def test_an_unwritable_folder_is_a_c2n_error(exported: Exported, tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    with pytest.raises(C2nError, match="cannot create the plot folder"):
        write_plots(exported.trace, exported.summary, blocker / "plots")
