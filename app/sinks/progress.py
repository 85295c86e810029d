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

from app.pipeline import Pipeline
from app.sources.logs import LogSource


class ReadProgress:
    """A renderable for the run loop's display: each redraw reads where the source is."""

    def __init__(self, pipeline: Pipeline, source: LogSource, name: str) -> None:
        self.pipeline = pipeline
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

    def __rich__(self) -> RenderableType:
        state = self.pipeline.state
        t0 = state.t_first or 0.0
        drive_s = (state.t_last or t0) - t0
        frames = self.pipeline.decoder.counts.total
        position = self.source.bytes_read()
        self._progress.update(
            self._task,
            completed=position if position is not None else 0,
            total=self.source.total_bytes if position is not None else None,
            status=f"{frames:,} frames, {drive_s:,.0f} s of drive, {len(state.crossings)} crossings",
        )
        return self._progress.get_renderable()
