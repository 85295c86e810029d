"""The blind check of the gap diagnosis: every case of a pack diagnosed from its log and config
alone, then the seal opened and the answers scored."""

import json
import os
from collections import Counter
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from app.config import DEFAULT_CONFIG, load_config
from app.errors import C2nError
from app.gap.result import GapResult

SEALED = "sealed"
OUT = "gap"


@dataclass(frozen=True)
class CaseAnswer:
    case: str
    result: GapResult | None
    error: str | None = None


# what every drive of our generators holds whatever was drawn: Magic-Formula (two-track) and
# Pacejka (CommonRoad) tyres soften with slip
ALWAYS_HELD = frozenset({"load_transfer_nonlinearity"})


def cases(pack: Path) -> list[Path]:
    """The pack's case folders with a drive log. The seal must be there (it is opened only after
    every case is diagnosed), so a pack without one fails before any work."""
    if not pack.is_dir():
        raise C2nError(f"{pack}: not a folder — give a pack written by c2n simulate --pack N")
    if not (pack / SEALED / "truth.json").is_file():
        raise C2nError(f"{pack}: no {SEALED}/truth.json — is it a pack written by c2n simulate --pack N?")
    found = sorted(p for p in pack.iterdir() if p.is_dir() and p.name != SEALED and p.name != OUT)
    found = [p for p in found if any(p.glob("drive.*"))]
    if not found:
        raise C2nError(f"{pack}: no case folders with a drive log — write a pack with c2n simulate --pack N")
    return found


def diagnose_case(folder: Path) -> CaseAnswer:
    """Only the case's log and config: nothing of the seal."""
    from app.gap.diagnose import diagnose
    from app.gap.measured import measure

    own = folder / "config.toml"
    logs = sorted(folder.glob("drive.*"))
    try:
        config = load_config(own if own.exists() else DEFAULT_CONFIG)
        return CaseAnswer(folder.name, diagnose(measure(logs, config), config).result)
    except C2nError as error:
        return CaseAnswer(folder.name, None, str(error))


def run_cases(
    folders: list[Path], workers: int, on_case: Callable[[CaseAnswer], None] | None = None
) -> list[CaseAnswer]:
    answers: list[CaseAnswer] = []
    if workers <= 1:
        for folder in folders:
            answers.append(diagnose_case(folder))
            if on_case:
                on_case(answers[-1])
    else:
        with ProcessPoolExecutor(max_workers=workers) as pool:
            for future in as_completed([pool.submit(diagnose_case, f) for f in folders]):
                answers.append(future.result())
                if on_case:
                    on_case(answers[-1])
    return sorted(answers, key=lambda a: a.case)


def default_workers() -> int:
    return max(1, min(os.cpu_count() or 1, 8))


def score(answers: list[CaseAnswer], truth: dict[str, Any]) -> dict[str, Any]:
    """Per generator and over all: the confusion matrix, the accuracy (the effect named anywhere
    in the report — the diagnosis, a finding, its confounded group, or listed within tolerance —
    and no finding the truth does not hold; a verdict of "none" with the truth among the effects it
    says the calibration absorbs counts too), false alarms on 'none', named effects that made the
    held-out gap worse, and the named effects' held-out shrink (of the gap each was named by: the
    sideslip's, or the vehicle speed signal's), alone and with the first secondary effect listed
    beside it. A sealed case without an answer (its log gone)
    counts as a failure."""
    by_case = {answer.case: answer for answer in answers}
    rows = []
    for case, sealed in sorted(truth["cases"].items()):
        answer = by_case.get(case) or CaseAnswer(case, None, "no drive log: the case was not diagnosed")
        true_effect = sealed["effect"]["name"]
        result = answer.result
        said = result.diagnosis if result else "error"
        group = list(result.confounded_with) if result else []
        findings = [e for e in result.effects if e.matters] if result else []
        # named in the report: a finding, or one the drive cannot tell from a finding; and no
        # finding the truth does not hold (every generator's tyres soften with slip)
        named = {e.effect for e in findings} | {c for e in findings for c in e.confounded_with}
        false = [
            e.effect
            for e in findings
            if e.effect not in {true_effect, *ALWAYS_HELD} and true_effect not in e.confounded_with
        ]
        ok = said == true_effect or (true_effect != "none" and said != "unexplained" and true_effect in group)
        if true_effect != "none":
            ok = (ok or true_effect in named) and not false
        else:  # nothing drawn: right when it names nothing the drive does not hold
            ok = said == "none" or (said in ALWAYS_HELD and not false)
        rows.append(
            {
                "case": case,
                "generator": sealed.get("model", "two_track"),
                "truth": true_effect,
                "size": sealed["effect"]["size"],
                "diagnosis": said,
                "confounded_with": group,
                "false_findings": false,
                "correct": ok,
                "shrink_heldout": result.shrink_heldout if result else None,
                "shrink_heldout_with_secondary": result.shrink_heldout_with_secondary if result else None,
                "error": answer.error,
            }
        )
    generators = sorted({row["generator"] for row in rows})
    return _summary(rows) | {
        "generators": {g: _summary([r for r in rows if r["generator"] == g]) for g in generators},
        "cases": rows,
    }


def _summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    n = len(rows)
    none_rows = [r for r in rows if r["truth"] == "none"]
    alarms = sum(not r["correct"] for r in none_rows)  # named what the drive does not hold
    named = [r for r in rows if r["diagnosis"] not in ("none", "unexplained", "error")]
    shrinks = [float(r["shrink_heldout"]) for r in named if r["shrink_heldout"] is not None]
    totals = [float(r["shrink_heldout_with_secondary"]) for r in named if r["shrink_heldout"] is not None]
    confusion = Counter((r["truth"], r["diagnosis"]) for r in rows)
    return {
        "n": n,
        "accuracy": sum(r["correct"] for r in rows) / n if n else 0.0,
        "false_alarm_rate": alarms / len(none_rows) if none_rows else None,
        "none_cases": len(none_rows),
        "false_alarms": alarms,
        "negative_shrinks": sum(float(r["shrink_heldout"] or 0.0) < 0 for r in named),
        "errors": sum(r["diagnosis"] == "error" for r in rows),
        "shrink_heldout_median": float(np.median(shrinks)) if shrinks else None,
        "shrink_heldout_quartiles": [float(q) for q in np.percentile(shrinks, [25, 75])] if shrinks else None,
        "shrink_with_secondary_median": float(np.median(totals)) if totals else None,
        "confusion": {f"{t} -> {s}": k for (t, s), k in sorted(confusion.items())},
    }


def open_seal(pack: Path) -> dict[str, Any]:
    """The sealed truth, each case's effect named (``{"cases": {case: {"effect": {"name", "size"}}}}``);
    one line naming the file where it is not that (a damaged seal ended, after every case was
    diagnosed, in a KeyError)."""
    path = pack / SEALED / "truth.json"
    try:
        truth = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError as error:
        raise C2nError(
            f"{path}: no sealed truth — is {pack} a pack written by c2n simulate --pack?"
        ) from error
    except (OSError, ValueError) as error:
        raise C2nError(f"{path}: cannot read ({error})") from error
    cases = truth.get("cases") if isinstance(truth, dict) else None
    cases = cases if isinstance(cases, dict) else {}
    if not cases or not all(_sealed_case(case) for case in cases.values()):
        raise C2nError(
            f"{path}: not a pack's seal (its cases, each with its effect's name and size) — write the pack "
            "again with c2n simulate --pack N"
        )
    return dict(truth)


def _sealed_case(case: object) -> bool:
    """One case of a seal: its effect's name (text) and size (a number, or none), and its
    generator's name (text) where given — what ``score`` reads (a number there ended, after every
    case was diagnosed, in a TypeError)."""
    if not isinstance(case, dict) or not isinstance(case.get("model", ""), str):
        return False
    effect = case.get("effect")
    if not isinstance(effect, dict) or not isinstance(effect.get("name"), str) or "size" not in effect:
        return False
    size = effect["size"]
    return size is None or (isinstance(size, int | float) and not isinstance(size, bool))
