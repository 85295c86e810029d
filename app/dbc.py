"""Loading DBC files (cantools) and telling which CAN channel a frame belongs to."""

import logging
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from app.errors import DbcError, one_line

log = logging.getLogger(__name__)

LARGEST_DBC = 64 * 2**20  # bytes: a whole vehicle's DBC is a few MB; cantools holds a file ~10× in RAM
ChannelSpec = int | str
"""A channel as the config names it: a live channel name ("can1") or a log's channel number."""


@dataclass(frozen=True)
class Dbc:
    """A loaded DBC file and the channel it is decoded on (None: every channel)."""

    path: Path
    database: Any  # cantools.database.can.Database (untyped library)
    channel: ChannelSpec | None = None
    relaxed: bool = False  # loaded with strict=False


def load_dbc(path: Path, channel: ChannelSpec | None = None) -> Dbc:
    """Load a DBC, translating cantools' errors into one-line DbcErrors.

    Real-world DBCs often have overlapping signals; those load with ``strict=False`` and a
    warning, as long as cantools can read them at all.
    """
    import cantools  # here, not at the top: it imports python-can, and `c2n --help` needs neither

    if not path.exists():
        raise DbcError(f"{path}: DBC file not found — check [dbc] files in the config")
    if not path.is_file():
        raise DbcError(f"{path}: is a folder or a device, not a DBC file — check [dbc] files in the config")
    size = path.stat().st_size
    if size > LARGEST_DBC:
        raise DbcError(
            f"{path}: {size / 2**20:.0f} MB is no DBC (the largest vehicle DBCs are a few MB) — check "
            "[dbc] files in the config"
        )
    try:
        return Dbc(path, cantools.database.load_file(path, strict=True), channel)
    except Exception as strict_error:
        try:
            database = cantools.database.load_file(path, strict=False)
        except Exception as error:
            reason = one_line(error)
            raise DbcError(
                f"{path}: not a readable DBC ({reason}) — fix the file or remove it from [dbc] files"
            ) from error
        log.warning("%s: loaded with strict=False: %s", path, one_line(strict_error))
        return Dbc(path, database, channel, relaxed=True)


_TRAILING_NUMBER = re.compile(r"(\d+)$")


def _channel_number(channel: ChannelSpec) -> int | None:
    if isinstance(channel, int):
        return channel
    match = _TRAILING_NUMBER.search(channel)
    return int(match.group(1)) if match else None


def channel_matches(spec: ChannelSpec | None, channel: object) -> bool:
    """Does a frame received on ``channel`` belong to the config's channel ``spec``?

    None (no spec) matches every channel. Names match exactly ("can1" == "can1"); a bare number
    matches a name ending in that number, so ``1`` matches python-can's log channel 1 and "can1".
    """
    if spec is None:
        return True
    if channel is None or not isinstance(channel, int | str):
        return False
    if str(spec) == str(channel):
        return True
    if isinstance(spec, int) or isinstance(channel, int):
        return _channel_number(spec) == _channel_number(channel)
    return False
