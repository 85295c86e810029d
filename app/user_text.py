"""The one way user text reaches a terminal: paths, tags, channel and signal names, config values.

rich reads ``[...]`` in a printed string as markup: a tag ``Pirelli [old]`` would lose its
``[old]``, a ``[/]`` would raise a MarkupError after the work is done. And what a file holds must
not move the cursor or clear the screen. ``shown`` answers both; every string that comes from the
user or a file goes through it before a rich console prints it as markup.
"""

from rich.markup import escape

from app.errors import printable

EMPTY = "(empty)"


def shown(value: object) -> str:
    """``value`` as text a rich console prints literally: control characters written as their
    escapes (``\\x1b``), markup brackets escaped; the empty string as ``(empty)``."""
    text = str(value)
    return escape(printable(text)) if text else EMPTY
