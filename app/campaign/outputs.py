"""What a campaign leaves: ``results.csv`` and ``results.parquet`` (a row per drive),
``comparison.json`` (groups, differences, trends) and ``report.html``."""

import csv
import hashlib
import io
import json
import math
import os
from collections import Counter
from collections.abc import Collection, Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, NamedTuple

from app.campaign.compare import (
    Difference,
    Model,
    Pooled,
    Softening,
    Trend,
    difference,
    no_trend,
    pool,
    softening,
    trend,
    with_scale,
)
from app.campaign.manifest import Entry, Manifest
from app.campaign.row import OWN_COLUMNS, SessionResult, SessionRow
from app.errors import OutputError
from app.output.csv_dialects import CSV_DIALECTS
from app.output.files import as_text, json_ready, write_atomically, write_json
from app.output.paths import HTML_REPORT, json_with
from app.sinks.html import fields, figure, none, page, paragraph, section, table, text, write_html

_FIRST = ("log", "error", "c2n", "c2n_ci95.low", "c2n_ci95.high", "c2n_method", "u0_mps")
# what the comparison took of each session (``Compared``), after the first columns
_COMPARED = ("compared.c2n", "compared.c2n_ci95.low", "compared.c2n_ci95.high", "compared.model")
_LAST = ("frames", "seconds", "worker_peak_mib", "cached", "key")
FILES = ("results.csv", "results.parquet", "comparison.json", "report.html")  # written together


def ours(entry: Path) -> bool:
    """What a campaign leaves in its folder: its results, each as the record in its cache says
    it wrote them (``record_written``), its cache folder, a killed run's temporary folder. A
    results.csv edited by hand since, or a user's own that begins as c2n's does, is not ours: a
    later run would have replaced it, unread."""
    from app.campaign.work import CACHE, is_cache

    if entry.name == CACHE:
        return entry.is_dir() and is_cache(entry)
    if entry.name.startswith(".partial-"):
        return entry.is_dir()
    if entry.name not in FILES or not entry.is_file():
        return False
    record = _written(entry.parent)
    if record is not None:
        return _digest(entry) in record.get(entry.name, ())
    cache = entry.parent / CACHE
    return cache.is_dir() and is_cache(cache) and _begins_as_ours(entry)  # an older c2n's campaign


def _begins_as_ours(entry: Path) -> bool:
    """A campaign's file by its content, for a campaign of a c2n that kept no record."""
    starts = {"results.csv": (b"\xef\xbb\xbflog,", b"\xef\xbb\xbflog;"), "results.parquet": (b"PAR1",)}
    if entry.name in starts:
        try:
            with entry.open("rb") as file:
                return file.read(len(starts[entry.name][0])) in starts[entry.name]
        except OSError:
            return False
    if entry.name == "comparison.json":
        return json_with("groups", "differences", "trends", "method")(entry)
    return entry.name == "report.html" and HTML_REPORT(entry)


def _digest(path: Path) -> str | None:
    try:
        with path.open("rb") as file:
            return hashlib.file_digest(file, "blake2b").hexdigest()
    except OSError:
        return None


_MANIFEST = "manifest"  # the record's key for the manifest the results are of


def results_of(folder: Path) -> Path | None:
    """The manifest whose results are in ``folder`` now (None: none are, or a c2n that kept
    no record of it wrote them)."""
    from app.campaign.work import CACHE, WRITTEN

    try:
        record = json.loads((folder / CACHE / WRITTEN).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    named = record.get(_MANIFEST) if isinstance(record, dict) else None
    if not isinstance(named, str) or not any(ours(folder / name) for name in FILES):
        return None
    return Path(named)


def check_results_of(folder: Path, manifest: Manifest) -> None:
    """Refused: ``folder`` holds another manifest's results, which this run would replace (the
    analyses in its cache are kept and shared either way, keyed by the logs' content). A
    manifest is known by where it is, as its logs are (a link to it is another manifest, whose
    logs lie beside the link); the results of a c2n that kept no record of their manifest, by
    the logs their results.csv lists."""
    fix = f"choose another --out, or remove {', '.join(FILES)} there to replace them (its cache is reused)"
    other = results_of(folder)
    if other is not None and other != _where(manifest.path):
        raise OutputError(
            f"{folder}: holds the results of the campaign {other}, not of {manifest.path} — {fix}"
        )
    listed = _listed_logs(folder) if other is None else None
    if listed is not None and listed != {log_name(manifest, entry) for entry in manifest.entries}:
        raise OutputError(
            f"{folder}: holds the results of a campaign of other logs than {manifest.path}'s (results.csv "
            f"lists {len(listed)}, not as the manifest does) — {fix}"
        )


def _where(manifest: Path) -> Path:
    """The manifest as its place, not its content's: absolute, its own name kept (a link)."""
    return Path(os.path.abspath(manifest))


def _listed_logs(folder: Path) -> set[str] | None:
    """The logs results.csv lists, where it is the campaign's own (``ours``); else None."""
    results = folder / "results.csv"
    if not ours(results):
        return None
    try:
        text = results.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError):
        return None
    rows = list(csv.reader(io.StringIO(text), delimiter=text[3:4] if text.startswith("log") else ","))
    return {row[0] for row in rows[1:] if row}


def _written(folder: Path) -> dict[str, list[str]] | None:
    """The campaign's record of the results it put in ``folder`` (None: it kept none)."""
    from app.campaign.work import CACHE, WRITTEN

    try:
        record = json.loads((folder / CACHE / WRITTEN).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    if not isinstance(record, dict):
        return None
    return {
        name: [d for d in digests if isinstance(d, str)]
        for name, digests in record.items()
        if isinstance(digests, list)
    }


def record_written(folder: Path, staging: Path, manifest: Path) -> None:
    """Before the results in ``staging`` take their places in ``folder``: their digests in the
    cache's record, beside those of the ones in place now — a kill between the two leaves
    either set known as the campaign's — and the manifest they are the results of."""
    from app.campaign.work import CACHE, WRITTEN

    before = _written(folder) or {}
    record: dict[str, Any] = {name: [_digest(staging / name), *before.get(name, [])[:1]] for name in FILES}
    record[_MANIFEST] = str(_where(manifest))
    (folder / CACHE).mkdir(exist_ok=True)
    write_json(folder / CACHE / WRITTEN, record, "the campaign's record of its results")


def clashing_tags(manifest: Manifest) -> list[str]:
    """The manifest's tags named like a column c2n writes into results (``c2n``, ``error``,
    ``frames``, ``regression.…``): the file could not hold both, so the manifest is refused."""
    from dataclasses import fields as summary_fields

    from app.sinks.summary import Summary

    written = {*_FIRST, *_COMPARED, *_LAST, *OWN_COLUMNS, *(f.name for f in summary_fields(Summary))}
    return [tag for tag in manifest.tag_names if tag in written or tag.split(".", 1)[0] in written]


def log_name(manifest: Manifest, entry: Entry) -> str:
    """The log as the manifest names it (relative to the manifest's folder)."""
    return Path(os.path.relpath(entry.log, manifest.path.parent.resolve())).as_posix()


def table_rows(manifest: Manifest, rows: Sequence[SessionRow]) -> tuple[list[str], list[dict[str, Any]]]:
    """The columns and the rows of ``results``: the log as the manifest names it, its tags, then
    every key of the analysis, the bookkeeping last."""
    out = [
        {"log": log_name(manifest, entry), **entry.tags, **row.columns()}
        for entry, row in zip(manifest.entries, rows, strict=True)
    ]
    names: dict[str, None] = dict.fromkeys([*_FIRST[:1], *manifest.tag_names, *_FIRST[1:]])
    for columns in out:
        names.update(dict.fromkeys(k for k in columns if k not in _LAST))
    names.update(dict.fromkeys(_LAST))
    return list(names), out


def write_tables(
    folder: Path,
    columns: list[str],
    rows: list[dict[str, Any]],
    dialect: str = "excel",
    numeric: Collection[str] = (),
) -> None:
    """results.csv in ``dialect`` (``CSV_DIALECTS``: its numbers, and the ``numeric`` tags' values,
    with that decimal mark; its text as it is) and results.parquet."""
    delimiter, decimal = CSV_DIALECTS[dialect]
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=columns, delimiter=delimiter, lineterminator="\r\n")
    writer.writeheader()
    for row in rows:
        cells = {k: _cell(row.get(k), decimal) for k in columns}
        writer.writerow(cells | {k: cells[k].replace(".", decimal) for k in numeric if k in cells})
    # a byte-order mark: a spreadsheet then reads the units (m/s², 1/rad) as UTF-8
    write_atomically(
        folder / "results.csv", lambda tmp: tmp.write_text(buffer.getvalue(), "utf-8-sig"), "results.csv"
    )
    import pyarrow as pa
    import pyarrow.parquet as pq

    numbers = {k: _numbers([row.get(k) for row in rows]) for k in numeric if k in columns}
    table = pa.Table.from_pylist(
        [
            {k: numbers[k][i] if k in numbers else _text(row.get(k)) for k in columns}
            for i, row in enumerate(rows)
        ]
    )

    def parquet(tmp: Path) -> None:
        with tmp.open("wb") as file:  # a file, not its name: pyarrow cannot encode undecodable bytes
            pq.write_table(table, file)

    write_atomically(folder / "results.parquet", parquet, "results.parquet")


def _numbers(values: Sequence[Any]) -> list[int | float | None]:
    """A numeric tag's values as numbers for results.parquet (a reader's column of numbers, not of
    text): whole numbers where every value is one, an empty cell None."""
    read = [float(v) if isinstance(v, str) and v else None for v in values]
    if all(x is None or (x.is_integer() and abs(x) < 2**53) for x in read):
        return [None if x is None else int(x) for x in read]
    return list(read)


def _text(value: Any) -> Any:
    return as_text(value) if isinstance(value, str) else value


def _cell(value: Any, decimal: str = ".") -> Any:
    if value is None:
        return ""
    if isinstance(value, float):
        return f"{value:.10g}".replace(".", decimal)
    return _text(value)


@dataclass(frozen=True)
class Compared:
    """What the comparison took of one session: its fit of its group's tyre model where the fit
    could take either model, else its own headline."""

    c2n: float
    ci95: tuple[float, float]
    model: Model | None  # the group's tyre model; None where the headline is not such a fit
    own_model: Model | None  # the model the session's own fit chose
    softening_t: float | None


@dataclass(frozen=True)
class NoC2n:
    """A group none of whose sessions gave a C2n, and why: each error (its log's name taken off)
    with the number of sessions that gave it, the most common first."""

    n_sessions: int
    reasons: dict[str, int]

    @classmethod
    def of(cls, reasons: Sequence[str]) -> "NoC2n":
        return cls(len(reasons), dict(Counter(reasons).most_common()))

    @property
    def said(self) -> str:
        """``3 sessions, none gave a C2n: 2× <why>; 1× <why>`` (the reasons as the files gave them)."""
        counted = "; ".join(f"{n}× {reason}" for reason, n in self.reasons.items())
        return f"{sessions(self.n_sessions)}, none gave a C2n: {counted}"


@dataclass(frozen=True)
class Comparison:
    by: str | None
    groups: dict[str, Pooled]
    sessions: dict[str, list[tuple[float, float]]]  # group -> (C2n, se) of its sessions
    differences: list[Difference]
    trends: dict[str, dict[str, Trend]]  # tag -> group (or "all") -> trend
    # tag -> group -> (x, C2n, se, the session's own 95 % interval's low and high)
    tag_values: dict[str, dict[str, list[tuple[float, float, float, float, float]]]]
    failed: list[tuple[str, str]]  # (log, error)
    n_sessions: int
    softening: dict[str, Softening] = field(default_factory=dict)  # group -> its tyres' model
    compared: dict[str, Compared] = field(default_factory=dict)  # log -> what was compared of it
    no_trend: dict[str, str] = field(default_factory=dict)  # tag -> why no trend is fitted against it
    no_c2n: dict[str, NoC2n] = field(default_factory=dict)  # a group none of whose sessions gave a C2n
    # tag -> the sessions with a C2n whose cell of that numeric tag is empty: left out of its trends
    no_value: dict[str, list[str]] = field(default_factory=dict)

    @property
    def switched(self) -> dict[str, Compared]:
        """Sessions compared on their group's tyre model where their own fit chose the other."""
        return {log: c for log, c in self.compared.items() if c.model is not None and c.model != c.own_model}

    def to_json(self) -> dict[str, Any]:
        nulled: list[str] = []
        out = finite(self._json(), "", nulled)
        if nulled:  # JSON has no NaN or Infinity: such a number is null, and said so
            out["not_finite"] = {"fields": nulled, "reason": "the computation overflowed: written as null"}
        return dict(out)

    def _json(self) -> dict[str, Any]:
        return {
            "by": self.by,
            "sessions": self.n_sessions,
            "failed": [{"log": log, "error": error} for log, error in self.failed],
            "groups": {name: json_ready(asdict(p)) for name, p in self.groups.items()},
            "no_c2n": {name: json_ready(asdict(n)) for name, n in self.no_c2n.items()},
            "softening": {name: json_ready(asdict(s)) for name, s in self.softening.items()},
            "switched": [{"log": log} | json_ready(asdict(c)) for log, c in self.switched.items()],
            "differences": [json_ready(asdict(d)) for d in self.differences],
            "trends": {
                tag: {group: json_ready(asdict(t)) for group, t in per.items()}
                for tag, per in self.trends.items()
            },
            "no_trend": self.no_trend,
            "no_value": self.no_value,
            "method": "random effects: DerSimonian–Laird τ², Hartung–Knapp t interval (modified, max(1, q)); "
            "tyre softening per group: Stouffer's z of the sessions' a_y³ t (|z| > 2); a marginal fit's C2n "
            "(the default) carries the softening under its prior and is pooled as it is, a cascade fit's is "
            "compared on its group's model",
        }


def finite(value: Any, where: str, nulled: list[str]) -> Any:
    """``value`` with every NaN or infinite float replaced by None, its place added to ``nulled``."""
    if isinstance(value, float) and not math.isfinite(value):
        nulled.append(where)
        return None
    if isinstance(value, dict):
        return {k: finite(v, f"{where}.{k}" if where else str(k), nulled) for k, v in value.items()}
    if isinstance(value, list):
        return [finite(v, f"{where}[{i}]", nulled) for i, v in enumerate(value)]
    return value


class _Session(NamedTuple):
    """A session with a C2n, as the comparison reads it."""

    tags: dict[str, str]
    log: str
    group: str
    result: SessionResult

    def compared(self, decided: dict[str, Softening]) -> tuple[Compared, float]:
        """Its fit of its group's tyre model, where it has both fits, else its own headline; and
        the data's standard error of what is compared."""
        own, fits = self.result.own, self.result.fits
        tyres = decided.get(self.group)
        picked = fits.of(tyres.model) if fits is not None and tyres is not None else None
        if fits is None or tyres is None or picked is None:
            return Compared(own.c2n, own.ci95, None, None, None), own.se
        return Compared(picked.c2n, picked.ci95, tyres.model, fits.chosen, fits.softening_t), picked.se


def reason(log: Path, error: str) -> str:
    """Why a row has no C2n, without its log's name in front (``<log>: <why>``, or a session
    folder's file's ``<log>/frames.blf: <why>``): what the rows of a group can have in common."""
    name = str(log)
    if error.startswith(name):
        _, said, why = error[len(name) :].partition(": ")
        if said and why:
            return why
    return error


def _trend(values: Sequence[tuple[float, float, float, float, float]]) -> Trend | None:
    """``trend`` of sessions' (x, C2n, se, low, high)."""
    return trend([v[0] for v in values], [v[1] for v in values], [v[2] for v in values])


def _groups(manifest: Manifest, by: str | None) -> dict[int, str]:
    """Each entry's group (by its line): its ``by`` tag as written, one value of a numeric tag
    under its first spelling ('230' and '230.0' are one pressure); "all" without ``by``."""
    if by is None:
        return {entry.line: "all" for entry in manifest.entries}
    if by not in manifest.numeric_tags():
        return {entry.line: entry.tags[by] for entry in manifest.entries}
    first: dict[float, str] = {}
    return {
        entry.line: first.setdefault(float(entry.tags[by]), entry.tags[by]) if entry.tags[by] else ""
        for entry in manifest.entries
    }


def compare(manifest: Manifest, rows: Sequence[SessionRow], by: str | None) -> Comparison:
    """Groups by the ``by`` tag (one group, "all", without it); a row without a C2n is failed,
    and a group of such rows is one of ``no_c2n``, with their reasons counted."""
    failed, done = [], []
    reasons: dict[str, list[str]] = {}  # group -> why each of its failed rows has no C2n
    group_of = _groups(manifest, by)
    for entry, row in zip(manifest.entries, rows, strict=True):
        group = group_of[entry.line]
        if row.error or row.result is None:
            failed.append((entry.log.name, row.error or "no C2n"))
            reasons.setdefault(group, []).append(reason(entry.log, row.error or "no C2n"))
            continue
        done.append(_Session(entry.tags, log_name(manifest, entry), group, row.result))
    evidence: dict[str, list[float]] = {}
    for session in done:
        if session.result.softening_t is not None:
            evidence.setdefault(session.group, []).append(session.result.softening_t)
    decided = {group: tyres for group, t in sorted(evidence.items()) if (tyres := softening(t)) is not None}
    sessions: dict[str, list[tuple[float, float]]] = {}
    tagged: dict[str, dict[str, list[tuple[float, float, float, float, float]]]] = {}
    numeric = [tag for tag in manifest.numeric_tags() if tag != by]
    no_value: dict[str, list[str]] = {}
    compared: dict[str, Compared] = {}
    for session in done:
        c, se = session.compared(decided)
        compared[session.log] = c
        sessions.setdefault(session.group, []).append((c.c2n, se))
        for tag in numeric:
            if not session.tags[tag]:  # not noted: no place on the line (the terminal said so)
                no_value.setdefault(tag, []).append(session.log)
                continue
            tagged.setdefault(tag, {}).setdefault(session.group, []).append(
                (float(session.tags[tag]), c.c2n, se, *c.ci95)
            )
    pooled = {name: pool(*zip(*values, strict=True)) for name, values in sorted(sessions.items())}
    names = list(pooled)
    differences = [  # one sensor: its scale cancels
        difference(b, pooled[b], a, pooled[a]) for i, a in enumerate(names) for b in names[i + 1 :]
    ]
    common = {name: max(s.result.scale for s in done if s.group == name) for name in names}
    groups = {name: with_scale(p, common[name]) for name, p in pooled.items()}
    for session in done:  # a group of one session: its own interval stands (a short drive's
        # reaches further up than down; one as wide symmetric about C2n went below zero)
        if groups[session.group].n_sessions == 1:
            groups[session.group] = replace(groups[session.group], ci95=compared[session.log].ci95)
    trends: dict[str, dict[str, Trend]] = {}
    unfitted: dict[str, str] = {}
    for tag in numeric if done else []:  # every numeric tag a trend, or why it has none
        per_group = tagged.get(tag, {})
        everything = [value for values in per_group.values() for value in values]
        found = {"all": _trend(everything)} if len(per_group) > 1 else {}
        found |= {group: _trend(values) for group, values in sorted(per_group.items())}
        trends[tag] = {group: t for group, t in found.items() if t is not None}
        if not trends[tag]:
            unfitted[tag] = no_trend([x for x, *_ in everything], len(no_value.get(tag, [])))
    no_c2n = {group: NoC2n.of(why) for group, why in sorted(reasons.items()) if group not in sessions}
    return Comparison(
        by,
        groups,
        sessions,
        differences,
        trends,
        tagged,
        failed,
        len(rows),
        decided,
        compared,
        unfitted,
        no_c2n,
        no_value,
    )


def with_compared(
    columns: list[str], rows: list[dict[str, Any]], comparison: Comparison
) -> tuple[list[str], list[dict[str, Any]]]:
    """``results``' columns and rows with what the comparison took of each session."""
    out = []
    for row in rows:
        c = comparison.compared.get(str(row["log"]))
        extra = dict.fromkeys(_COMPARED)
        if c is not None and not row.get("error"):
            extra = dict(zip(_COMPARED, (c.c2n, *c.ci95, c.model), strict=True))
        out.append(row | extra)
    at = columns.index(_FIRST[-1]) + 1 if _FIRST[-1] in columns else len(columns)
    named = [c for c in columns if c not in _COMPARED]
    return [*named[:at], *_COMPARED, *named[at:]], out


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
    write_html(page(title, body), folder / "report.html", "report.html")


def sessions(n: int) -> str:
    """A count of sessions in words: "1 session", "2 sessions"."""
    return f"{n} session" if n == 1 else f"{n} sessions"


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
