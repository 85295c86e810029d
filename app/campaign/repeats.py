"""A drive listed twice in a campaign (a copy, or the same drive in another format) counts once,
and so does one stretch of driving recorded twice (a second logger's copy, a log cut from another).

Each worker's row carries its drive's content identity (``drive``: ``app.sources.identity``) and a
sample of its optical sensor's runs (``runs``: ``app.sources.overlap``); a later row of the same
drive, or mostly of the same stretch, becomes a row with its error, so it takes no part in any
group, difference or trend, and the terminal names it beside the one that counts."""

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

from app.campaign.manifest import Manifest
from app.campaign.row import SessionRow
from app.sources.identity import DriveIdentity
from app.sources.overlap import SensorPrints, alike_earlier, of_runs


def counted_once(manifest: Manifest, rows: Sequence[SessionRow]) -> tuple[list[SessionRow], list[str]]:
    """The rows with each repeat made an error row, and one line per repeat. Of the copies of
    one stretch the one with the most frames counts (a fragment cut from a drive, or a logger
    stopped early, is the repeat wherever the manifest lists it); of equal ones, the first."""
    out: list[SessionRow] = list(rows)
    said: list[tuple[int, str]] = []
    seen: list[tuple[DriveIdentity, Path]] = []
    recorded: list[SensorPrints] = []  # the runs of the rows that count, most frames first
    recorded_logs: list[Path] = []
    holder: dict[int, int] = {}
    longest_first = sorted(range(len(rows)), key=lambda i: (-rows[i].frames if not rows[i].error else 0, i))
    for i in longest_first:
        entry, row = manifest.entries[i], rows[i]
        identity = DriveIdentity.parse(row.drive)
        first, same = None, "the same drive as"
        if identity is not None and not row.error:
            first = next((log for known, log in seen if known.same_drive(identity)), None)
            if first is None:
                seen.append((identity, entry.log))
        if first is None and row.runs and not row.error:
            earlier = alike_earlier(of_runs(row.runs), recorded, holder)
            recorded_logs.append(entry.log)
            if earlier is not None:
                first, same = recorded_logs[earlier], "the same driving as"
        if first is None:
            continue
        line = f"{entry.log}: {same} {first} (line {_line(manifest, first)}): counted once"
        out[i] = replace(row, error=line)
        said.append((i, line))
    return out, [line for _, line in sorted(said)]


def _line(manifest: Manifest, log: Path) -> int:
    return next(e.line for e in manifest.entries if e.log == log)
