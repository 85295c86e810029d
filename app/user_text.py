"""The one way user text reaches a terminal: paths, tags, channel and signal names, config values.

rich reads ``[...]`` in a printed string as markup: a tag ``Pirelli [old]`` would lose its
``[old]``, a ``[/]`` would raise a MarkupError after the work is done. And what a file holds must
not move the cursor or clear the screen. ``shown`` answers both; every string that comes from the
user or a file goes through it before a rich console prints it as markup.
"""

import shlex
from pathlib import Path

from rich.markup import escape

from app.errors import printable

EMPTY = "(empty)"


def shown(value: object) -> str:
    """``value`` as text a rich console prints literally: control characters written as their
    escapes (``\\x1b``), markup brackets escaped; the empty string as ``(empty)``, and a text that
    is ``(empty)`` itself in quotes (a tag so named is another group than the blank cells')."""
    text = printable(str(value))
    if not text:
        return EMPTY
    if text == EMPTY:
        return f"'{EMPTY}'"
    escaped = escape(text)
    # rich doubles a trailing backslash lest it escape a tag that follows; none does here (the
    # callers put no markup right after a user string), and the doubled one would be printed
    return escaped[:-1] if escaped.endswith("\\\\") and not text.endswith("\\\\") else escaped


def argument(path: Path) -> str:
    """``path`` as a command c2n suggests gives it to a shell: quoted (spaces, brackets, quotes),
    and a relative one that begins with ``-`` as ``./-day.log``, which no option parser takes for
    an option (``c2n split -day.log`` was refused: `the following arguments are required: LOG`)."""
    text = str(path)
    return shlex.quote(f"./{text}" if text.startswith("-") else text)
