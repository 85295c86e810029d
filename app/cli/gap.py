"""``c2n gap LOG...``: where the measured drive departs from the nominal bicycle model, which
unmodelled effect explains it, and how far the gap shrinks once it is added."""

import argparse
import os

from rich.console import Console

from app.cli.common import (
    ENDING,
    add_config,
    add_force,
    error_console,
    interrupted_by,
    parts_disagree,
    path_argument,
)
from app.config import load_config
from app.errors import NoResultError, need, printable
from app.gap.result import GapResult
from app.output.files import STDOUT, json_text, text_file, write_text, write_together
from app.output.paths import DIAGNOSIS_JSON, HTML_REPORT, Output, check, config_files, page_of
from app.user_text import argument


def add_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    parser = subparsers.add_parser("gap", help="diagnose the sim-to-real gap of a drive", description=__doc__)
    parser.add_argument(
        "logs", nargs="+", type=path_argument, metavar="LOG", help="the measured drive (any log format)"
    )
    add_config(parser)
    parser.add_argument(
        "--json",
        type=path_argument,
        metavar="OUT",
        help="write the diagnosis JSON here (- : standard output)",
    )
    parser.add_argument(
        "--report",
        type=path_argument,
        metavar="OUT",
        help="write an HTML report with residual maps (- : standard output)",
    )
    add_force(parser)
    parser.set_defaults(run=run)
    return parser


def run(args: argparse.Namespace, console: Console) -> int:
    from app.gap.measured import measure

    if args.report:
        need("matplotlib", "drawing the residual maps of --report", "export")
    config = load_config(args.config)
    check(
        [
            Output("--json", args.json, DIAGNOSIS_JSON, stdout=True) if args.json else None,
            Output("--report", args.report, HTML_REPORT, stdout=True, whose=page_of("gap"))
            if args.report
            else None,
        ],
        [*args.logs, *config_files(config)],
        args.force,
    )
    if len(args.logs) > 1:  # two drives merged are neither: refused as analyze refuses them
        from app.cli.analyze import each_alone

        each_alone(args.logs, config, "gap", console)
    from app.sources.sessions import parts_left_out

    for path, said in parts_left_out(args.logs, "gap"):  # a diagnosis of one part's driving
        error_console().print(f"c2n: warning: {printable(f'{path}: {said}')}", markup=False)
    workers = os.cpu_count() or 1
    with interrupted_by(*ENDING):  # each stops the forked processes too
        with console.status("reading the drive…"):  # the method's detector and regressions go on
            measured = measure(args.logs, config, background=workers > 1)  # beside the diagnosis
        for report in measured.reports:  # a log that paused: its parts alone, as c2n analyze reads them
            why = parts_disagree(report, config, console)
            if why is not None:  # two tyre sets diagnosed as one drive's gap
                from app.results.within_file import fix_for

                raise NoResultError(f"{why} — {fix_for(why, _WITHIN_FIX, argument(report.path))}")
        with console.status("fitting the candidate effects…"):
            from app.gap.diagnose import diagnose  # imported while the background works

            diagnosis = diagnose(measured, config, workers=workers)
    if measured.sign_problem is not None:  # a role the wrong way round reads as an effect (d at −1.1 m)
        raise NoResultError(f"{', '.join(map(str, args.logs))}: no diagnosis — {measured.sign_problem}")
    result = diagnosis.result
    texts = []  # (where, text, what): both made, then both written — never one run's beside another's
    if args.json:
        texts.append((args.json, json_text(result.to_json()), "the diagnosis"))
    if args.report:
        from app.gap.report import render

        texts.append((args.report, render(diagnosis, "c2n gap", [str(p) for p in args.logs]), "the report"))
    write_together([(path, text_file(text), what) for path, text, what in texts if path != STDOUT])
    for path, text, what in texts:
        if path == STDOUT:
            write_text(path, text, what)
    for line in lines(result):
        console.print(line, highlight=False)
    return 0


_WITHIN_FIX = "split the log at its pauses (c2n split {log}) and diagnose each part alone"


def _c2n(value: float | None) -> str:
    """A C2n of the diagnosis, or the words for none (it printed Python's ``None``)."""
    return "none" if value is None else str(value)


_CALIBRATION_LABELS = {
    "yaw_rate_bias_degps": ("yaw-rate sensor bias", "°/s"),
    "steering_offset_deg": ("steering-wheel centre offset", "°"),
    "steering_ratio": ("effective steering ratio", ""),
    "c1n_per_rad": ("C1n (front axle)", "1/rad"),
    "c2n_per_rad": ("C2n (rear axle)", "1/rad"),
    "turn_force_pct": ("force following the turn", "% of weight"),  # bank towards the centre, camber
}


def lines(result: GapResult) -> list[str]:
    """What ``c2n gap`` prints: the verdict, what it means, the calibration, C2n, where the gap lies."""
    named = result.diagnosis not in ("none", "unexplained")
    also = f" (or {', '.join(result.confounded_with)})" if result.confounded_with and named else ""
    out = [f"gap: {result.verdict.replace(result.diagnosis, result.diagnosis + also, 1)}"]
    if result.action:
        out.append(f"  what it means: {result.action}")
    out.extend(effect_lines(result))
    out.append("  calibrated (the config's value → this drive's, 95 %):")
    for name, value in result.calibration.items():
        label, unit = _CALIBRATION_LABELS.get(name, (name, ""))
        low, high = value.ci95
        bound = "  — at its physical bound: not to be trusted" if value.at_bound else ""
        held = f"  — held: {value.held}" if value.held else ""
        out.append(
            f"    {label:<30} {value.nominal:>8.4g} → {value.fitted:>8.4g} {unit:<5} "
            f"[{low:.4g}, {high:.4g}]{bound}{held}"
        )
    c2n = result.c2n
    corrected = f", with the effect taken out {_c2n(c2n.corrected)}" if c2n.corrected is not None else ""
    out.append(
        f"  C2n [1/rad]: config {_c2n(c2n.nominal)}, calibrated model {_c2n(c2n.calibrated)}, "
        f"the method on the measured sideslip {_c2n(c2n.measured)}{corrected} "
        f"(the pipeline's headline {_c2n(c2n.pipeline)})"
    )
    for row in result.located[:3]:
        out.append(
            f"  residual concentrates in {row.where}: {100 * row.share:.0f} % of it in "
            f"{100 * row.samples_share:.0f} % of the samples (mean {row.mean_deg:+.3f}°)"
        )
    return out


def effect_lines(result: GapResult) -> list[str]:
    """Every effect the drive holds, findings first: its size and 95 % interval, the held-out gap
    of its own channel without and with it, what it does to C2n, and the judgement."""
    if not result.effects:
        return ["  no effect found beyond the drive's own spread"]
    tolerances = result.tolerances or {}
    out = [
        "  effects found (size [95 %]; held-out gap of its channel; C2n on a single crossing / the "
        f"headline; tolerance ±{tolerances.get('c2n_pct', 0.5):g} % of C2n):"
    ]
    for e in result.effects:
        sizes = ", ".join(
            f"{name} {value:+.4g} [{e.ci95[name][0]:.4g}, {e.ci95[name][1]:.4g}]"
            for name, value in e.params.items()
        )
        unit = "°" if e.channel == "sideslip" else " m/s"
        c2n = e.c2n_effect_pct
        moves = (
            f"C2n {c2n.crossing:+.2f} % / {c2n.headline:+.2f} %"
            if c2n.crossing is not None and c2n.headline is not None
            else "C2n: no steady crossing"
        )
        mark = "MATTERS" if e.matters else "within tolerance" if not e.confounded_with else "confounded"
        seen = (
            f"{e.channel} {e.heldout_before:.4f} → {e.heldout_after:.4f}{unit} (gain z = {e.gain_sigmas:.1f})"
            if e.heldout_before is not None and e.heldout_after is not None
            else f"measured by {e.measured_by} (z = {e.gain_sigmas:.1f})"
        )
        out.append(f"    {e.effect:<27} {mark}: {sizes}; {seen}; {moves}")
        if e.matters:
            out.append(f"      what to do: {e.action}")
        elif e.confounded_with:
            out.append(f"      {e.judged}")
    return out
