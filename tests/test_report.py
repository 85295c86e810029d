"""The HTML report of ``c2n export``: one file that fetches nothing, shows the summary's numbers
and every plot, escapes what came from the data, and opens in a real browser without errors."""

import base64
import re
import shutil
import subprocess
from pathlib import Path

import pytest

from app.errors import C2nError
from app.sinks.plots import write_plots
from app.sinks.report import render, write_report
from app.sinks.summary import PairedRow, RejectedRow, Summary
from tests.exported import Exported, exported_drive

HOSTILE = "<script>alert('pwned')</script> & \"quoted\""
BROWSERS = ("chromium", "chromium-browser", "google-chrome")


@pytest.fixture(scope="module")
def exported() -> Exported:
    result = exported_drive()
    return Exported(result.trace, result.summary.warned([HOSTILE]))


@pytest.fixture(scope="module")
def plots(exported: Exported, tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    return write_plots(exported.trace, exported.summary, tmp_path_factory.mktemp("plots"))


@pytest.fixture(scope="module")
def report(exported: Exported, plots: list[Path], tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("report") / "report.html"
    write_report(exported.summary, plots, path, title="c2n — <sim> drive")
    return path


def test_the_report_fetches_nothing(report: Path) -> None:
    document = report.read_text(encoding="utf-8")
    assert document.startswith("<!DOCTYPE html>")
    sources = re.findall(r"""\bsrc\s*=\s*["']?([^"'\s>]*)""", document)
    assert len(sources) == 4 and all(s.startswith("data:image/png;base64,") for s in sources)
    text = re.sub(r"base64,[A-Za-z0-9+/=]+", "base64,", document)  # base64 may hold "//"
    for external in ("http://", "https://", "//", 'src="/', "url(", "@import", "href="):
        assert external not in text, external
    assert not list(report.parent.glob("*.tmp"))  # written atomically


def test_each_plot_is_inlined_byte_for_byte(report: Path, plots: list[Path]) -> None:
    document = report.read_text(encoding="utf-8")
    assert document.count("<img") == len(plots) == 4
    inlined = re.findall(r'src="data:image/png;base64,([A-Za-z0-9+/=]+)"', document)
    assert [base64.b64decode(data) for data in inlined] == [p.read_bytes() for p in plots]


def test_the_headline_and_the_crossings_are_shown(report: Path, exported: Exported) -> None:
    document = report.read_text(encoding="utf-8")
    summary = exported.summary.to_json()
    low, high = summary["c2n_ci95"]
    assert f'<span class="value">{summary["c2n"]}</span> 1/rad, 95 % [{low}, {high}] 1/rad' in document
    assert f"({summary['c2n_method']})" in document
    u0 = summary["u0_mps"]
    assert f"{u0} m/s = {u0 * 3.6:.2f} km/h" in document
    crossings = summary["crossings"]
    assert f"<h2>Crossings ({len(crossings)})</h2>" in document
    for crossing in crossings:
        lo, hi = crossing["ci95"]
        row = (
            f'<tr><td class="number">{crossing["t"]}</td><td>{crossing["direction"]}</td>'
            f'<td>{crossing["sweep"]}</td><td class="number">{crossing["u0_kmh"]:.2f}</td>'
            f'<td class="number">{crossing["ay_mps2"]}</td><td class="number">{crossing["c2n"]}</td>'
            f'<td>[{lo}, {hi}]</td><td class="number">{crossing["n_samples"]}</td></tr>'
        )
        assert row in document
    fit = summary["regression"]
    assert f"{fit['d_m']} m" in document and f"{fit['psi0_deg']}°" in document
    assert f"{summary['frames']['total']:,}" in document


def test_strings_from_the_data_are_escaped(report: Path) -> None:
    document = report.read_text(encoding="utf-8")
    assert document.count("<script") == 1  # the report's own, at the end
    assert "&lt;script&gt;alert(&#x27;pwned&#x27;)&lt;/script&gt; &amp; &quot;quoted&quot;" in document
    assert "<title>c2n — &lt;sim&gt; drive</title>" in document
    assert '<ul class="warnings">' in document


def test_missing_blocks_show_a_dash_or_a_note() -> None:
    document = render(Summary(c2n=None, regression=None, paired=None, crossings=(), warnings=()), [], "empty")
    assert '<span class="value">—</span>' in document
    assert "no regression" in document and "no pairs" in document and "no crossings" in document
    assert "No warnings." in document and "no plots" in document
    assert (
        render(Summary(), [], "nothing at all").count("<section>") == 8
    )  # every section, each saying it has nothing


def test_no_result_says_why_and_an_interval_without_an_upper_end_says_so() -> None:
    """The terminal's "C2n: no result (…)" in the report too; an interval's null upper end is no
    missing value: "no upper bound" (a dash read as both)."""
    why = (
        "1 crossing reads C2n 15.05 but does not bound it: its 95 % interval runs from 6.56 with no upper end"
    )
    paired = PairedRow(15.0541, (6.5641, None), None, None, None, None, (), {}, 1, 1.0)
    document = render(Summary(no_result=why, paired=paired), [], "one crossing")
    assert f'<p class="headline">No C2n: {why}</p>' in document
    assert "[6.5641, no upper bound]" in document


def test_rejected_sign_changes_are_listed_with_their_reasons() -> None:
    rejected = {"t": 12.5, "direction": "left", "sweep": "up", "u_mps": 10.0, "reason": "too few <samples>"}
    document = render(Summary(rejected_crossings=(RejectedRow(**rejected),)), [], "rejected")
    assert "<h2>Rejected sign changes (1)</h2>" in document
    assert '<td class="number">36.00</td><td>too few &lt;samples&gt;</td>' in document


def test_an_unwritable_report_is_a_c2n_error(exported: Exported, tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    path = blocker / "report.html"
    with pytest.raises(C2nError, match=re.escape(f"{path}: cannot write the report (")):
        write_report(exported.summary, [], path, "title")


def test_a_missing_plot_is_a_c2n_error(exported: Exported, tmp_path: Path) -> None:
    with pytest.raises(C2nError, match=r"gone\.png: cannot read the plot"):
        write_report(exported.summary, [tmp_path / "gone.png"], tmp_path / "report.html", "title")


# --- in a real browser ------------------------------------------------------------------------


def browser() -> str:
    for name in BROWSERS:
        found = shutil.which(name)
        if found:
            return found
    pytest.skip("Chromium not installed: apt-get install chromium (Debian/Ubuntu)")


def open_headless(page: Path, profile: Path) -> tuple[str, list[str]]:
    """The page's DOM after its scripts ran, and the console lines Chromium logged for it:
    ``[…:INFO:CONSOLE:12] "Uncaught Error: …", source: file:///… (12)``."""
    done = subprocess.run(
        [
            browser(),
            "--headless=new",
            "--no-sandbox",
            "--disable-gpu",
            f"--user-data-dir={profile}",
            "--enable-logging=stderr",
            "--v=0",
            "--virtual-time-budget=5000",
            "--dump-dom",
            page.as_uri(),
        ],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    console = [line for line in done.stderr.splitlines() if "CONSOLE" in line or "Uncaught" in line]
    return done.stdout, console


def test_the_report_opens_in_chromium_with_every_image_decoded(report: Path, tmp_path: Path) -> None:
    dom, console = open_headless(report, tmp_path / "profile")
    assert re.search(r'<body[^>]*\bdata-images-ok="4"', dom), dom[:500]
    assert console == []


def test_the_browser_check_sees_page_errors(report: Path, tmp_path: Path) -> None:
    """The check above can fail: a copy that logs an error, throws, and loads an outside image."""
    broken = tmp_path / "broken.html"
    faults = (
        '<script>console.error("on purpose"); throw new Error("boom");</script>'
        '<img src="https://example.invalid/x.png"></body>'
    )
    broken.write_text(report.read_text(encoding="utf-8").replace("</body>", faults), encoding="utf-8")
    dom, console = open_headless(broken, tmp_path / "profile")
    text = "\n".join(console)
    assert '"on purpose"' in text and "Uncaught Error: boom" in text
    assert "Content Security Policy" in text  # the outside image was blocked, not fetched
    assert re.search(r'data-images-ok="4"', dom)  # five <img>, four decoded
