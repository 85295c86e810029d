"""One self-contained HTML report of a run for ``c2n export``: the summary's numbers, the
crossings, the warnings and the plots in a single file that fetches nothing (images inlined as
``data:`` URIs, CSS and script inline), so it can be mailed or archived as it is.

``render`` is pure (summary and image bytes in, text out); ``write_report`` reads the plots and
writes the file. Every string from the summary is escaped; missing blocks show "—".
"""

import base64
import html
import os
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from app.errors import C2nError

Summary = Mapping[str, Any]

DASH = "—"
_KMH_PER_MPS = 3.6

_CSS = """
body { font: 15px/1.45 system-ui, sans-serif; color: #1d1d1f; max-width: 1240px; margin: 2em auto;
       padding: 0 1em; }
h1 { font-size: 1.6em; margin-bottom: 0.2em; }
h2 { font-size: 1.2em; border-bottom: 1px solid #ccc; padding-bottom: 0.2em; margin-top: 1.8em; }
dl.inputs { display: grid; grid-template-columns: max-content 1fr; gap: 0.1em 1em; color: #555; }
dl.inputs dt { font-weight: 600; }
dl.inputs dd { margin: 0; }
.headline { font-size: 1.3em; margin: 0.6em 0; }
.headline .value { font-size: 1.8em; font-weight: 700; }
.method { color: #555; }
table { border-collapse: collapse; margin: 0.5em 0; }
th, td { padding: 0.25em 0.8em; border-bottom: 1px solid #e3e3e3; text-align: left; }
th { background: #f4f4f6; }
td.number { text-align: right; font-variant-numeric: tabular-nums; }
table.fields th { background: none; font-weight: 600; }
ul.warnings { background: #fff4e0; border-left: 5px solid #e08a00; padding: 0.6em 0.6em 0.6em 2em; }
ul.warnings li { margin: 0.2em 0; }
.ok { color: #2a7a2a; }
.none { color: #777; font-style: italic; }
figure { margin: 1em 0; }
figure img { max-width: 100%; height: auto; border: 1px solid #e3e3e3; }
figcaption { color: #555; font-size: 0.9em; }
"""

# Sets data-images-ok on <body> to the number of images that decoded (the report's test reads it).
_SCRIPT = """
window.addEventListener("load", () => {
  const decoded = Array.from(document.images).filter((img) => img.complete && img.naturalWidth > 0);
  document.body.dataset.imagesOk = String(decoded.length);
});
"""

# Nothing may be fetched: only inline styles and scripts, images only from data: URIs.
_POLICY = "default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'"


def write_report(summary: Summary, plots: Sequence[Path], path: Path, title: str) -> None:
    """Write the report atomically: a crash leaves the old file or the new one."""
    write_html(render(summary, [(plot.name, read_plot(plot)) for plot in plots], title), path)


def write_html(document: str, path: Path) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(document, encoding="utf-8")
        os.replace(tmp, path)
    except OSError as error:
        raise C2nError(f"{path}: cannot write the report ({error.strerror})") from None


def read_plot(plot: Path) -> bytes:
    try:
        return plot.read_bytes()
    except OSError as error:
        raise C2nError(f"{plot}: cannot read the plot ({error.strerror})") from None


def render(summary: Summary, images: Sequence[tuple[str, bytes]], title: str) -> str:
    """The HTML document; ``images`` are (name, PNG bytes) in display order."""
    return page(
        title,
        (
            _header(summary, title),
            _headline(summary),
            _warnings(summary.get("warnings")),
            _regression(_block(summary.get("regression"))),
            _paired(_block(summary.get("paired"))),
            _crossings(summary.get("crossings")),
            _rejected(summary.get("rejected_crossings")),
            _frames(_block(summary.get("frames"))),
            _plots(images),
        ),
    )


def page(title: str, sections: Sequence[str]) -> str:
    """A self-contained HTML document of sections (HTML already)."""
    return "\n".join(
        (
            "<!DOCTYPE html>",
            '<html lang="en">',
            "<head>",
            '<meta charset="utf-8">',
            f'<meta http-equiv="Content-Security-Policy" content="{_POLICY}">',
            '<meta name="viewport" content="width=device-width, initial-scale=1">',
            f"<title>{text(title)}</title>",
            f"<style>{_CSS}</style>",
            "</head>",
            "<body>",
            *sections,
            f"<script>{_SCRIPT}</script>",
            "</body>",
            "</html>",
            "",
        )
    )


# --- values -------------------------------------------------------------------------------------


def text(value: Any) -> str:
    """A summary value as escaped HTML text: numbers as the summary holds them, None as "—"."""
    if value is None:
        return DASH
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return f"{value:,}"
    if isinstance(value, float):
        return html.escape(str(float(value)))  # numpy floats print as plain numbers too
    return html.escape(str(value))


def _fixed(value: Any, digits: int) -> str:
    return f"{value:.{digits}f}" if _is_number(value) else DASH


def _is_number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool)


def interval(pair: Any) -> str:
    """[low, high], or "—" when the summary has none."""
    if isinstance(pair, Sequence) and not isinstance(pair, str) and len(pair) == 2:
        return f"[{text(pair[0])}, {text(pair[1])}]"
    return DASH


def _with_interval(value: Any, pair: Any, unit: str = "") -> str:
    """The value, its unit (" m", "°") and its 95 % interval."""
    suffix = html.escape(unit) if value is not None else ""
    ci = interval(pair)
    if ci == DASH:
        return f"{text(value)}{suffix}"
    return f'{text(value)}{suffix} <span class="method">95 % {ci}</span>'


def _block(value: Any) -> Mapping[str, Any] | None:
    return value if isinstance(value, Mapping) else None


def _rows(value: Any) -> list[Mapping[str, Any]]:
    if not isinstance(value, Sequence) or isinstance(value, str):
        return []
    return [row for row in value if isinstance(row, Mapping)]


# --- markup -------------------------------------------------------------------------------------


def section(heading: str, *body: str) -> str:
    return "\n".join((f"<section>\n<h2>{html.escape(heading)}</h2>", *body, "</section>"))


def _none(message: str) -> str:
    return f'<p class="none">{html.escape(message)}</p>'


def fields(pairs: Iterable[tuple[str, str]]) -> str:
    """A two-column table of a block's fields; the values are HTML already."""
    rows = "\n".join(f"<tr><th>{html.escape(name)}</th><td>{value}</td></tr>" for name, value in pairs)
    return f'<table class="fields">\n{rows}\n</table>'


def table(headers: Sequence[str], rows: Iterable[Sequence[str]], numeric: Sequence[bool]) -> str:
    """A table with a header row; cells are HTML already; numeric columns align right."""
    head = "".join(f"<th>{html.escape(h)}</th>" for h in headers)
    body = "\n".join(
        "<tr>"
        + "".join(
            f'<td class="number">{cell}</td>' if number else f"<td>{cell}</td>"
            for cell, number in zip(row, numeric, strict=True)
        )
        + "</tr>"
        for row in rows
    )
    return f"<table>\n<thead><tr>{head}</tr></thead>\n<tbody>\n{body}\n</tbody>\n</table>"


# --- sections -----------------------------------------------------------------------------------


def _header(summary: Summary, title: str) -> str:
    inputs = _texts(summary.get("inputs"))
    pairs = (
        ("inputs", ", ".join(inputs) or DASH),
        ("config", text(summary.get("config"))),
        ("duration", f"{text(summary.get('duration_s'))} s"),
        ("c2n version", text(summary.get("version"))),
    )
    details = "\n".join(f"<dt>{html.escape(name)}</dt><dd>{value}</dd>" for name, value in pairs)
    return f'<header>\n<h1>{text(title)}</h1>\n<dl class="inputs">\n{details}\n</dl>\n</header>'


def _texts(value: Any) -> list[str]:
    if isinstance(value, Sequence) and not isinstance(value, str):
        return [text(item) for item in value]
    return [] if value is None else [text(value)]


def _headline(summary: Summary) -> str:
    c2n = summary.get("c2n")
    u0 = summary.get("u0_mps")
    u0_kmh = _kmh(None, u0)
    headline = (
        f'<p class="headline">C2n = <span class="value">{text(c2n)}</span> '
        f"95 % {interval(summary.get('c2n_ci95'))} "
        f'<span class="method">({text(summary.get("c2n_method"))})</span></p>'
    )
    values = fields(
        (
            ("u0", f"{text(u0)} m/s = {_fixed(u0_kmh, 2)} km/h"),
            ("d (sensor ahead of the rear axle)", f"{text(summary.get('d_m'))} m"),
            ("g", f"{text(summary.get('g_mps2'))} m/s²"),
        )
    )
    return section("Cornering stiffness C2n", headline, values)


def _warnings(warnings: Any) -> str:
    items = _texts(warnings)
    if not items:
        return section("Warnings", '<p class="ok">No warnings.</p>')
    listed = "\n".join(f"<li>{item}</li>" for item in items)
    return section(f"Warnings ({len(items)})", f'<ul class="warnings">\n{listed}\n</ul>')


def _regression(fit: Mapping[str, Any] | None) -> str:
    if fit is None:
        return section("Regression over every steady sample", _none("no regression: too few steady samples"))
    ay_range = interval(fit.get("ay_range_mps2"))
    return section(
        "Regression over every steady sample",
        fields(
            (
                ("C2n", _with_interval(fit.get("c2n"), fit.get("c2n_ci95"))),
                ("d", _with_interval(fit.get("d_m"), fit.get("d_ci95"), " m")),
                (
                    "ψ0 (sensor misalignment)",
                    _with_interval(fit.get("psi0_deg"), fit.get("psi0_ci95_deg"), "°"),
                ),
                ("model", text(fit.get("model"))),
                ("C2n, linear model", text(fit.get("c2n_linear_model"))),
                ("C2n, softening model", text(fit.get("c2n_softening_model"))),
                ("softening t statistic", text(fit.get("softening_t"))),
                ("samples", text(fit.get("n_samples"))),
                ("|a_y| range", f"{ay_range} m/s²" if ay_range != DASH else DASH),
            )
        ),
    )


def _paired(paired: Mapping[str, Any] | None) -> str:
    if paired is None:
        return section("Paired crossings", _none("no pairs: needs crossings up and down, left and right"))
    cancels = _texts(paired.get("cancels"))
    cells = _block(paired.get("cells")) or {}
    return section(
        "Paired crossings",
        fields(
            (
                ("C2n", _with_interval(paired.get("c2n"), paired.get("c2n_ci95"))),
                (
                    "misalignment",
                    _with_interval(paired.get("misalignment_deg"), paired.get("misalignment_ci95_deg"), "°"),
                ),
                ("lag", _with_interval(paired.get("lag_s"), paired.get("lag_ci95_s"), " s")),
                ("cancels", ", ".join(cancels) or "nothing"),
                ("cells", ", ".join(f"{text(k)}: {text(v)}" for k, v in cells.items()) or DASH),
                ("crossings", text(paired.get("n"))),
                ("Birge ratio", text(paired.get("birge_ratio"))),
            )
        ),
    )


def _crossings(crossings: Any) -> str:
    rows = _rows(crossings)
    if not rows:
        return section(
            "Crossings", _none("no crossings: the sideslip never changed sign in steady cornering")
        )
    headers = ("t [s]", "direction", "sweep", "u0 [km/h]", "a_y [m/s²]", "C2n", "95 % CI", "samples")
    numeric = (True, False, False, True, True, True, False, True)
    return section(
        f"Crossings ({len(rows)})",
        table(
            headers,
            (
                (
                    text(c.get("t")),
                    text(c.get("direction")),
                    text(c.get("sweep")),
                    _fixed(_kmh(c.get("u0_kmh"), c.get("u0_mps")), 2),
                    text(c.get("ay_mps2")),
                    text(c.get("c2n")),
                    interval(c.get("ci95")),
                    text(c.get("n_samples")),
                )
                for c in rows
            ),
            numeric,
        ),
    )


def _kmh(kmh: Any, mps: Any) -> float | None:
    if _is_number(kmh):
        return float(kmh)
    return float(mps) * _KMH_PER_MPS if _is_number(mps) else None


def _rejected(rejected: Any) -> str:
    rows = _rows(rejected)
    if not rows:
        return section("Rejected sign changes", _none("none"))
    headers = ("t [s]", "direction", "sweep", "u [km/h]", "reason")
    return section(
        f"Rejected sign changes ({len(rows)})",
        table(
            headers,
            (
                (
                    text(r.get("t")),
                    text(r.get("direction")),
                    text(r.get("sweep")),
                    _fixed(_kmh(None, r.get("u_mps")), 2),
                    text(r.get("reason")),
                )
                for r in rows
            ),
            (True, False, False, True, False),
        ),
    )


def _frames(frames: Mapping[str, Any] | None) -> str:
    if not frames:
        return section("Frames", _none("no frame counts"))
    return section(
        "Frames",
        table(
            ("", "frames"),
            ((html.escape(str(name).replace("_", " ")), text(n)) for name, n in frames.items()),
            (False, True),
        ),
    )


def _plots(images: Sequence[tuple[str, bytes]]) -> str:
    if not images:
        return section("Plots", _none("no plots"))
    figures = "\n".join(figure(name, data) for name, data in images)
    return section("Plots", figures)


def figure(name: str, png: bytes) -> str:
    uri = "data:image/png;base64," + base64.b64encode(png).decode("ascii")
    caption = html.escape(name)
    return f'<figure>\n<img src="{uri}" alt="{caption}">\n<figcaption>{caption}</figcaption>\n</figure>'
