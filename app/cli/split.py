"""``c2n split LOG``: the log cut at its optical sensor's pauses, each part a log file of its own
in the log's format, for ``c2n analyze`` (or ``c2n export``, a campaign) to take each part alone.

A logger left recording through a tyre change holds two drives in one file, which those refuse
where the parts disagree. Every frame of every id goes to one part: a part begins at the first
frame of the sensor after a pause longer than the config's ``gap_reset_s``.
"""

import argparse
import contextlib
import glob
import json
import os
import struct
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console
from rich.progress import BarColumn, DownloadColumn, Progress, TaskProgressColumn, TextColumn

from app.cli.common import ENDING, add_config, error_console, interrupted_by, path_argument
from app.config import Config, load_config
from app.errors import NoResultError, OutputError, one_line, printable
from app.output.files import folder_atomically, new_folder, remove_stale
from app.output.paths import Output, check, config_files, fitted_stem
from app.user_text import argument, shown

# loaded when the command runs, not at import: `c2n --help` needs none of them
if TYPE_CHECKING:
    import can

    from app.output.can_logs import Format, PartFile
    from app.sources.logs import LogReport, LogSource
    from app.sources.spacing import FrameSpacing


def add_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "split", help="cut a log at its optical sensor's pauses, a file per part", description=__doc__
    )
    parser.add_argument(
        "log", type=path_argument, metavar="LOG", help="ASC, BLF, candump .log, CSV, TRC or MF4"
    )
    add_config(parser)
    parser.add_argument(
        "--out",
        type=path_argument,
        metavar="DIR",
        help="output folder, new or empty (default: a new folder LOG-parts beside the log)",
    )
    parser.set_defaults(run=run)
    return parser


_CHUNK = 4096  # frames assigned to their parts at once
_LARGEST_LIST = 16 << 20  # a parts.json larger is not one c2n split wrote (100,000 parts: 20 MB)
# part files open at once, a log of hundreds of pauses written in turn: far under the open-file
# limits in use (macOS's 256 a process, a shell's `ulimit -n 64`); a log's frames come in time
# order but for the few around a cut that its channels interleave
_OPEN_AT_MOST = 16


@dataclass(frozen=True)
class Cut:
    """Where a log is cut: at its pauses and where its clock goes back (``spacing``, read again
    by ``within_file.Parting``), ``spans_s`` each part's sensor's seconds from the log's first
    frame, as ``within_file`` names them."""

    spacing: "FrameSpacing"
    spans_s: list[tuple[float, float]]
    t0_s: float  # the log's first frame's time
    between: str = "pauses"  # what the parts lie between (``Parting.between``)

    def names(self, stem: str, suffix: str, folder: Path) -> list[str]:
        """``day part 07 of 12 (300–450 s).blf``: numbered to sort as they follow each other, the
        stem cut short where a name would not fit ``folder``'s file system."""
        count = len(self.spans_s)
        width = len(str(count))
        tails = [
            f" part {k:0{width}d} of {count} ({begin:.0f}–{end:.0f} s){suffix}"
            for k, (begin, end) in enumerate(self.spans_s, 1)
        ]
        short = fitted_stem(stem, max(tails, key=lambda tail: len(tail.encode())), folder)
        return [short + tail for tail in tails]


def cut_of(report: "LogReport") -> Cut:
    """The parts of ``report``'s log between its pauses, bounded as ``within_file`` bounds them."""
    from app.results.within_file import Parting

    t0 = report.span_s[0] if report.span_s is not None else 0.0
    parting = Parting(report.spacing)
    spans = [(begin - t0, end - t0) for begin, end in parting.spans(report.span_s)]
    return Cut(report.spacing, spans, t0, parting.between)


@dataclass
class _Found:
    """The first read of a log: its report (the sensor's pauses) and its sensor's frames."""

    report: "LogReport"
    sensor_frames: int = 0


def _bar(console: Console, what: str, total: int) -> Progress:
    """A transient progress bar over the file's bytes, drawn only on a terminal."""
    progress = Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TaskProgressColumn(),
        DownloadColumn(),
        console=console,
        transient=True,
        disable=not console.is_terminal,
    )
    progress.add_task(shown(what), total=total or None)  # a name's brackets are no markup
    return progress


def _advance(progress: Progress, source: "LogSource") -> None:
    progress.update(progress.task_ids[0], completed=source.bytes_read() or 0)


def find_pauses(log: Path, config: Config, console: Console) -> _Found:
    """Read ``log`` as ``c2n analyze`` reads it (the decoder's triage, blocks where the reader
    gives them) for the pauses of its optical sensor's frames and how many there are."""
    import numpy as np

    from app.decode.decoder import Decoder
    from app.results.log_clock import sensor_messages
    from app.sources.blocks import FrameBlock
    from app.sources.logs import LogSource

    sensor = frozenset(sensor_messages(config))
    source = LogSource([log], triage=Decoder(config), spaced=sensor, pause_s=config.filter.gap_reset_s)
    found = _Found(source.reports[0])
    ids = np.array(sorted(sensor))
    with _bar(console, f"finding the pauses of {log.name}", source.total_bytes) as progress:
        for n, item in enumerate(source.items(blocks=True)):
            if isinstance(item, FrameBlock):
                found.sensor_frames += int(np.isin(item.frame_id, ids).sum())
            elif item is not None and item.arbitration_id in sensor:
                found.sensor_frames += 1
            if not n % 1024:
                _advance(progress, source)
    return found


def refusal(found: _Found, config: Config) -> str | None:
    """Why the log is not split (nothing is written): no optical sensor's frame, a clock not in
    seconds (a pause at every frame: ``log_clock`` says why), or no pause."""
    from app.results.log_clock import clock_notes, sensor_messages

    report = found.report
    if not found.sensor_frames:
        ids = ", ".join(f"0x{i:X}" for i in sorted(sensor_messages(config)))
        return (
            f"{report.path}: no frames of the optical sensor (id {ids}) of {config.path} — wrong DBC or "
            "config for this log? give the car's with --config (nothing written)"
        )
    clock = clock_notes([report], config)
    if clock:
        return f"{report.path}: {clock[0].stopped} (nothing written)"
    if not (report.spacing.pauses or report.spacing.rewinds):
        return (
            f"{report.path}: the optical sensor's frames never pause longer than gap_reset_s "
            f"({config.filter.gap_reset_s:g} s), nor does their clock go back further — one part, "
            "nothing to split (nothing written)"
        )
    return None


def _chunks(messages: "Iterable[can.Message]") -> "Iterator[list[can.Message]]":
    chunk: list[can.Message] = []
    for msg in messages:
        chunk.append(msg)
        if len(chunk) == _CHUNK:
            yield chunk
            chunk = []
    if chunk:
        yield chunk


def write_parts(
    log: Path, cut: Cut, names: list[str], folder: Path, fmt: "Format", console: Console
) -> "tuple[list[PartFile], str | None]":
    """Every frame of ``log``, read as python-can reads it (every id, remote, error and CAN FD
    frames too), written in file order into its part's file in ``folder``; and why the read
    stopped before the log's end (a damaged file), if it did. Whatever stops the writing takes
    every temporary with it; an OS error is an OutputError naming the file."""
    from app.output.can_logs import PartFile, open_part
    from app.results.within_file import Parting
    from app.sources.logs import LogSource

    part_of = Parting(cut.spacing)
    source = LogSource([log])
    report = source.reports[0]
    parts: dict[int, PartFile] = {}
    writing: dict[int, PartFile] = {}  # the parts open, at most _OPEN_AT_MOST
    current: Path = folder / names[0]
    try:
        with _bar(console, f"writing the parts of {log.name}", source.total_bytes) as progress:
            for chunk in _chunks(source):
                index = part_of([m.arbitration_id for m in chunk], [m.timestamp for m in chunk])
                for k, msg in zip(index.tolist(), chunk, strict=True):
                    part = writing.get(k)
                    if part is None:
                        if k in parts:  # finished: in the file after _OPEN_AT_MOST later parts began
                            raise NoResultError(_out_of_order(log, msg, names[k]))
                        if len(writing) == _OPEN_AT_MOST:  # the earliest part is done with
                            earliest = writing.pop(min(writing))
                            current = earliest.path
                            earliest.finish()
                        current = folder / names[k]
                        start = getattr(report.reader, "start_time", None)  # an ASC's header date
                        part = parts[k] = writing[k] = open_part(current, fmt, start)
                    current = part.path
                    part.add(msg)
                _advance(progress, source)
        for k in sorted(writing):
            current = writing[k].path
            writing[k].finish()
    except OSError as error:
        raise OutputError(f"{current}: cannot write the part ({error.strerror or error})") from error
    except (ValueError, TypeError, struct.error) as error:  # a frame python-can cannot write
        raise OutputError(f"{current}: python-can cannot write a frame ({one_line(error)})") from error
    finally:
        for part in parts.values():
            part.abandon()
    if report.stopped is not None:
        error_console().print(f"c2n: warning: {printable(f'{log}: {report.stopped}')}", markup=False)
    return [parts[k] for k in sorted(parts)], report.stopped


def _out_of_order(log: Path, msg: "can.Message", name: str) -> str:
    return (
        f"{log}: the frame at {msg.timestamp:.3f} s (id 0x{msg.arbitration_id:X}) belongs to {name}, "
        f"written already: {_OPEN_AT_MOST} later parts began before it in the file (its frames out of "
        "time order across as many pauses) — split a copy sorted by time (nothing written)"
    )


PARTS_JSON = "parts.json"  # the split's own list: the log (its real path) and each part's file


def _ours(log: Path) -> Callable[[Path], bool]:
    """What an earlier ``c2n split`` of this same log wrote (replaced whole by a split into
    ``--out``): its ``parts.json``, naming the log, and the files it lists. A file merely named
    like a part (a user's notes, a logger's file) or the parts of another log of the same name
    are not ours: they were replaced, unread, when a name was enough."""
    source = os.path.realpath(log)

    def listed(folder: Path) -> frozenset[str]:
        try:
            if (folder / PARTS_JSON).stat().st_size > _LARGEST_LIST:
                return frozenset()
            written = json.loads((folder / PARTS_JSON).read_text(encoding="utf-8"))
            if written["log"] == source:
                return frozenset({PARTS_JSON, *(str(part["file"]) for part in written["parts"])})
        except (OSError, ValueError, TypeError, KeyError, IndexError):
            pass
        return frozenset()

    def ours(path: Path) -> bool:
        return path.is_file() and path.name in listed(path.parent)

    return ours


def _list_parts(
    folder: Path, log: Path, parts: "list[PartFile]", cut: Cut, config: Config, stopped: str | None
) -> None:
    """``parts.json`` beside the parts: what was split, where and into which files, and why the
    read stopped before the log's end, if it did (its last part then ends there, not the drive)."""
    from app.output.files import write_json

    t0 = cut.t0_s
    write_json(
        folder / PARTS_JSON,
        {
            "log": os.path.realpath(log),
            "pauses_longer_than_s": config.filter.gap_reset_s,
            "read_stopped": stopped,
            "parts": [
                {
                    "file": part.path.name,
                    "sensor_from_s": span[0],
                    "sensor_to_s": span[1],
                    "first_frame_s": part.first_s - t0,
                    "last_frame_s": part.last_s - t0,
                    "frames": part.frames,
                }
                for part, span in zip(parts, cut.spans_s, strict=True)
            ],
        },
        "the parts' list",
    )


def _remove_killed(log: Path, stem: str) -> None:
    """What a killed split of this log left beside it (SIGKILL, a power cut): its hidden
    folder of part files, and the folder it had claimed for them if that is still empty."""
    for left in log.parent.glob(f".{glob.escape(stem)}-parts*.partial-*"):
        prefix = left.name[: left.name.rindex(".partial-") + len(".partial-")]
        if remove_stale(log.parent, prefix):
            with contextlib.suppress(OSError):
                (log.parent / prefix[1 : -len(".partial-")]).rmdir()  # only if empty


def claim_folder(log: Path, stem: str) -> Path:
    """A new folder beside the log, ``<stem>-parts`` (``-parts-2`` … where taken): never one
    that holds someone's files."""
    _remove_killed(log, stem)
    candidates = (log.with_name(f"{stem}-parts{'' if k == 1 else f'-{k}'}") for k in range(1, 1000))
    try:
        folder = new_folder(candidates)
    except OSError as error:
        raise OutputError(
            f"{log.parent}: cannot create a folder for the parts ({error.strerror or error}) — give --out"
        ) from error
    if folder is None:
        raise OutputError(f"{log.with_name(f'{stem}-parts')}: taken up to -parts-999 — give --out")
    return folder


def run(args: argparse.Namespace, console: Console) -> int:
    from app.output.can_logs import format_of

    config = load_config(args.config)
    log: Path = args.log
    stem, fmt = format_of(log)
    ours = _ours(log)
    if args.out is not None:  # before any work: never the input, never a folder of someone's files
        check([Output("--out", args.out, ours, folder=True)], [log, *config_files(config)])
    found = find_pauses(log, config, console)
    why = refusal(found, config)
    if why is not None:
        raise NoResultError(why)
    cut = cut_of(found.report)
    claimed = args.out is None
    names = cut.names(stem, fmt.suffix, log.parent if claimed else args.out)
    with interrupted_by(*ENDING):  # SIGTERM, a closed terminal: as Ctrl-C, nothing left behind
        out: Path = claim_folder(log, fitted_stem(stem, "-parts-999", log.parent)) if claimed else args.out
        try:
            with folder_atomically(out, ours, "c2n split", replace=not claimed) as staging:
                parts, stopped = write_parts(log, cut, names, staging, fmt, console)
                _list_parts(staging, log, parts, cut, config, stopped)
        except BaseException as error:
            if not claimed:
                raise
            with contextlib.suppress(OSError):
                out.rmdir()  # claimed for this run, still empty
            if isinstance(error, OutputError):  # the folder this run made is gone again
                raise OutputError(
                    str(error).replace(f" — {out} is left as it was", " — nothing written")
                ) from error
            raise
    _say(console, log, out, cut, parts, fmt)
    return 0


def _say(
    console: Console,
    log: Path,
    out: Path,
    cut: Cut,
    parts: "list[PartFile]",
    fmt: "Format",
) -> None:
    """A line per part written (its file, seconds and frames) and how to go on."""
    if fmt.note is not None:
        error_console().print(f"c2n: note: {printable(f'{log}: {fmt.note}')}", markup=False)
    t0 = cut.t0_s
    console.print(
        printable(f"{log}: {len(cut.spans_s)} parts between the optical sensor's {cut.between} → {out}"),
        markup=False,
    )
    console.print(printable(f"  {PARTS_JSON}  the log, and each part's seconds and frames"), markup=False)
    for part in parts:
        console.print(
            printable(
                f"  {part.path.name}  {part.first_s - t0:.1f}–{part.last_s - t0:.1f} s, "
                f"{part.frames:,} frames"
            ),
            markup=False,
        )
    first = argument(out / parts[0].path.name)
    console.print(
        printable(f"analyse each part alone: c2n analyze {first} … (--pool the parts of one set of tyres)"),
        markup=False,
    )
