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


def cases(pack: Path) -> list[Path]:
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
    config = load_config(own if own.exists() else DEFAULT_CONFIG)
    logs = sorted(folder.glob("drive.*"))
    try:
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
    """Confusion matrix, accuracy (the effect, or the truth within a correct confounded group),
    false alarms on 'none', and the held-out shrink."""
    confusion: Counter[tuple[str, str]] = Counter()
    correct = 0
    none_cases = none_alarms = 0
    shrinks: list[float] = []
    rows = []
    for answer in answers:
        true_effect = truth["cases"][answer.case]["effect"]["name"]
        said = answer.result.diagnosis if answer.result else "error"
        group = list(answer.result.confounded_with) if answer.result else []
        ok = said == true_effect or (true_effect != "none" and said != "none" and true_effect in group)
        correct += ok
        confusion[(true_effect, said)] += 1
        if true_effect == "none":
            none_cases += 1
            none_alarms += said != "none"
        elif answer.result:
            shrinks.append(answer.result.shrink_heldout)
        rows.append(
            {
                "case": answer.case,
                "truth": true_effect,
                "size": truth["cases"][answer.case]["effect"]["size"],
                "diagnosis": said,
                "confounded_with": group,
                "correct": ok,
                "shrink_heldout": answer.result.shrink_heldout if answer.result else None,
                "error": answer.error,
            }
        )
    n = len(answers)
    return {
        "n": n,
        "accuracy": correct / n if n else 0.0,
        "false_alarm_rate": none_alarms / none_cases if none_cases else None,
        "none_cases": none_cases,
        "shrink_heldout_median": float(np.median(shrinks)) if shrinks else None,
        "shrink_heldout_quartiles": [float(q) for q in np.percentile(shrinks, [25, 75])] if shrinks else None,
        "confusion": {f"{t} -> {s}": k for (t, s), k in sorted(confusion.items())},
        "cases": rows,
    }


def open_seal(pack: Path) -> dict[str, Any]:
    path = pack / SEALED / "truth.json"
    try:
        return dict(json.loads(path.read_text()))
    except FileNotFoundError as error:
        raise C2nError(
            f"{path}: no sealed truth — is {pack} a pack written by c2n simulate --pack?"
        ) from error
    except (OSError, json.JSONDecodeError) as error:
        raise C2nError(f"{path}: cannot read ({error})") from error
