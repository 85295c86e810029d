"""The command line: ``c2n <command>``. Each command is a module with ``add_parser`` and ``run``."""

import argparse
import gc
import logging
import os
import re
import sys
import threading
import traceback
from collections.abc import Sequence
from contextlib import AbstractContextManager, nullcontext
from typing import NoReturn, TextIO, cast

from rich.console import Console

from app import __version__
from app.cli import analyze, campaign, demo, export, gap, gap_check, live, replay, simulate, split
from app.cli.common import ENDING, INTERRUPTED, interrupted_by
from app.cli.terminal import LosableStream, say
from app.errors import C2nError, Interrupted, UsageError, printable

COMMANDS = (live, replay, analyze, export, split, simulate, gap, gap_check, campaign, demo)


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
        _plain(sub)
    return parser


class _Formatter(argparse.HelpFormatter):
    """Help that says each option's default, unless its words already do."""

    def _get_help_string(self, action: argparse.Action) -> str | None:
        text = action.help or ""
        default = action.default
        nothing = default is None or default is False or default == [] or default == argparse.SUPPRESS
        if "default" in text or not action.option_strings or nothing:  # 0 is a default, False is not
            return text
        return f"{text} (default: %(default)s)"


def _plain(parser: argparse.ArgumentParser) -> None:
    """The command's help as a user reads it: the module docstring's code marks (``x``) gone,
    each option's default said."""
    parser.formatter_class = _Formatter
    if parser.description:
        parser.description = parser.description.replace("``", "")
    for action in parser._actions:
        if action.help:
            action.help = action.help.replace("``", "")


class _WarningFormatter(logging.Formatter):
    def format(self, record: logging.LogRecord) -> str:
        return f"c2n: {record.levelname.lower()}: {record.getMessage()}"


def _configure_logging(debug: bool) -> None:
    handler = logging.StreamHandler(LosableStream(sys.stderr))
    handler.setFormatter(_WarningFormatter())
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(logging.DEBUG if debug else logging.WARNING)
    logging.getLogger("can").setLevel(logging.DEBUG if debug else logging.ERROR)
    # asammdf logs a damaged MF4 as an ERROR with a traceback; the reader's error says it in one line
    logging.getLogger("asammdf").setLevel(logging.DEBUG if debug else logging.CRITICAL)


def entry() -> NoReturn:
    """The ``c2n`` command (``python -m app``): ``main``, then the exit. What is still alive then
    is frozen first (``gc.freeze``), so the interpreter's last collections do not walk numba's,
    scipy's and pandas's objects once more before the OS frees them all (0.6 s off ``c2n gap``,
    tools/bench.py)."""
    code = main()
    if code == INTERRUPTED:
        # A KeyboardInterrupt that passed through an exec() of source text (a dataclass's methods
        # being made as the signal came) leaves CPython's "unhandled KeyboardInterrupt" flag set,
        # though main caught it: `python -m app` then ended by SIGINT (-2), 1 run in 4, where 130
        # was meant. Running source text clears the flag (pythonrun.c, run_eval_code_obj).
        exec("")
    gc.freeze()
    sys.exit(code)


def _ended_as_by_ctrl_c() -> AbstractContextManager[None]:
    """SIGTERM and a closed terminal end every command as Ctrl-C does, unwinding: a temporary
    file or folder goes, what is finished is kept. Their default ended the process where it
    stood, leaving a half-written export's hidden folder behind. (Signals are the main thread's:
    a command run in another thread keeps the handlers it finds.)"""
    if threading.current_thread() is not threading.main_thread():
        return nullcontext()
    return interrupted_by(*ENDING)


_OPTION_LIKE = re.compile(r"--?[A-Za-z][\w-]*")


def _files_read_as_options(argv: Sequence[str]) -> None:
    """After a usage error: a word that begins with '-' and names a file (`c2n gap -x.log`) was
    taken for an option, so argparse said "LOG is required" of a log it was given. Say how, and
    where no command was given (`c2n -x.log`), that one goes before it."""
    command = any(not word.startswith("-") for word in argv)  # c2n's own options take no value
    for word in argv:  # a file, named otherwise than an option is (`--force`, `-v`)
        if word.startswith("-") and not _OPTION_LIKE.fullmatch(word) and os.path.isfile(word):
            name = printable(word)
            how = f"./{name}" if command else f"a command and ./{name}, as c2n analyze ./{name}"
            say(f"c2n: hint: {name} is a file, read as an option: write {how}")


def main(argv: Sequence[str] | None = None, console: Console | None = None) -> int:
    """Run a c2n command; returns the exit code (0 ok, 1 user error, 2 bad usage)."""
    parser = build_parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exit_:
        if exit_.code:
            _files_read_as_options(sys.argv[1:] if argv is None else argv)
        return int(exit_.code or 0)
    if args.command is None:
        parser.print_help(sys.stderr)
        return 2
    _configure_logging(args.debug)
    # `--json -` (or `--report -`): standard output carries the file, the words go to stderr
    to_stdout = any(str(getattr(args, name, None)) == "-" for name in ("json", "report"))
    words = LosableStream(sys.stderr if to_stdout else sys.stdout)
    own = console is None
    console = console or Console(file=cast(TextIO, words), highlight=False, soft_wrap=True)
    try:
        with _ended_as_by_ctrl_c():
            code = int(args.run(args, console))
    except C2nError as error:
        if args.debug:
            traceback.print_exc()
        if isinstance(error, Interrupted):
            say(f"c2n: interrupted — {printable(str(error))}")
            return INTERRUPTED
        say(f"c2n: error: {printable(str(error))}")
        return 2 if isinstance(error, UsageError) else 1
    except KeyboardInterrupt:
        say("c2n: interrupted")
        return INTERRUPTED
    if own and words.lost is not None and not words.reader_left:
        # a reader that stopped reading (`| head`) wanted no more; any other loss hid the words
        where = "standard error" if to_stdout else "standard output"
        say(f"c2n: error: {where}: cannot write ({words.why}) — the command ran to its end unseen")
        return code or 1
    return code
