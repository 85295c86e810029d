"""The one error hierarchy of c2n.

Library errors (tomllib, cantools, python-can, OS) are translated into these at the edge, with
the file and the fix in the message, so the CLI can print one line and exit 1 (2 for a
UsageError). They are raised ``from`` the library's error, so ``--debug`` shows the cause.
"""

import importlib


class C2nError(Exception):
    """A user-facing error: its message is one line naming the file or field and the fix."""


class ConfigError(C2nError):
    """The vehicle config file is missing, malformed or inconsistent with its DBCs."""


class DbcError(C2nError):
    """A DBC file is missing or does not parse."""


class LogFileError(C2nError):
    """A CAN log file is missing, of an unknown format, or unreadable."""


class BusError(C2nError):
    """A CAN interface could not be opened or failed."""


class OutputError(C2nError):
    """A result file or folder could not be written (full disk, no permission, a file in the way)."""


class UsageError(C2nError):
    """The command line asks for something impossible: exit code 2, like argparse's own errors."""


class Interrupted(C2nError):
    """Ended by Ctrl-C, SIGTERM or a closed terminal, what was done kept: exit 130, as any
    command so ended; the message says what is kept and how to go on."""


class NoResultError(C2nError):
    """The input was read but cannot give a C2n (e.g. a required role had no frames)."""


class MissingLibraryError(C2nError):
    """A library of an optional extra is not installed; the message names the extra that brings it."""


def need(library: str, purpose: str, extra: str, otherwise: str = "") -> None:
    """Import ``library`` now, or say in one line what wants it and how to install it:
    ``reading .mf4 logs needs asammdf: pip install 'c2n[mf4]'`` (then ``otherwise``)."""
    try:
        importlib.import_module(library)
    except ModuleNotFoundError as error:
        raise MissingLibraryError(
            f"{purpose} needs {library}: pip install 'c2n[{extra}]'{otherwise}"
        ) from error


def one_line(error: BaseException, limit: int = 200) -> str:
    """A library error's own words on one line, cut to ``limit`` characters: the part of a
    C2nError's message that says what the library saw."""
    text = " ".join(str(error).split()) or type(error).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


_CONTROL = {c: f"\\x{c:02x}" for c in [*range(0x20), 0x7F, *range(0x80, 0xA0)]}


def printable(text: str) -> str:
    """``text`` with every control character written as its escape (``\\x1b``): what a file
    (a DBC, a log, a config) holds must not move the cursor, clear the screen or ring the bell
    of the terminal it is shown on."""
    return text.translate(_CONTROL)
