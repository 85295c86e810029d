"""The progress bar of long offline runs (drawn only on a terminal): bytes of the files read,
frames, drive time and crossings so far."""

from rich.console import RenderableType
from rich.progress import (
    BarColumn,
    DownloadColumn,
    Progress,
    TaskProgressColumn,
    TextColumn,
    TimeRemainingColumn,
)

from app.sinks.sink import Display
from app.snapshot import Snapshot
from app.sources.logs import LogSource


class ReadProgress(Display):
    """The run loop's display for a run over files: each snapshot updates the bar from where the
    source is."""

    def __init__(self, source: LogSource, name: str) -> None:
        self.source = source
        self._progress = Progress(
            TextColumn("{task.description}"),
            BarColumn(),
            TaskProgressColumn(),
            DownloadColumn(),
            TimeRemainingColumn(),
            TextColumn("{task.fields[status]}"),
            auto_refresh=False,
        )
        self._task = self._progress.add_task(name, total=source.total_bytes or None, status="")

    def on_snapshot(self, snapshot: Snapshot) -> None:
        position = self.source.bytes_read()
        self._progress.update(
            self._task,
            completed=position if position is not None else 0,
            total=self.source.total_bytes if position is not None else None,
            status=f"{snapshot.frames.total:,} frames, {snapshot.elapsed_s:,.0f} s of drive, "
            f"{len(snapshot.crossings)} crossings",
        )

    def __rich__(self) -> RenderableType:
        return self._progress.get_renderable()
