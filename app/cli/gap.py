"""``c2n gap LOG...``: where the measured drive departs from the nominal bicycle model, which
unmodelled effect explains it, and how far the gap shrinks once it is added."""

import argparse
import json
from pathlib import Path

from rich.console import Console

from app.cli.common import add_config
from app.config import load_config
from app.errors import C2nError


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
        write_json(args.json, result)
    if args.report:
        from app.gap.report import render
        from app.sinks.report import write_html

        write_html(render(diagnosis, "c2n gap", [str(p) for p in args.logs]), args.report)
    console.print(verdict_line(result))
    for row in result["located"][:3]:
        console.print(
            f"  residual concentrates in {row['where']}: {100 * row['share']:.0f} % of it in "
            f"{100 * row['samples_share']:.0f} % of the samples (mean {row['mean_deg']:+.3f}°)",
            style="dim",
        )
    return 0


def verdict_line(result: dict[str, object]) -> str:
    c2n = result["c2n"]
    assert isinstance(c2n, dict)
    rms = result["heldout_rms_deg"]
    assert isinstance(rms, dict)
    confounded = result["confounded_with"]
    also = f" (or {', '.join(confounded)})" if isinstance(confounded, list) and confounded else ""
    return (
        f"gap: {result['diagnosis']}{also}; held-out sideslip RMS {rms['before']:.4f}° → {rms['after']:.4f}° "
        f"(shrink {result['shrink_heldout']:.0%}); C2n nominal {c2n['nominal']}, measured {c2n['measured']}, "
        f"model with the effect {c2n['after']}"
    )


def write_json(path: Path, data: object) -> None:
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(data, indent=2) + "\n")
    except OSError as error:
        raise C2nError(f"{path}: cannot write ({error.strerror})") from None
