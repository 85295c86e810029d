"""A campaign's rows compared (``comparison.json``): C2n per group of a tag, the groups'
differences, the trends against numeric tags, each group's tyre model — the statistics from
``meta_analysis.py``, the sessions that gave no C2n and why."""

import math
from collections import Counter
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any, NamedTuple

from app.campaign.manifest import Manifest
from app.campaign.meta_analysis import (
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
from app.campaign.row import SessionResult, SessionRow
from app.campaign.tables import COMPARED_COLUMNS, FIRST_COLUMNS, log_name
from app.output.files import json_ready, write_json


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
        extra = dict.fromkeys(COMPARED_COLUMNS)
        if c is not None and not row.get("error"):
            extra = dict(zip(COMPARED_COLUMNS, (c.c2n, *c.ci95, c.model), strict=True))
        out.append(row | extra)
    at = columns.index(FIRST_COLUMNS[-1]) + 1 if FIRST_COLUMNS[-1] in columns else len(columns)
    named = [c for c in columns if c not in COMPARED_COLUMNS]
    return [*named[:at], *COMPARED_COLUMNS, *named[at:]], out


def write_comparison(folder: Path, comparison: Comparison) -> None:
    write_json(folder / "comparison.json", comparison.to_json(), "comparison.json")


def sessions(n: int) -> str:
    """A count of sessions in words: "1 session", "2 sessions"."""
    return f"{n} session" if n == 1 else f"{n} sessions"
