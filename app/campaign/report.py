"""A campaign's ``report.html``: the comparison's groups, differences and trends as tables and
plots, self-contained."""

import io
import math
from pathlib import Path
from typing import Any

from app.campaign.comparison import Comparison, sessions
from app.campaign.meta_analysis import (
    Softening,
    Trend,
)
from app.errors import OutputError
from app.sinks.html import fields, figure, none, page, paragraph, section, table, text, write_html


def write_report(folder: Path, comparison: Comparison, title: str) -> None:
    images = [("C2n per group, 95 % intervals", _group_plot(comparison))]
    images += [(f"C2n against {tag}", _trend_plot(comparison, tag)) for tag in comparison.tag_values]
    by = comparison.by or "group"
    group_rows = [
        (
            text(name),
            text(p.n_sessions),
            f"{p.c2n:.3f}",
            f"{p.ci95[0]:.3f} … {p.ci95[1]:.3f}",
            f"{p.tau:.3f}",
            f"{p.i2_pct:.0f}",
            text(_tyres(comparison.softening.get(name))),
        )
        for name, p in comparison.groups.items()
    ]
    body = [
        section(
            "Campaign",
            fields(
                (
                    ("sessions", text(comparison.n_sessions)),
                    ("failed", text(len(comparison.failed))),
                    ("grouped by", text(comparison.by or "— (one group)")),
                    ("intervals", "random effects over sessions (DerSimonian–Laird, Hartung–Knapp)"),
                )
            ),
        ),
        section(
            f"C2n per {by} [1/rad]",
            table(
                (by, "sessions", "C2n [1/rad]", "95 % [1/rad]", "τ [1/rad]", "I² [%]", "tyres"),
                group_rows,
                (False, True, True, True, True, True, False),
            )
            if group_rows
            else none("no session gave a C2n"),
            *(none(f"{by} {name}: {group.said}") for name, group in comparison.no_c2n.items()),
        ),
        section(
            "Sessions compared on their group's tyre model",
            paragraph(
                "Whether tyres soften is decided per group, over its sessions' a_y³ t statistics together "
                "(Stouffer's z; softening where z < −2): a session's own t passes 2 by chance in about "
                "1.5 % of drives on linear tyres. A fit that chose its model by that test (the cascade "
                "estimator) is compared on its group's; these sessions' own fits chose the other model. "
                "A marginal fit (the default) chose none: its C2n carries the softening under its prior "
                "and is compared as it is."
            ),
            table(
                ("log", "own fit", "t", "compared on", "C2n [1/rad]", "95 % [1/rad]"),
                [
                    (
                        text(log),
                        text(c.own_model),
                        f"{c.softening_t:+.1f}",
                        text(c.model),
                        f"{c.c2n:.3f}",
                        f"{c.ci95[0]:.3f} … {c.ci95[1]:.3f}",
                    )
                    for log, c in comparison.switched.items()
                ],
                (False, False, True, False, True, True),
            )
            if comparison.switched
            else none("none: every session is compared on its own fit"),
        ),
        section(
            "Differences [1/rad]",
            table(
                ("difference", "C2n [1/rad]", "95 % [1/rad]"),
                [
                    (text(f"{d.a} − {d.b}"), f"{d.c2n:+.3f}", f"{d.ci95[0]:+.3f} … {d.ci95[1]:+.3f}")
                    for d in comparison.differences
                ],
                (False, True, True),
            )
            if comparison.differences
            else none("one group: nothing to compare"),
        ),
        section(
            "Trends",
            *_trend_tables(comparison),
        ),
        section(
            "Failed logs",
            table(
                ("log", "error"),
                [(text(log), text(error)) for log, error in comparison.failed],
                (False, False),
            )
            if comparison.failed
            else none("none"),
        ),
        section("Plots", *(figure(name, png) for name, png in images)),
    ]
    write_html(page(title, body, "campaign"), folder / "report.html", "report.html")


def _tyres(tyres: Softening | None) -> str:
    return "—" if tyres is None else f"{tyres.shown}, {sessions(tyres.n_sessions)}"


def _trend_tables(comparison: Comparison) -> list[str]:
    """A table of each numeric tag's trends, or why it has none; and the sessions left out of
    them, their tag's cell empty."""
    said = []
    for tag, per in comparison.trends.items():
        if not per:
            said.append(none(f"{tag} {comparison.no_trend.get(tag, 'no trend')}"))
            continue
        said.append(_trend_table(tag, per))
        if left_out := comparison.no_value.get(tag):
            said.append(none(f"{tag}: left out, no value in the manifest: {', '.join(left_out)}"))
    return said or [none("no numeric tag")]


def _trend_table(tag: str, per: dict[str, Trend]) -> str:
    rows = [
        (
            text(group),
            text(t.n_sessions),
            f"{t.slope:+.4g}",
            f"{t.slope_ci95[0]:+.4g} … {t.slope_ci95[1]:+.4g}",
        )
        for group, t in per.items()
    ]
    return table(
        (f"C2n against {tag}", "sessions", f"slope [1/rad per {tag}]", "95 %"),
        rows,
        (False, True, True, True),
    )


def _png(draw: Any) -> bytes:
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7, 4), layout="constrained")
    FigureCanvasAgg(fig)
    draw(fig.add_subplot())
    out = io.BytesIO()
    try:
        fig.savefig(out, format="png", dpi=100)
    except OSError as error:  # pragma: no cover - an in-memory buffer
        raise OutputError(f"a plot could not be drawn: {error}") from None
    return out.getvalue()


def _group_plot(comparison: Comparison) -> bytes:
    def draw(ax: Any) -> None:
        for x, (name, pooled) in enumerate(comparison.groups.items()):
            values = comparison.sessions[name]
            c2n = [v for v, _ in values]
            ax.scatter([x + 0.15] * len(c2n), c2n, s=12, color="0.55", label="sessions" if x == 0 else None)
            low, high = pooled.ci95
            ax.errorbar(
                [x],
                [pooled.c2n],
                yerr=[[pooled.c2n - low], [high - pooled.c2n]],
                fmt="o",
                color="C0",
                capsize=5,
                label="group, 95 %" if x == 0 else None,
            )
        ax.set_xticks(range(len(comparison.groups)), list(comparison.groups))
        ax.set_xlabel(comparison.by or "group")
        ax.set_ylabel("C2n [1/rad]")
        ax.grid(alpha=0.3)
        if comparison.groups:
            ax.legend(fontsize="small")

    return _png(draw)


# beyond this a tag is plotted in a power of ten of it: matplotlib's margins and tick steps
# overflow past ~1e307 ("arange: cannot compute length"), long after the trend was fitted
_LARGEST_PLOTTED = 1e100


def _plotted(tag: str, x: list[float]) -> tuple[float, str]:
    """The unit a tag with the values x is plotted in, and the axis's label."""
    largest = max((abs(v) for v in x), default=0.0)
    if largest < _LARGEST_PLOTTED:
        return 1.0, tag
    power = math.floor(math.log10(largest))
    return 10.0**power, f"{tag} [× 1e{power}]"


def _trend_plot(comparison: Comparison, tag: str) -> bytes:
    per_group = sorted(comparison.tag_values[tag].items())
    unit, label = _plotted(tag, [v[0] for _, values in per_group for v in values])

    def draw(ax: Any) -> None:
        for k, (group, values) in enumerate(per_group):
            x = [v[0] for v in values]
            y = [v[1] for v in values]
            err = [[v[1] - v[3] for v in values], [v[4] - v[1] for v in values]]  # each one's own interval
            ax.errorbar(
                [v / unit for v in x], y, yerr=err, fmt="o", ms=4, color=f"C{k}", alpha=0.8, label=group
            )
            fitted = comparison.trends.get(tag, {}).get(group)
            if fitted is not None:
                ends = [min(x), max(x)]
                ax.plot(
                    [e / unit for e in ends],
                    [fitted.intercept + fitted.slope * e for e in ends],
                    color=f"C{k}",
                )
        ax.set_xlabel(label)
        ax.set_ylabel("C2n [1/rad]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="small")

    return _png(draw)
