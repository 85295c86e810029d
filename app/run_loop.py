"""The run loop shared by every command that reads frames (``live``, ``demo``, ``analyze``,
``export``, ``gap``): frames through the pipeline and out to the sinks, the display redrawn and
the sinks flushed on a wall-clock cadence (the only clock here, and it is injected).

Drawing the dashboard takes milliseconds of rich's layout work, too long to hold up the frames
behind it. So the loop only takes a picture of it (``rich_cast``: the dashboard's values turned
into text, well under a millisecond) and rich's own refresh thread lays that picture out and draws
it. While it draws, the interpreter switches threads every ``_SWITCH_S`` instead of Python's 5 ms,
so a frame that arrives waits at most that long for the loop.
"""

import sys
import time
from collections.abc import Callable, Iterable, Sequence
from contextlib import ExitStack, nullcontext
from typing import Any, TypeVar

import can
from rich.console import Console
from rich.live import Live
from rich.protocol import rich_cast

from app.pipeline import Pipeline
from app.records import Event
from app.sinks.sink import Display, Sink, overrides
from app.sources.blocks import FrameBlock

_SWITCH_S = 0.0005  # the interpreter's thread switch interval while a display is drawn
_T = TypeVar("_T")


def run(
    source: Iterable[can.Message | FrameBlock | None],
    pipeline: Pipeline,
    sinks: Sequence[Sink] = (),
    *,
    display: Display | None = None,
    console: Console | None = None,
    clock: Callable[[], float] = time.monotonic,
    refresh_s: float = 0.1,
    flush_s: float = 0.05,
    transient: bool = False,
    blocks: bool = False,
) -> bool:
    """Run until the source ends (True) or Ctrl-C / SIGTERM (False); then fit what is pending.

    Every sink hears what it overrides (``app.sinks.sink``); the display is one more sink, drawn
    only on a terminal, every ``refresh_s``, from a picture taken in this thread. A transient
    display is cleared at the end. Sinks are flushed every ``flush_s`` and whenever the source
    is idle (it yields None), and closed at the end whatever happened, so a recording is finished
    even when the analysis fails. With ``blocks``, the source may yield FrameBlocks
    (``LogSource.items``): they go to ``process_block`` whole, with no frame or record for a sink.
    """
    sinks = [*sinks, *([display] if display is not None and display not in sinks else [])]

    def hooks(name: str) -> list[Any]:
        return [getattr(sink, name) for sink in sinks if overrides(sink, name)]

    on_frame, on_record, on_events, on_snapshot = (
        hooks(name) for name in ("on_frame", "on_record", "on_events", "on_snapshot")
    )
    if blocks and (on_frame or on_record):
        raise ValueError("FrameBlocks give no records and no frames to a sink")
    flushes = hooks("flush")
    live: Any = nullcontext()
    if display is not None and console is not None and console.is_terminal:
        live = Live(
            rich_cast(display),
            console=console,
            refresh_per_second=1.0 / refresh_s,
            transient=transient,
            redirect_stdout=False,
        )

    def emit(events: Sequence[Event]) -> None:
        t0 = pipeline.state.t_first or 0.0
        for hook in on_events:
            hook(events, t0)

    def show() -> None:
        if on_snapshot:
            snapshot = pipeline.snapshot()
            for hook in on_snapshot:
                hook(snapshot)
        if isinstance(live, Live):
            live.update(rich_cast(display))  # rich's refresh thread draws it

    completed = True
    switch_s = sys.getswitchinterval()
    with ExitStack() as closing:
        for sink in reversed(sinks):  # closed in order, each even when one before it failed
            if overrides(sink, "close"):
                closing.callback(sink.close)
        if isinstance(live, Live) and console is not None and console.soft_wrap:
            # the display is laid out to the terminal's width, its long lines wrapped: under a
            # console's soft wrap (the command's lines are one line each) rich cut them instead
            closing.callback(setattr, console, "soft_wrap", True)
            console.soft_wrap = False
        with live:
            next_refresh = next_flush = clock()
            try:
                if isinstance(live, Live):
                    sys.setswitchinterval(min(switch_s, _SWITCH_S))
                decode, take = pipeline.decoder.decode, pipeline.take  # looked up once: they run per frame
                record_frame, see_record = _fan_out(on_frame), _fan_out(on_record)
                for msg in source:
                    if msg is None:
                        pass
                    elif blocks and type(msg) is FrameBlock:
                        events = pipeline.process_block(msg)
                        if events:
                            emit(events)
                    else:
                        if record_frame is not None:
                            record_frame(msg)
                        record = decode(msg)  # type: ignore[arg-type]  # a Message: blocks are above
                        if record is not None:
                            record = take(record)
                            if see_record is not None:
                                see_record(record)
                            if record.events:
                                emit(record.events)
                    now = clock()
                    if flushes and (msg is None or now >= next_flush):
                        for flush in flushes:
                            flush()
                        next_flush = now + flush_s
                    if now >= next_refresh:
                        show()
                        next_refresh = now + refresh_s
            except KeyboardInterrupt:
                completed = False
            finally:
                sys.setswitchinterval(switch_s)
            events = pipeline.finish()
            if events:
                emit(events)
            show()
            if isinstance(live, Live):
                live.refresh()
    return completed


def _fan_out(hooks: list[Callable[[_T], None]]) -> Callable[[_T], None] | None:
    """One callable for the hooks: None for none, the hook itself for one (the common case on
    the per-frame path), else a call of each in turn."""
    if not hooks:
        return None
    if len(hooks) == 1:
        return hooks[0]

    def each(item: _T) -> None:
        for hook in hooks:
            hook(item)

    return each
