"""The run loop shared by ``c2n live``, ``c2n demo`` and ``c2n analyze``: frames through the
pipeline, events printed as they happen, the dashboard redrawn and the recording flushed on a
wall-clock cadence (the only clock here, and it is injected).

Drawing the dashboard takes milliseconds of rich's layout work, too long to hold up the frames
behind it. So the loop only takes a picture of it (``rich_cast``: the dashboard's values turned
into text, well under a millisecond) and rich's own refresh thread lays that picture out and draws
it. While it draws, the interpreter switches threads every ``_SWITCH_S`` instead of Python's 5 ms,
so a frame that arrives waits at most that long for the loop.
"""

import sys
import time
from collections.abc import Callable, Iterable, Sequence
from contextlib import nullcontext
from typing import Any

import can
from rich.console import Console, RenderableType
from rich.live import Live
from rich.protocol import rich_cast
from rich.text import Text

from app.pipeline import Pipeline
from app.records import Crossing, CrossingRejected, Event, Record
from app.sinks.event_printer import crossing_line, rejected_line
from app.sinks.recorder import SessionRecorder
from app.sources.blocks import FrameBlock

_SWITCH_S = 0.0005  # the interpreter's thread switch interval while a display is drawn


class EventPrinter:
    """Prints each crossing (and each sign change not used) as one line."""

    def __init__(self, console: Console, pipeline: Pipeline, recorder: SessionRecorder | None = None) -> None:
        self.console = console
        self.pipeline = pipeline
        self.recorder = recorder

    def __call__(self, events: Sequence[Event]) -> None:
        t0 = self.pipeline.state.t_first or 0.0
        for event in events:
            if isinstance(event, Crossing):
                self.console.print(Text(crossing_line(event, t0), style="bold green"), soft_wrap=True)
            elif isinstance(event, CrossingRejected):
                self.console.print(Text(rejected_line(event, t0), style="dim"), soft_wrap=True)
            else:
                continue
            if self.recorder is not None:
                self.recorder.on_event(event, t0)


def run(
    source: Iterable[can.Message | FrameBlock | None],
    pipeline: Pipeline,
    printer: Callable[[Sequence[Event]], None],
    display: RenderableType | None = None,
    console: Console | None = None,
    recorder: SessionRecorder | None = None,
    clock: Callable[[], float] = time.monotonic,
    refresh_s: float = 0.1,
    transient: bool = False,
    on_record: Callable[[Record], None] | None = None,
    flush_s: float = 0.05,
    blocks: bool = False,
) -> bool:
    """Run until the source ends (True) or Ctrl-C / SIGTERM (False); then fit what is pending.

    The display (dashboard, progress) is drawn only on a terminal, every ``refresh_s``, from a
    picture taken in this thread; elsewhere the printed lines are all there is. A transient
    display is cleared at the end. The recording is flushed every ``flush_s`` and whenever the
    source is idle (it yields None). ``on_record`` sees every record. With ``blocks``, the
    source may yield FrameBlocks (``LogSource.items``): they go to ``process_block`` whole, with
    no record to see and no frame to record.
    """
    if blocks and (on_record is not None or recorder is not None):
        raise ValueError("FrameBlocks give no records to see and no frames to record")
    live: Any = nullcontext()
    switch_s = sys.getswitchinterval()
    if display is not None and console is not None and console.is_terminal:
        live = Live(
            rich_cast(display),
            console=console,
            refresh_per_second=1.0 / refresh_s,
            transient=transient,
            redirect_stdout=False,
        )
    completed = True
    with live:
        next_refresh = next_flush = clock()
        try:
            if isinstance(live, Live):
                sys.setswitchinterval(min(switch_s, _SWITCH_S))
            decode, take = pipeline.decoder.decode, pipeline.take  # looked up once: they run per frame
            record_frame = recorder.on_message if recorder is not None else None
            for msg in source:
                if msg is None:
                    pass
                elif blocks and type(msg) is FrameBlock:
                    events = pipeline.process_block(msg)
                    if events:
                        printer(events)
                else:
                    if record_frame is not None:
                        record_frame(msg)  # type: ignore[arg-type]  # a Message: blocks are above
                    record = decode(msg)  # type: ignore[arg-type]
                    if record is not None:
                        record = take(record)
                        if on_record is not None:
                            on_record(record)
                        if record.events:
                            printer(record.events)
                now = clock()
                if recorder is not None and (msg is None or now >= next_flush):
                    recorder.flush()
                    next_flush = now + flush_s
                if now >= next_refresh:
                    if isinstance(live, Live):
                        live.update(rich_cast(display))  # rich's refresh thread draws it
                    next_refresh = now + refresh_s
        except KeyboardInterrupt:
            completed = False
        finally:
            sys.setswitchinterval(switch_s)
        printer(pipeline.finish())
        if isinstance(live, Live):
            live.update(rich_cast(display), refresh=True)
    return completed
