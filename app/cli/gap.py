"""``c2n gap LOG...``: where the measured drive departs from the nominal bicycle model, which
unmodelled effect explains it, and how far the gap shrinks once it is added."""

import argparse
from pathlib import Path

from rich.console import Console

from app.cli.common import add_config
from app.config import load_config
from app.gap.result import GapResult
from app.sinks.files import write_json


def add_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    parser = subparsers.add_parser("gap", help="diagnose the sim-to-real gap of a drive", description=__doc__)
    parser.add_argument(
        "logs", nargs="+", type=Path, metavar="LOG", help="the measured drive (any log format)"
    )
    add_config(parser)
    parser.add_argument("--json", type=Path, metavar="OUT", help="write the diagnosis (DESIGN §6) here")
    parser.add_argument("--report", type=Path, metavar="OUT", help="write an HTML report with residual maps")
    parser.set_defaults(run=run)
    return parser


def run(args: argparse.Namespace, console: Console) -> int:
    from app.gap.diagnose import diagnose
    from app.gap.measured import measure

    config = load_config(args.config)
    with console.status("reading the drive…"):
        measured = measure(args.logs, config)
    with console.status("fitting the candidate effects…"):
        diagnosis = diagnose(measured, config)
    result = diagnosis.result
    if args.json:
        write_json(args.json, result.to_json(), "the diagnosis")
    if args.report:
        from app.gap.report import render
        from app.sinks.html import write_html

        write_html(render(diagnosis, "c2n gap", [str(p) for p in args.logs]), args.report)
    console.print(verdict_line(result))
    for row in result.located[:3]:
        console.print(
            f"  residual concentrates in {row.where}: {100 * row.share:.0f} % of it in "
            f"{100 * row.samples_share:.0f} % of the samples (mean {row.mean_deg:+.3f}°)",
            style="dim",
        )
    return 0


def verdict_line(result: GapResult) -> str:
    c2n, rms = result.c2n, result.heldout_rms_deg
    also = f" (or {', '.join(result.confounded_with)})" if result.confounded_with else ""
    return (
        f"gap: {result.diagnosis}{also}; held-out sideslip RMS {rms.before:.4f}° → {rms.after:.4f}° "
        f"(shrink {result.shrink_heldout:.0%}); C2n nominal {c2n.nominal}, measured {c2n.measured}, "
        f"model with the effect {c2n.after}"
    )
