"""The command line: ``c2n <command>``. Each command is a module with ``add_parser`` and ``run``."""

import argparse
import logging
import sys
import traceback
from collections.abc import Sequence

from rich.console import Console

from app import __version__
from app.cli import analyze, campaign, demo, export, gap, gap_check, live, replay, simulate
from app.errors import C2nError, UsageError, printable

COMMANDS = (live, replay, analyze, export, simulate, gap, gap_check, campaign, demo)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="c2n",
        description="Tyre cornering stiffness C2n = u0²/(g·d) from the sideslip sign change, live on CAN.",
    )
    parser.add_argument("--version", action="version", version=f"c2n {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for command in COMMANDS:
        sub = command.add_parser(subparsers)
        sub.add_argument("--debug", action="store_true", help="show tracebacks and debug logging")
    return parser


class _WarningFormatter(logging.Formatter):
    def format(self, record: logging.LogRecord) -> str:
        return f"c2n: {record.levelname.lower()}: {record.getMessage()}"


def _configure_logging(debug: bool) -> None:
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(_WarningFormatter())
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(logging.DEBUG if debug else logging.WARNING)
    logging.getLogger("can").setLevel(logging.DEBUG if debug else logging.ERROR)
    # asammdf logs a damaged MF4 as an ERROR with a traceback; the reader's error says it in one line
    logging.getLogger("asammdf").setLevel(logging.DEBUG if debug else logging.CRITICAL)


def main(argv: Sequence[str] | None = None, console: Console | None = None) -> int:
    """Run a c2n command; returns the exit code (0 ok, 1 user error, 2 bad usage)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_:
        return int(exit_.code or 0)
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    _configure_logging(args.debug)
    console = console or Console(highlight=False, soft_wrap=True)
    try:
        return int(args.run(args, console))
    except C2nError as error:
        if args.debug:
            traceback.print_exc()
        print(f"c2n: error: {printable(str(error))}", file=sys.stderr)
        return 2 if isinstance(error, UsageError) else 1
    except KeyboardInterrupt:
        print("c2n: interrupted", file=sys.stderr)
        return 130
