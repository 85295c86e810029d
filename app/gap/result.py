"""The gap diagnosis in typed form: what ``c2n gap --json`` writes, its fields the file's keys
(README, "The sim-to-real gap"), its numbers rounded as the file holds them. The report and the
command line read it; ``to_json`` gives the file's content."""

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from app.sinks.files import json_ready


@dataclass(frozen=True)
class Located:
    """One slice of the drive: its share of the squared sideslip residual against its share of
    the samples."""

    where: str
    share: float
    samples_share: float
    concentration: float
    mean_deg: float
    rms_deg: float


@dataclass(frozen=True)
class CandidateScore:
    """One effect fitted on some manoeuvres and scored on the others."""

    effect: str
    params: Mapping[str, float]
    heldout_rms_before: float
    heldout_rms_after: float
    heldout_cost_before: float
    heldout_cost_after: float
    improvement: float


@dataclass(frozen=True)
class GapC2n:
    """C2n as the method reads it from the nominal model, the measurement and the model with the
    effect; the config's nominal value and the pipeline's headline beside them."""

    nominal: float | None
    sim: float | None
    measured: float | None
    after: float | None
    pipeline: float | None


@dataclass(frozen=True)
class BeforeAfter:
    before: float
    after: float


@dataclass(frozen=True)
class GapNoise:
    sideslip_deg: float
    yaw_rate_degps: float


@dataclass(frozen=True)
class GapResult:
    diagnosis: str
    confounded_with: tuple[str, ...]
    separate_by: Mapping[str, str]
    located: tuple[Located, ...]
    candidates: tuple[CandidateScore, ...]
    c2n: GapC2n
    shrink_heldout: float
    heldout_rms_deg: BeforeAfter
    noise: GapNoise
    manoeuvres: int
    speed_input: str

    def to_json(self) -> dict[str, Any]:
        """The file's content: JSON types only, in the file's key order."""
        return dict(json_ready(self))
