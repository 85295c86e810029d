"""The HTML report of a run for ``c2n export``: the summary's numbers, the crossings, the
warnings and the plots in one self-contained page (``app.sinks.html``).

``render`` is pure (summary and image bytes in, text out); ``write_report`` reads the plots and
writes the file. Every string from the summary is escaped; missing values show "—".
"""

import html
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path

from app.errors import OutputError
from app.sinks.html import DASH, fields, figure, interval, none, page, section, table, text, write_html
from app.sinks.summary import (
    CrossingRow,
    Frames,
    Interval,
    PairedRow,
    RegressionRow,
    RejectedRow,
    Summary,
)

_KMH_PER_MPS = 3.6


def write_report(summary: Summary, plots: Sequence[Path], path: Path, title: str) -> None:
    """Write the report atomically: a crash leaves the old file or the new one."""
    write_html(render(summary, [(plot.name, read_plot(plot)) for plot in plots], title), path)


def read_plot(plot: Path) -> bytes:
    try:
        return plot.read_bytes()
    except OSError as error:
        raise OutputError(f"{plot}: cannot read the plot ({error.strerror})") from error


def render(summary: Summary, images: Sequence[tuple[str, bytes]], title: str) -> str:
    """The HTML document; ``images`` are (name, PNG bytes) in display order."""
    return page(
        title,
        (
            _header(summary, title),
            _headline(summary),
            _warnings(summary.warnings),
            _regression(summary.regression),
            _paired(summary.paired),
            _crossings(summary.crossings),
            _rejected(summary.rejected_crossings),
            _frames(summary.frames),
            _plots(images),
        ),
        "export",
    )


# --- values -------------------------------------------------------------------------------------


def _fixed(value: float | None, digits: int) -> str:
    return DASH if value is None else f"{value:.{digits}f}"


def _kmh(mps: float | None) -> float | None:
    return None if mps is None else mps * _KMH_PER_MPS


def _with_interval(value: float | None, pair: Interval | None, unit: str = "") -> str:
    """The value, its unit (" m", "°") and its 95 % interval."""
    suffix = html.escape(unit) if value is not None else ""
    ci = interval(pair)
    if ci == DASH:
        return f"{text(value)}{suffix}"
    return f'{text(value)}{suffix} <span class="method">95 % {ci}</span>'


# --- sections -----------------------------------------------------------------------------------


def _header(summary: Summary, title: str) -> str:
    pairs = (
        ("inputs", ", ".join(text(item) for item in summary.inputs) or DASH),
        ("config", text(summary.config)),
        ("duration", f"{text(summary.duration_s)} s"),
        ("c2n version", text(summary.version)),
    )
    details = "\n".join(f"<dt>{html.escape(name)}</dt><dd>{value}</dd>" for name, value in pairs)
    return f'<header>\n<h1>{text(title)}</h1>\n<dl class="inputs">\n{details}\n</dl>\n</header>'


def _headline(summary: Summary) -> str:
    u0 = summary.u0_mps
    headline = (
        f'<p class="headline">C2n = <span class="value">{text(summary.c2n)}</span> 1/rad, '
        f"95 % {interval(summary.c2n_ci95)} 1/rad "
        f'<span class="method">({text(summary.c2n_method)})</span></p>'
        if summary.c2n is not None or summary.no_result is None
        else f'<p class="headline">No C2n: {text(summary.no_result)}</p>'
    )
    values = fields(
        (
            ("u0", f"{text(u0)} m/s = {_fixed(_kmh(u0), 2)} km/h"),
            ("d (sensor ahead of the rear axle)", f"{text(summary.d_m)} m"),
            ("g", f"{text(summary.g_mps2)} m/s²"),
        )
    )
    return section("Cornering stiffness C2n", headline, values)


def _warnings(warnings: Sequence[str]) -> str:
    if not warnings:
        return section("Warnings", '<p class="ok">No warnings.</p>')
    listed = "\n".join(f"<li>{text(item)}</li>" for item in warnings)
    return section(f"Warnings ({len(warnings)})", f'<ul class="warnings">\n{listed}\n</ul>')


def _regression(fit: RegressionRow | None) -> str:
    if fit is None:
        return section("Regression over every steady sample", none("no regression: too few steady samples"))
    return section(
        "Regression over every steady sample",
        fields(
            (
                ("C2n", _with_interval(fit.c2n, fit.c2n_ci95)),
                ("d", _with_interval(fit.d_m, fit.d_ci95, " m")),
                ("ψ0 (sensor misalignment)", _with_interval(fit.psi0_deg, fit.psi0_ci95_deg, "°")),
                ("model", text(fit.model)),
                ("C2n, linear model", text(fit.c2n_linear_model)),
                ("C2n, softening model", text(fit.c2n_softening_model)),
                ("softening t statistic", text(fit.softening_t)),
                (
                    "softening resolved",
                    "yes" if fit.softening_resolved else f"no: {text(fit.softening_hidden_pct)} % could hide",
                ),
                ("samples", text(fit.n_samples)),
                ("|a_y| range", f"{interval(fit.ay_range_mps2)} m/s²"),
            )
        ),
    )


def _paired(paired: PairedRow | None) -> str:
    if paired is None:
        return section("Paired crossings", none("no pairs: needs crossings up and down, left and right"))
    return section(
        "Paired crossings",
        fields(
            (
                ("C2n", _with_interval(paired.c2n, paired.c2n_ci95)),
                ("misalignment", _with_interval(paired.misalignment_deg, paired.misalignment_ci95_deg, "°")),
                ("lag", _with_interval(paired.lag_s, paired.lag_ci95_s, " s")),
                ("cancels", ", ".join(text(c) for c in paired.cancels) or "nothing"),
                ("cells", ", ".join(f"{text(k)}: {text(v)}" for k, v in paired.cells.items()) or DASH),
                ("crossings", text(paired.n)),
                ("Birge ratio", text(paired.birge_ratio)),
            )
        ),
    )


def _crossings(crossings: Sequence[CrossingRow]) -> str:
    if not crossings:
        return section("Crossings", none("no crossings: the sideslip never changed sign in steady cornering"))
    headers = ("t [s]", "direction", "sweep", "u0 [km/h]", "a_y [m/s²]", "C2n", "95 % CI", "samples")
    numeric = (True, False, False, True, True, True, False, True)
    return section(
        f"Crossings ({len(crossings)})",
        table(
            headers,
            (
                (
                    text(c.t),
                    text(c.direction),
                    text(c.sweep),
                    _fixed(c.u0_kmh, 2),
                    text(c.ay_mps2),
                    text(c.c2n),
                    interval(c.ci95),
                    text(c.n_samples),
                )
                for c in crossings
            ),
            numeric,
        ),
    )


def _rejected(rejected: Sequence[RejectedRow]) -> str:
    if not rejected:
        return section("Rejected sign changes", none("none"))
    headers = ("t [s]", "direction", "sweep", "u [km/h]", "reason")
    return section(
        f"Rejected sign changes ({len(rejected)})",
        table(
            headers,
            (
                (text(r.t), text(r.direction), text(r.sweep), _fixed(_kmh(r.u_mps), 2), text(r.reason))
                for r in rejected
            ),
            (True, False, False, True, False),
        ),
    )


def _frames(frames: Frames) -> str:
    return section(
        "Frames",
        table(
            ("", "frames"),
            ((html.escape(name.replace("_", " ")), text(n)) for name, n in asdict(frames).items()),
            (False, True),
        ),
    )


def _plots(images: Sequence[tuple[str, bytes]]) -> str:
    if not images:
        return section("Plots", none("no plots"))
    figures = "\n".join(figure(name, data) for name, data in images)
    return section("Plots", figures)
