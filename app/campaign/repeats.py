"""A drive listed twice in a campaign (a copy, or the same drive in another format) counts once.

Each worker's row carries its drive's content identity (``drive``: ``app.sources.identity``); a
later row of the same drive becomes a row with its error, so it takes no part in any group,
difference or trend, and the terminal names it beside the one that counts."""

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from app.campaign.manifest import Manifest
from app.campaign.row import SessionRow
from app.sources.identity import DriveIdentity


def counted_once(manifest: Manifest, rows: Sequence[SessionRow]) -> tuple[list[SessionRow], list[str]]:
    """The rows with each repeat made an error row, and one line per repeat."""
    out: list[SessionRow] = []
    said: list[str] = []
    seen: list[tuple[DriveIdentity, Path]] = []
    for entry, row in zip(manifest.entries, rows, strict=True):
        identity = DriveIdentity.parse(row.drive)
        first = None
        if identity is not None and not row.error:
            first = next((log for known, log in seen if known.same_drive(identity)), None)
            if first is None:
                seen.append((identity, entry.log))
        if first is None:
            out.append(row)
            continue
        line = f"{entry.log}: the same drive as {first} (line {_line(manifest, first)}): counted once"
        out.append(replace(row, error=line))
        said.append(line)
    return out, said


def _line(manifest: Manifest, log: Path) -> int:
    return next(e.line for e in manifest.entries if e.log == log)
