"""The gap report: residual maps as plots and the diagnosis, in one self-contained HTML file."""

import html
import io
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from app.gap.diagnose import Diagnosis, Residuals
from app.sinks.html import fields, figure, page, section, table, text
from app.sinks.plots import DPI, SIZE_IN, stride

_MAX_POINTS = 30_000


def _png(draw: Any, *args: Any) -> bytes:
    fig = Figure(figsize=SIZE_IN, dpi=DPI)
    FigureCanvasAgg(fig)
    draw(fig, *args)
    fig.tight_layout()
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=DPI)
    return buffer.getvalue()


def _scatter_pair(fig: Figure, res: Residuals, x: np.ndarray, xlabel: str, effect: str) -> None:
    rows = res.rows
    pick = np.flatnonzero(rows)[stride(int(rows.sum()), _MAX_POINTS)]
    for i, (values, label) in enumerate(((res.before, "calibrated model"), (res.after, f"with {effect}"))):
        ax = fig.add_subplot(1, 2, i + 1)
        left, right = pick[res.ay[pick] > 0.3], pick[res.ay[pick] < -0.3]
        other = pick[np.abs(res.ay[pick]) <= 0.3]
        ax.scatter(x[other], values[other], s=1, c="0.6", label="straight", rasterized=True)
        ax.scatter(x[left], values[left], s=1, c="tab:blue", label="left", rasterized=True)
        ax.scatter(x[right], values[right], s=1, c="tab:red", label="right", rasterized=True)
        ax.axhline(0.0, color="black", linewidth=0.8)
        ax.set_xlabel(xlabel)
        ax.set_ylabel("sideslip residual [deg]")
        ax.set_title(label, fontsize="medium")
        ax.grid(alpha=0.3)
        if i == 0:
            ax.legend(fontsize="small", markerscale=6)
    fig.suptitle(f"Sideslip residual (measured − model) against {xlabel.split(' [')[0]}")


def _time(fig: Figure, res: Residuals, effect: str) -> None:
    ax = fig.add_subplot(1, 1, 1)
    pick = np.flatnonzero(res.rows)[stride(int(res.rows.sum()), _MAX_POINTS)]
    ax.scatter(res.t[pick], res.before[pick], s=1, c="tab:orange", label="calibrated model", rasterized=True)
    ax.scatter(res.t[pick], res.after[pick], s=1, c="tab:green", label=f"with {effect}", rasterized=True)
    ax.axhline(0.0, color="black", linewidth=0.8)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("sideslip residual [deg]")
    ax.set_title("Sideslip residual over the drive")
    ax.grid(alpha=0.3)
    ax.legend(fontsize="small", markerscale=6)


def _bars(fig: Figure, labels: Sequence[str], values: Sequence[float], title: str, xlabel: str) -> None:
    ax = fig.add_subplot(1, 1, 1)
    y = np.arange(len(labels))
    ax.barh(y, values, color="tab:blue")
    ax.set_yticks(y, labels, fontsize="small")
    ax.invert_yaxis()
    ax.set_xlabel(xlabel)
    ax.set_title(title)
    ax.grid(alpha=0.3, axis="x")


def plots(diagnosis: Diagnosis) -> list[tuple[str, bytes]]:
    res, result = diagnosis.residuals, diagnosis.result
    effect = result.diagnosis if result.diagnosis != "none" else "no effect"
    located = result.located
    candidates = result.candidates
    return [
        ("gap_residual_time.png", _png(_time, res, effect)),
        ("gap_residual_ay.png", _png(_scatter_pair, res, res.ay, "lateral acceleration [m/s²]", effect)),
        ("gap_residual_heading.png", _png(_scatter_pair, res, res.heading_deg, "heading [deg]", effect)),
        (
            "gap_located.png",
            _png(
                _bars,
                [row.where for row in located],
                [row.concentration for row in located],
                "Where the residual concentrates (share of residual² / share of samples)",
                "concentration",
            ),
        ),
        (
            "gap_candidates.png",
            _png(
                _bars,
                [c.effect for c in candidates],
                [100 * c.shrink_heldout for c in candidates],
                "Held-out shrink of the sideslip gap per candidate effect",
                "shrink [%]",
            ),
        ),
    ]


def render(diagnosis: Diagnosis, title: str, inputs: Sequence[str]) -> str:
    result = diagnosis.result
    c2n, yaw = result.c2n, result.heldout_yaw_rms_degps
    verdict = fields(
        (
            ("inputs", ", ".join(html.escape(i) for i in inputs)),
            ("diagnosis", f"<strong>{text(result.diagnosis)}</strong>"),
            ("verdict", text(result.verdict)),
            ("what it means", text(result.action)),
            ("confounded with", text(", ".join(result.confounded_with) or None)),
            ("held-out shrink", text(result.shrink_heldout)),
            ("with the other findings beside it", text(result.shrink_heldout_with_secondary)),
            (
                "held-out sideslip gap",
                f"{text(result.heldout_rms_deg.before)}° → {text(result.heldout_rms_deg.after)}°",
            ),
            (
                "held-out yaw-rate gap",
                f"{text(yaw.before)} → {text(yaw.after)} °/s",
            ),
            (
                "C2n (config / calibrated / measured / with the effect taken out)",
                " / ".join(text(v) for v in (c2n.nominal, c2n.calibrated, c2n.measured, c2n.corrected)),
            ),
        )
    )
    calibration_rows = [
        (
            text(name),
            text(value.nominal),
            text(value.fitted),
            f"[{text(value.ci95[0])}, {text(value.ci95[1])}]",
            "at its bound: not to be trusted"
            if value.at_bound
            else text(f"held: {value.held}")
            if value.held
            else "",
        )
        for name, value in result.calibration.items()
    ]
    effect_rows = [
        (
            text(e.effect),
            text(e.channel),
            html.escape(_intervals(e.params, e.ci95)),
            f"{text(e.heldout_before)} → {text(e.heldout_after)} ({100 * e.shrink_heldout:.0f} %)"
            if e.heldout_before is not None
            else f"measured by {text(e.measured_by)}",
            text(e.gain_sigmas),
            f"{text(e.c2n_effect_pct.crossing)} / {text(e.c2n_effect_pct.headline)}",
            "<strong>matters</strong>" if e.matters else text(e.judged),
            text(e.action),
        )
        for e in result.effects
    ]
    separate = [(html.escape(other), html.escape(how)) for other, how in result.separate_by.items()]
    candidate_rows = [
        (
            text(c.effect),
            html.escape(_sizes(c.params)),
            text(", ".join(c.at_bound) or None),
            text(c.heldout_rms_before),
            text(c.heldout_rms_after),
            f"{100 * c.shrink_heldout:.1f} %",
            f"{text(c.heldout_yaw_rms_before)} → {text(c.heldout_yaw_rms_after)}",
            "named" if c.named else text(c.why_not),
        )
        for c in result.candidates
    ]
    located_rows = [
        tuple(text(v) for v in (row.where, row.share, row.samples_share, row.concentration, row.mean_deg))
        for row in result.located
    ]
    return page(
        title,
        (
            f"<h1>{html.escape(title)}</h1>",
            section("Diagnosis", verdict),
            section(
                "Calibrated nuisances (the config's value → this drive's)",
                table(
                    ("nuisance", "config", "fitted", "95 %", ""),
                    calibration_rows,
                    (False, True, True, False, False),
                ),
            ),
            section(
                "Effects the drive holds (fitted beside the nuisances; judged against the config's "
                f"tolerances: {html.escape(_sizes(result.tolerances or {}))})",
                table(
                    (
                        "effect",
                        "channel",
                        "size [95 %]",
                        "held-out gap of its channel",
                        "held-out gain z",
                        "C2n % (crossing / headline)",
                        "judged",
                        "what to do",
                    ),
                    effect_rows,
                    (False, False, False, False, True, False, False, False),
                )
                if effect_rows
                else "<p>no effect beyond the drive's own spread</p>",
            ),
            section(
                "Which manoeuvre would separate the confounded effects",
                table(("effect", "manoeuvre"), separate, (False, False)) if separate else "<p>—</p>",
            ),
            section(
                "Candidates (fitted with the nuisances on some manoeuvres, scored on the others)",
                table(
                    (
                        "effect",
                        "fitted",
                        "at bound",
                        "held-out gap before [deg]",
                        "after [deg]",
                        "shrink",
                        "yaw-rate gap [deg/s]",
                        "verdict",
                    ),
                    candidate_rows,
                    (False, False, False, True, True, True, False, False),
                ),
            ),
            section(
                "Where the residual lies",
                table(
                    ("slice", "share of residual²", "share of samples", "concentration", "mean [deg]"),
                    located_rows,
                    (False, True, True, True, True),
                ),
            ),
            section("Residual maps", *(figure(name, png) for name, png in plots(diagnosis))),
        ),
        "gap",
    )


def _sizes(params: Mapping[str, float]) -> str:
    return ", ".join(f"{k} = {v:g}" for k, v in params.items())


def _intervals(params: Mapping[str, float], ci95: Mapping[str, tuple[float, float]]) -> str:
    return ", ".join(f"{k} = {v:g} [{ci95[k][0]:g}, {ci95[k][1]:g}]" for k, v in params.items())
