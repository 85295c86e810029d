"""What a campaign leaves: ``results.csv`` and ``results.parquet`` (a row per drive),
``comparison.json`` (groups, differences, trends) and ``report.html``."""

import csv
import io
import math
import os
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from app.campaign.compare import Difference, Pooled, Trend, difference, pool, session_se, trend
from app.campaign.manifest import Manifest
from app.errors import OutputError
from app.sinks.files import json_ready, write_atomically, write_json
from app.sinks.html import fields, figure, none, page, section, table, text, write_html

_FIRST = ("log", "error", "c2n", "c2n_ci95.low", "c2n_ci95.high", "c2n_method", "u0_mps")
_LAST = ("frames", "seconds", "worker_peak_mib", "cached", "key")


def table_rows(manifest: Manifest, rows: Sequence[dict[str, Any]]) -> tuple[list[str], list[dict[str, Any]]]:
    """The columns and the rows of ``results``: the log as the manifest names it, its tags, then
    every key of the analysis, the bookkeeping last."""
    out = []
    for entry, row in zip(manifest.entries, rows, strict=True):
        log = Path(os.path.relpath(entry.log, manifest.path.parent.resolve())).as_posix()
        out.append({"log": log, **entry.tags, **{k: v for k, v in row.items() if k != "log"}})
    names: dict[str, None] = dict.fromkeys([*_FIRST[:1], *manifest.tag_names, *_FIRST[1:]])
    for row in out:
        names.update(dict.fromkeys(k for k in row if k not in _LAST))
    names.update(dict.fromkeys(_LAST))
    return list(names), out


def write_tables(folder: Path, columns: list[str], rows: list[dict[str, Any]]) -> None:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, lineterminator="\r\n")
    writer.writeheader()
    writer.writerows({k: _cell(row.get(k)) for k in columns} for row in rows)
    # a byte-order mark: a spreadsheet then reads the units (m/s², 1/rad) as UTF-8
    write_atomically(
        folder / "results.csv", lambda tmp: tmp.write_text(buffer.getvalue(), "utf-8-sig"), "results.csv"
    )
    import pyarrow as pa
    import pyarrow.parquet as pq

    table = pa.Table.from_pylist([{k: row.get(k) for k in columns} for row in rows])
    write_atomically(folder / "results.parquet", lambda tmp: pq.write_table(table, tmp), "results.parquet")


def _cell(value: Any) -> Any:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.10g}"
    return value


@dataclass(frozen=True)
class Comparison:
    by: str | None
    groups: dict[str, Pooled]
    sessions: dict[str, list[tuple[float, float]]]  # group -> (C2n, se) of its sessions
    differences: list[Difference]
    trends: dict[str, dict[str, Trend]]  # tag -> group (or "all") -> trend
    tag_values: dict[str, dict[str, list[tuple[float, float, float]]]]  # tag -> group -> (x, C2n, se)
    failed: list[tuple[str, str]]  # (log, error)
    n_sessions: int

    def to_json(self) -> dict[str, Any]:
        return {
            "by": self.by,
            "sessions": self.n_sessions,
            "failed": [{"log": log, "error": error} for log, error in self.failed],
            "groups": {name: json_ready(asdict(p)) for name, p in self.groups.items()},
            "differences": [json_ready(asdict(d)) for d in self.differences],
            "trends": {
                tag: {group: json_ready(asdict(t)) for group, t in per.items()}
                for tag, per in self.trends.items()
            },
            "method": "random effects: DerSimonian–Laird τ², Hartung–Knapp t interval (modified, max(1, q))",
        }


def compare(manifest: Manifest, rows: Sequence[dict[str, Any]], by: str | None) -> Comparison:
    """Groups by the ``by`` tag (one group, "all", without it); a row without a C2n is failed."""
    sessions: dict[str, list[tuple[float, float]]] = {}
    tagged: dict[str, dict[str, list[tuple[float, float, float]]]] = {}
    numeric = [tag for tag in manifest.numeric_tags() if tag != by]
    failed = []
    for entry, row in zip(manifest.entries, rows, strict=True):
        values = row.get("c2n"), row.get("c2n_ci95.low"), row.get("c2n_ci95.high")
        if row.get("error") or not _finite(*values):
            failed.append((entry.log.name, str(row.get("error") or "no C2n")))
            continue
        c2n, low, high = (float(v) for v in values if v is not None)
        group = entry.tags[by] if by else "all"
        se = session_se((low, high))
        sessions.setdefault(group, []).append((c2n, se))
        for tag in numeric:
            tagged.setdefault(tag, {}).setdefault(group, []).append((float(entry.tags[tag]), c2n, se))
    groups = {name: pool(*zip(*values, strict=True)) for name, values in sorted(sessions.items())}
    names = list(groups)
    differences = [
        difference(b, groups[b], a, groups[a]) for i, a in enumerate(names) for b in names[i + 1 :]
    ]
    trends: dict[str, dict[str, Trend]] = {}
    for tag, per_group in tagged.items():
        everything = [value for values in per_group.values() for value in values]
        found = {"all": trend(*zip(*everything, strict=True))} if len(per_group) > 1 else {}
        found |= {group: trend(*zip(*values, strict=True)) for group, values in sorted(per_group.items())}
        trends[tag] = {group: t for group, t in found.items() if t is not None}
    return Comparison(by, groups, sessions, differences, trends, tagged, failed, len(rows))


def _finite(*values: Any) -> bool:
    return all(isinstance(v, int | float) and math.isfinite(v) for v in values)


def write_comparison(folder: Path, comparison: Comparison) -> None:
    write_json(folder / "comparison.json", comparison.to_json(), "comparison.json")


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
                (by, "sessions", "C2n [1/rad]", "95 % [1/rad]", "τ between sessions [1/rad]", "I² [%]"),
                group_rows,
                (False, True, True, True, True, True),
            )
            if group_rows
            else none("no session gave a C2n"),
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
            *([_trend_table(tag, per) for tag, per in comparison.trends.items()] or [none("no numeric tag")]),
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
    write_html(page(title, body), folder / "report.html", "report.html")


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


def _trend_plot(comparison: Comparison, tag: str) -> bytes:
    def draw(ax: Any) -> None:
        for k, (group, values) in enumerate(sorted(comparison.tag_values[tag].items())):
            x = [v[0] for v in values]
            y = [v[1] for v in values]
            err = [1.96 * v[2] for v in values]
            ax.errorbar(x, y, yerr=err, fmt="o", ms=4, color=f"C{k}", alpha=0.8, label=group)
            fitted = comparison.trends.get(tag, {}).get(group)
            if fitted is not None:
                ends = [min(x), max(x)]
                ax.plot(ends, [fitted.intercept + fitted.slope * e for e in ends], color=f"C{k}")
        ax.set_xlabel(tag)
        ax.set_ylabel("C2n [1/rad]")
        ax.grid(alpha=0.3)
        ax.legend(fontsize="small")

    return _png(draw)
