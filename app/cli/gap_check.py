"""``c2n gap-check PACK``: diagnose every case of a blind pack from its log and config alone, then
open the seal and print the confusion matrix, the accuracy, the false-alarm rate on 'none' cases
and the held-out shrink."""

import argparse
import os
from pathlib import Path
from typing import Any

from rich.console import Console
from rich.table import Table

from app.cli import common
from app.cli.common import error_console, path_argument
from app.errors import C2nError, OutputError, printable
from app.output.files import write_json
from app.output.paths import DIAGNOSIS_JSON, SCORES_JSON, Output
from app.output.paths import check as guard
from app.user_text import shown


def add_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "gap-check", help="score the gap diagnosis on a blind pack", description=__doc__
    )
    parser.add_argument(
        "pack", type=path_argument, metavar="PACK", help="a folder written by c2n simulate --pack"
    )
    parser.add_argument(
        "--workers",
        type=common.number(1, 64, integer=True),
        metavar="N",
        help="parallel cases (default: the CPU count)",
    )
    parser.add_argument(
        "--json",
        type=path_argument,
        metavar="OUT",
        help="the scores JSON here too (- : standard output); PACK/gap/scores.json always",
    )
    common.add_force(parser)
    parser.set_defaults(run=run)
    return parser


def run(args: argparse.Namespace, console: Console) -> int:
    from app.gap import check

    folders = _sealed(check.cases(args.pack), check.open_seal(args.pack))  # the seal's form, not its answers
    out = args.pack / check.OUT
    _check_outputs(args, folders, out)
    done = 0

    def on_case(answer: check.CaseAnswer) -> None:
        nonlocal done
        done += 1
        said = answer.result.diagnosis if answer.result else f"error: {answer.error}"
        console.print(f"\\[{done}/{len(folders)}] {shown(answer.case)}: {shown(said)}", highlight=False)
        answered = out / f"{answer.case}.json"
        if answer.result:
            write_json(answered, answer.result.to_json(), "the case's diagnosis")
        elif DIAGNOSIS_JSON(answered):  # an earlier run's answer beside this run's error
            answered.unlink()

    answers = check.run_cases(folders, args.workers or check.default_workers(), on_case)
    scores = check.score(answers, check.open_seal(args.pack))  # the seal opens only now
    effects = sorted(
        {row["truth"] for row in scores["cases"]} | {row["diagnosis"] for row in scores["cases"]}
    )
    table = Table(title="truth (rows) × diagnosis (columns, numbered as the rows)")
    table.add_column("truth")
    for number in range(1, len(effects) + 1):
        table.add_column(str(number), justify="right")
    for number, truth in enumerate(effects, start=1):
        counts = [
            sum(1 for r in scores["cases"] if r["truth"] == truth and r["diagnosis"] == e) for e in effects
        ]
        table.add_row(f"{number} {truth}", *(str(c) if c else "·" for c in counts))
    console.print(table)
    for generator, summary in scores["generators"].items():
        console.print(f"{generator}: {summary_line(summary)}", highlight=False)
    if len(scores["generators"]) > 1:
        console.print(f"all: {summary_line(scores)}", highlight=False)
    write_json(out / "scores.json", scores, "the scores")
    if args.json and os.path.realpath(args.json) != os.path.realpath(out / "scores.json"):
        write_json(args.json, scores, "the scores")
    return 0


def _sealed(folders: list[Path], truth: dict[str, Any]) -> list[Path]:
    """The case folders the seal scores; each other is said and left out (it was diagnosed, then
    left out of the scores without a word)."""
    sealed = [folder for folder in folders if folder.name in truth["cases"]]
    for folder in folders:
        if folder.name not in truth["cases"]:
            error_console().print(
                f"c2n: warning: {printable(str(folder))}: not a case of the pack's seal — not diagnosed",
                markup=False,
            )
    if not sealed:
        raise C2nError(f"{folders[0].parent}: none of its case folders is in its seal — is it one pack?")
    return sealed


def _check_outputs(args: argparse.Namespace, folders: list[Path], out: Path) -> None:
    """Before any work: each case's answer in ``PACK/gap/`` and the scores are files c2n wrote
    there, or new (a user's file there was replaced, a read-only one too); ``gap`` is a folder."""
    if os.path.lexists(out) and not out.is_dir():
        raise OutputError(f"{out}: is a file, where gap-check writes its answers (a folder) — move it")
    # the pack's files (its cases, configs and seal) are its inputs
    pack = [p for p in args.pack.rglob("*") if p.is_file() and p.relative_to(args.pack).parts[0] != out.name]
    answers = [Output("gap-check", out / f"{folder.name}.json", DIAGNOSIS_JSON) for folder in folders]
    # the pack's scores beside its answers always (an earlier run's were left beside new answers)
    scores = [Output("gap-check", out / "scores.json", SCORES_JSON)]
    if args.json and os.path.realpath(args.json) != os.path.realpath(out / "scores.json"):
        scores.append(Output("--json", args.json, SCORES_JSON, stdout=True))
    guard([*answers, *scores], pack, args.force)


def summary_line(summary: dict[str, object]) -> str:
    """Accuracy, false alarms on 'none', named effects that made the gap worse, median shrink."""
    alarm, shrink, quartiles, total = (
        summary["false_alarm_rate"],
        summary["shrink_heldout_median"],
        summary["shrink_heldout_quartiles"],
        summary["shrink_with_secondary_median"],
    )
    alarms = (
        f"{summary['false_alarms']} of {summary['none_cases']}" if alarm is not None else "— (no 'none' case)"
    )
    spread = f" (quartiles {quartiles[0]:.0%}, {quartiles[1]:.0%})" if isinstance(quartiles, list) else ""
    errors = f"; {summary['errors']} not diagnosed" if summary["errors"] else ""
    if isinstance(total, float) and isinstance(shrink, float) and total > shrink:
        spread += f"; {total:.0%} with the secondary effects listed"
    return (
        f"accuracy {summary['accuracy']:.0%} of {summary['n']} cases; false alarms on 'none' {alarms}; "
        f"named effects with a negative shrink {summary['negative_shrinks']}; median held-out shrink "
        "of the named effects " + (f"{shrink:.0%}" if isinstance(shrink, float) else "—") + spread + errors
    )
