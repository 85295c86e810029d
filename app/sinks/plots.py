"""PNG plots of a run for ``c2n export``: the sideslip against speed (the paper's Fig. 9), the
regression's v/r against u², each crossing's C2n and the time series, with the crossings marked.

Drawn with matplotlib's object API on the Agg canvas (no pyplot, no global state). Long traces
are decimated before plotting, so a drive of millions of frames plots in seconds.
"""

import math
from collections.abc import Callable, Sequence
from functools import partial
from pathlib import Path

import numpy as np
from matplotlib.axes import Axes
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.transforms import offset_copy
from numpy.typing import ArrayLike

from app.errors import OutputError
from app.output.files import write_atomically
from app.paper import G, crossing_speed
from app.sinks.summary import CrossingRow, Summary
from app.sinks.trace import Trace

SIZE_IN = (8.0, 5.0)
DPI = 150
MAX_SCATTER_POINTS = 50_000  # per series
MAX_LINE_POINTS = 20_000  # per time series
MIN_AY_MPS2 = 0.5  # v/r samples below this lateral acceleration have r too close to zero

_KMH_PER_MPS = 3.6
_DIRECTIONS = (("left", 1.0, "tab:blue"), ("right", -1.0, "tab:red"))
_COLOUR = {name: colour for name, _, colour in _DIRECTIONS}
_MARKER = {"up": "^", "down": "v"}
_LINESTYLE = {"up": "--", "down": ":"}


def write_plots(trace: Trace, summary: Summary, folder: Path) -> list[Path]:
    """Write the four PNGs into ``folder``; return their paths in the order of ``PLOTS``."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise OutputError(f"{folder}: cannot create the plot folder ({error.strerror})") from error
    paths = []
    for name, draw in PLOTS.items():
        figure = Figure(figsize=SIZE_IN, dpi=DPI)
        FigureCanvasAgg(figure)
        draw(figure, trace, summary)
        figure.tight_layout()
        path = folder / name
        write_atomically(path, partial(figure.savefig, dpi=DPI, format="png"), "the plot")
        paths.append(path)
    return paths


# --- data helpers -------------------------------------------------------------------------------


def _column(trace: Trace, name: str) -> np.ndarray:
    """A channel as floats; all NaN when the trace lacks it."""
    column = trace.columns.get(name)
    if column is None:
        return np.full(len(trace), math.nan)
    return np.asarray(column, dtype=np.float64)


def stride(n: int, limit: int) -> slice:
    """Every k-th of ``n`` samples so that at most ``limit`` remain."""
    return slice(None, None, max(1, math.ceil(n / limit)))


def envelope(t: np.ndarray, y: np.ndarray, limit: int) -> tuple[np.ndarray, np.ndarray]:
    """At most ``limit`` samples of a time series: each bin's minimum and maximum, in time order,
    so spikes survive the decimation. NaN stays NaN (a gap in the line)."""
    n = len(t)
    if n <= limit:
        return t, y
    k = math.ceil(n / (limit // 2))  # samples per bin
    bins = math.ceil(n / k)
    padded = np.full(bins * k, math.nan)
    padded[:n] = y
    blocks = padded.reshape(bins, k)
    nan = np.isnan(blocks)
    start = np.arange(bins) * k
    low = start + np.where(nan, np.inf, blocks).argmin(axis=1)
    high = start + np.where(nan, -np.inf, blocks).argmax(axis=1)
    index = np.unique(np.minimum(np.concatenate([low, high]), n - 1))
    return t[index], y[index]


# --- drawing helpers ----------------------------------------------------------------------------


def _note(ax: Axes, text: str) -> None:
    """A centred message on an axes that has nothing to show."""
    ax.text(0.5, 0.5, text, transform=ax.transAxes, ha="center", va="center", fontsize=14, color="0.4")


def _legend(ax: Axes, fontsize: str = "small", ncols: int = 1) -> None:
    """A legend when the axes have more than one labelled series, one entry per label."""
    handles, labels = ax.get_legend_handles_labels()
    unique = dict(zip(labels, handles, strict=True))
    if len(unique) < 2:
        return
    legend = ax.legend(
        list(unique.values()), list(unique.keys()), fontsize=fontsize, ncols=ncols, framealpha=0.85
    )
    for handle in legend.legend_handles:
        if isinstance(handle, Line2D) and handle.get_marker() == ".":
            handle.set_markersize(8)  # the scatter's tiny dots, legible in the legend


def _to_kmh(u: ArrayLike) -> np.ndarray:
    return np.asarray(u) * _KMH_PER_MPS


def _to_mps(kmh: ArrayLike) -> np.ndarray:
    return np.asarray(kmh) / _KMH_PER_MPS


_STAGGER_PT = 7.0  # the four kinds of crossing (left/right, up/down) drawn this far apart


def _mark_crossings_at_zero(ax: Axes, crossings: Sequence[CrossingRow]) -> None:
    """A marker at (u0, 0) per crossing; the kinds are staggered a few points up and down so the
    crossings of one u0 (they should agree) stay apart instead of hiding each other."""
    labelled: set[tuple[str, str]] = set()
    kinds = [(d, s) for d in ("left", "right") for s in ("up", "down")]
    for crossing in crossings:
        u0, direction, sweep = crossing.u0_mps, crossing.direction, crossing.sweep
        if u0 is None:
            continue
        key = (direction, sweep)
        k = kinds.index(key) if key in kinds else 0
        figure = ax.get_figure(root=True)
        assert isinstance(figure, Figure)  # an Axes of ours always has its figure
        shifted = offset_copy(ax.transData, fig=figure, y=(k - 1.5) * _STAGGER_PT, units="points")
        ax.plot(
            [u0],
            [0.0],
            transform=shifted,
            linestyle="none",
            marker=_MARKER.get(sweep, "o"),
            markersize=10,
            markerfacecolor=_COLOUR.get(direction, "0.3"),
            markeredgecolor="black",
            zorder=5,
            label=f"u0, {direction} {sweep}" if key not in labelled else None,
        )
        labelled.add(key)


# --- the plots ----------------------------------------------------------------------------------


def draw_sideslip_vs_speed(figure: Figure, trace: Trace, summary: Summary) -> None:
    """Steady samples' filtered sideslip against speed, per turn direction; the crossings at 0."""
    ax = figure.add_subplot()
    ax.set_title("Sideslip at the sensor against speed (steady cornering)")
    ax.set_xlabel("speed u [m/s]")
    ax.set_ylabel("sideslip β [deg]")
    speed, sideslip = _column(trace, "speed"), _column(trace, "sideslip")
    steady, direction = _column(trace, "steady") == 1.0, _column(trace, "direction")
    usable = steady & np.isfinite(speed) & np.isfinite(sideslip)
    plotted = 0
    for name, sign, colour in _DIRECTIONS:
        rows = np.flatnonzero(usable & (direction == sign))
        rows = rows[stride(len(rows), MAX_SCATTER_POINTS)]
        plotted += len(rows)
        _dots(ax, speed[rows], sideslip[rows], colour, f"{name} turns", alpha=0.6)
    ax.axhline(0.0, color="black", linewidth=0.8)
    _mark_crossings_at_zero(ax, summary.crossings)
    if not plotted:
        _note(ax, "no data" if len(trace) == 0 else "no steady samples")
    ax.secondary_xaxis("top", functions=(_to_kmh, _to_mps)).set_xlabel("speed [km/h]")
    ax.grid(alpha=0.3)
    _legend(ax)


def _dots(ax: Axes, x: np.ndarray, y: np.ndarray, colour: str, label: str, alpha: float) -> None:
    """A rasterised scatter of small dots (fast for many points); nothing for no points."""
    if len(x):
        ax.plot(
            x,
            y,
            linestyle="none",
            marker=".",
            markersize=2,
            color=colour,
            alpha=alpha,
            rasterized=True,
            label=label,
        )


def draw_vr_vs_u2(figure: Figure, trace: Trace, summary: Summary) -> None:
    """v/r − ψ0·u/r against u²: the straight line d − u²/(g·C2n) of the regression (eq. 6)."""
    ax = figure.add_subplot()
    ax.set_xlabel("u² [m²/s²]")
    ax.set_ylabel("v/r − ψ0·u/r [m]")
    fit = summary.regression
    psi0 = math.radians(fit.psi0_deg or 0.0) if fit else 0.0
    speed, v_meas = _column(trace, "speed"), _column(trace, "lateral_velocity_measured")
    r = np.radians(_column(trace, "yaw_rate"))
    ay, direction = _column(trace, "lateral_acceleration"), _column(trace, "direction")
    with np.errstate(invalid="ignore"):
        usable = (
            (_column(trace, "steady") == 1.0)
            & np.isfinite(v_meas)
            & np.isfinite(r)
            & np.isfinite(speed)
            & (np.abs(ay) >= MIN_AY_MPS2)
            & (r != 0.0)
        )
    rows = np.flatnonzero(usable)
    with np.errstate(divide="ignore", invalid="ignore"):
        x = speed[rows] ** 2
        y = v_meas[rows] / r[rows] - psi0 * speed[rows] / r[rows]
    for name, sign, colour in _DIRECTIONS:
        mine = np.flatnonzero(direction[rows] == sign)
        mine = mine[stride(len(mine), MAX_SCATTER_POINTS)]
        _dots(ax, x[mine], y[mine], colour, f"{name} turns", alpha=0.5)
    c2n = (fit.c2n_linear_model or fit.c2n) if fit else None
    d = fit.d_m if fit else None
    g = summary.g_mps2 or G
    line_y: list[float] = []
    if c2n is not None and d is not None and c2n > 0:
        u0_squared = d * g * c2n  # the line's zero: paper eq. 7
        x_end = max(float(np.max(x)) if len(x) else 0.0, u0_squared) * 1.05
        line_x = np.array([0.0, x_end])
        line_y = list(d - line_x / (g * c2n))
        ax.plot(line_x, line_y, color="black", linewidth=1.5, label=f"d − u²/(g·C2n), C2n = {c2n:.3f} 1/rad")
        if u0_squared > 0:
            u0 = crossing_speed(c2n, d, g)
            ax.axvline(
                u0_squared,
                color="0.3",
                linestyle=":",
                label=f"u0² = {u0_squared:.1f} m²/s² (u0 = {u0 * _KMH_PER_MPS:.1f} km/h)",
            )
        ax.set_title(f"v/r against u² with the regression line (d = {d:.3f} m)")
    else:
        ax.set_title("v/r against u² (no regression)")
    ax.axhline(0.0, color="black", linewidth=0.6)
    _clip_y(ax, y, line_y)
    if not len(rows):
        _note(ax, "no data" if len(trace) == 0 else f"no steady samples with |a_y| ≥ {MIN_AY_MPS2:g} m/s²")
    ax.grid(alpha=0.3)
    _legend(ax)


def _clip_y(ax: Axes, y: np.ndarray, line_y: Sequence[float]) -> None:
    """The 1st–99th percentile of the points, padded: v/r explodes where r is near zero."""
    finite = y[np.isfinite(y)]
    if not len(finite):
        return
    low, high = (float(v) for v in np.percentile(finite, [1.0, 99.0]))
    low, high = min(low, 0.0, *line_y), max(high, 0.0, *line_y)
    pad = 0.1 * (high - low) or 1.0
    ax.set_ylim(low - pad, high + pad)


def draw_c2n_per_crossing(figure: Figure, trace: Trace, summary: Summary) -> None:
    """Each crossing's C2n and 95 % interval against its lateral acceleration; the headline band."""
    ax = figure.add_subplot()
    ax.set_title("C2n of each crossing")
    ax.set_xlabel("|a_y| at the crossing [m/s²]")
    ax.set_ylabel("C2n [1/rad]")
    shown = 0
    for crossing in summary.crossings:
        c2n, ay, (low, high) = crossing.c2n, crossing.ay_mps2, crossing.ci95
        if c2n is None or ay is None:
            continue
        error = [[c2n - low], [high - c2n]] if low is not None and high is not None else None
        direction, sweep = crossing.direction, crossing.sweep
        ax.errorbar(
            [abs(ay)],
            [c2n],
            yerr=error,
            linestyle="none",
            marker=_MARKER.get(sweep, "o"),
            markersize=8,
            color=_COLOUR.get(direction, "0.3"),
            markeredgecolor="black",
            capsize=4,
            label=f"{direction} {sweep}",
        )
        shown += 1
    headline = summary.c2n
    if headline is not None:
        method = summary.c2n_method or "headline"
        ax.axhline(headline, color="black", linewidth=1.2, label=f"{method}: C2n = {headline:.3f} 1/rad")
        low, high = summary.c2n_ci95 or (None, None)
        if low is not None and high is not None:
            ax.axhspan(low, high, color="0.5", alpha=0.2, label=f"95 % [{low:.3f}, {high:.3f}]")
    if not shown:
        _note(ax, "no crossings")
    ax.grid(alpha=0.3)
    _legend(ax)


def draw_timeseries(figure: Figure, trace: Trace, summary: Summary) -> None:
    """Speed, sideslip and lateral acceleration over time, with the crossings marked."""
    axes = figure.subplots(3, 1, sharex=True)
    figure.suptitle("Time series (time since the first frame)")
    t = _column(trace, "time")
    rows: tuple[tuple[str, str, str], ...] = (
        ("speed", "speed [m/s]", "tab:green"),
        ("sideslip", "sideslip [deg]", "tab:purple"),
        ("lateral_acceleration", "a_y [m/s²]", "tab:orange"),
    )
    for ax, (name, label, colour) in zip(axes, rows, strict=True):
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        if name == "sideslip":
            measured = _column(trace, "sideslip_measured")
            keep = np.flatnonzero(np.isfinite(measured))
            keep = keep[stride(len(keep), MAX_LINE_POINTS)]
            if len(keep):
                ax.plot(
                    t[keep],
                    measured[keep],
                    linestyle="none",
                    marker=".",
                    markersize=1,
                    color="0.6",
                    alpha=0.4,
                    rasterized=True,
                    label="measured",
                )
            ax.axhline(0.0, color="black", linewidth=0.6)
        x, y = envelope(t, _column(trace, name), MAX_LINE_POINTS)
        if np.isfinite(y).any():
            ax.plot(x, y, color=colour, linewidth=0.9, label="filtered")
        else:
            _note(ax, "no data" if len(trace) == 0 else f"no {name.replace('_', ' ')}")
    for crossing in summary.crossings:
        at, direction, sweep = crossing.t, crossing.direction, crossing.sweep
        if at is None:
            continue
        for i, ax in enumerate(axes):
            ax.axvline(
                at,
                color=_COLOUR.get(direction, "0.3"),
                linestyle=_LINESTYLE.get(sweep, "-"),
                linewidth=1.0,
                label=f"crossing, {direction} {sweep}" if i == 0 else None,
            )
    for ax in axes:
        _legend(ax, fontsize="x-small", ncols=3)
    axes[-1].set_xlabel("time [s]")


Draw = Callable[[Figure, Trace, Summary], None]

PLOTS: dict[str, Draw] = {
    "sideslip_vs_speed.png": draw_sideslip_vs_speed,
    "vr_vs_u2.png": draw_vr_vs_u2,
    "c2n_per_crossing.png": draw_c2n_per_crossing,
    "timeseries.png": draw_timeseries,
}
