"""``c2n live``'s pipeline: the one pipeline over the whole run, and each part between the optical
sensor's pauses alone beside it (``results/parts.py`` says why).

A pause is what ``c2n analyze`` calls one in a log (``sources/spacing.py``): no frame of the
optical sensor's messages for longer than ``gap_reset_s``, from its last frame before to its first
after. The pooled pipeline is the run as before, frame for frame. From the first pause on, the
frames go to one more pipeline, the current part's; the part before it keeps only its C2n as it
stood at the pause (the first part's is the pooled pipeline's then, which had seen it alone). So
the cost is the pooled run's until the sensor first pauses, and twice it after. A sign change
still being fitted when the sensor paused is not in its part's C2n (the pooled run's filter
restarts there too).

Frame by frame only: a bus gives no blocks (``take_block`` raises).
"""

from dataclasses import replace

from app.config import Config
from app.pipeline import Pipeline
from app.records import Event, Record
from app.results.log_clock import sensor_messages
from app.results.parts import Part, parts_disagree
from app.snapshot import Snapshot
from app.sources.blocks import RecordBlock


class PartedPipeline(Pipeline):
    def __init__(self, config: Config) -> None:
        super().__init__(config)
        self._sensor = frozenset(sensor_messages(config))  # the optical sensor's frame ids
        self._pause_s = config.filter.gap_reset_s
        self._seen: float | None = None  # the optical sensor's last frame time
        self._begin: float | None = None  # the current part's first frame time, from the first pause
        self._part: Pipeline | None = None  # the current part alone, from the first pause
        self._ended: list[Part] = []
        self._take_pooled = super().take  # bound once: ``take`` runs for every frame

    def take(self, record: Record) -> Record:
        if record.frame_id in self._sensor:
            seen = self._seen
            if seen is not None and record.t - seen > self._pause_s:
                self._end_part(seen, record.t)
            self._seen = record.t
        if self._part is not None:
            self._part.take(record)
        return self._take_pooled(record)

    def take_block(self, block: RecordBlock) -> list[Event]:
        raise TypeError("PartedPipeline takes frames one by one (c2n live): a bus gives no blocks")

    def _end_part(self, last_t: float, next_t: float) -> None:
        """The sensor paused from ``last_t`` to ``next_t``: the current part ends with its C2n as
        it stands, and a new one begins."""
        if self._part is None:  # the first part: the pooled pipeline has seen it alone
            begin, headline = self.state.t_first, super().snapshot().headline
        else:
            begin, headline = self._begin, self._part.snapshot().headline
        self._ended.append(Part(begin if begin is not None else last_t, last_t, headline))
        self._part, self._begin = Pipeline(self.config), next_t

    def finish(self) -> list[Event]:
        events = super().finish()
        if self._part is not None:
            self._part.finish()
        return events

    def snapshot(self, first_stage: Snapshot | None = None) -> Snapshot:
        pooled = super().snapshot(first_stage)
        if self._part is None or self._begin is None:
            return pooled
        end = self._seen if self._seen is not None else self._begin
        parts = (*self._ended, Part(self._begin, end, self._part.snapshot().headline))
        return replace(pooled, parts=parts, parts_disagree=parts_disagree(parts, pooled.t0))
