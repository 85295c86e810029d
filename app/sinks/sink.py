"""The one seam between the run loop and what it feeds: a ``Sink``.

Like python-can's ``Listener``: a sink overrides what it needs of ``on_frame`` (every raw frame as
it arrives: the recorder), ``on_record`` (every decoded frame with what the pipeline made of it:
the channel trace), ``on_events`` (crossings and rejected sign changes as they happen: the event
printer, the events table), ``on_snapshot`` (the run as it stands, at the display's pace: the
dashboard, the progress bar), ``flush`` (every 50 ms and whenever the source is idle) and
``close`` (once at the end, whatever happened). The run loop calls only what a sink overrides,
so a sink that records nothing costs the per-frame path nothing.
"""

from collections.abc import Sequence

import can
from rich.console import Console, ConsoleOptions, RenderResult

from app.records import Event, Record
from app.snapshot import Snapshot


class Sink:
    def on_frame(self, msg: can.Message) -> None:
        """A raw frame as it arrived (not called for frames read in bulk)."""

    def on_record(self, record: Record) -> None:
        """A decoded frame with its estimate, steady-state verdict and events."""

    def on_events(self, events: Sequence[Event], t0: float) -> None:
        """New events; ``t0`` is the run's first frame time, which event times are shown from."""

    def on_snapshot(self, snapshot: Snapshot) -> None:
        """The run as it stands: every display refresh and once at the end."""

    def flush(self) -> None:
        """Hand what is buffered to the operating system."""

    def close(self) -> None:
        """The run is over (or failed): finish every file."""


def overrides(sink: Sink, hook: str) -> bool:
    """Whether ``sink`` does something on ``hook`` (its class, or the instance, replaces it)."""
    return hook in vars(sink) or getattr(type(sink), hook) is not getattr(Sink, hook)


class Display(Sink):
    """A sink that is also drawn (the dashboard, the progress bar): it renders the last snapshot
    it was given, as rich's ``__rich_console__`` (which knows the terminal's size) or ``__rich__``."""

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        raise NotImplementedError
