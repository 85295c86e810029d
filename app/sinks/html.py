"""The HTML kit of c2n's reports: one self-contained page that fetches nothing (images inlined as
``data:`` URIs, CSS and script inline), so it can be mailed or archived as it is. Every value is
escaped here; missing values show "—".
"""

import base64
import html
from collections.abc import Iterable, Sequence
from pathlib import Path

from app.output.files import write_text
from app.output.paths import GENERATOR, PAGE_KIND

DASH = "—"

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


def write_html(document: str, path: Path, what: str = "the report") -> None:
    """Write a page atomically (``app.output.files``)."""
    write_text(path, document, what)


def page(title: str, sections: Sequence[str], kind: str) -> str:
    """A self-contained HTML document of sections (HTML already); ``kind``: the command whose page
    it is, in its head (``c2n gap --report`` replaces no other's)."""
    return "\n".join(
        (
            "<!DOCTYPE html>",
            '<html lang="en">',
            "<head>",
            '<meta charset="utf-8">',
            GENERATOR,
            PAGE_KIND.format(kind=kind),
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


def text(value: object) -> str:
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


def interval(pair: tuple[object, object] | None) -> str:
    """[low, high], or "—" when there is none; [low, no upper bound] where only the low end is
    (a C2n's interval without an upper end: the result file's null)."""
    if pair is None:
        return DASH
    high = "no upper bound" if pair[1] is None and pair[0] is not None else text(pair[1])
    return f"[{text(pair[0])}, {high}]"


# --- markup -------------------------------------------------------------------------------------


def section(heading: str, *body: str) -> str:
    return "\n".join((f"<section>\n<h2>{html.escape(heading)}</h2>", *body, "</section>"))


def paragraph(message: str) -> str:
    return f"<p>{html.escape(message)}</p>"


def none(message: str) -> str:
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


def figure(name: str, png: bytes) -> str:
    uri = "data:image/png;base64," + base64.b64encode(png).decode("ascii")
    caption = html.escape(name)
    return f'<figure>\n<img src="{uri}" alt="{caption}">\n<figcaption>{caption}</figcaption>\n</figure>'
