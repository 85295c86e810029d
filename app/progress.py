"""A one-line progress display for long offline runs (drawn only on a terminal)."""

from rich.console import RenderableType
from rich.spinner import Spinner

from app.pipeline import Pipeline


class ReadProgress:
    def __init__(self, pipeline: Pipeline, name: str) -> None:
        self.pipeline = pipeline
        self.name = name
        self._spinner = Spinner("dots")

    def __rich__(self) -> RenderableType:
        state = self.pipeline.state
        t0 = state.t_first or 0.0
        drive_s = (state.t_last or t0) - t0
        frames = self.pipeline.decoder.counts.total
        self._spinner.text = (
            f"{self.name}: {frames:,} frames, {drive_s:,.0f} s of drive, {len(state.crossings)} crossings"
        )
        return self._spinner
