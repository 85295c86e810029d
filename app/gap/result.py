"""The gap diagnosis in typed form: what ``c2n gap --json`` writes, its fields the file's keys
(docs/gap.md), its numbers rounded as the file holds them. The report and the
command line read it; ``to_json`` gives the file's content."""

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from app.output.files import json_ready
from app.sim.effects import EffectName


@dataclass(frozen=True)
class Calibrated:
    """A nuisance: the config's value, the drive's, its 95 % interval, whether the fit ended on
    the nuisance's physical bound (then the number is not to be trusted), and why it was held at
    its nominal value if it was."""

    nominal: float
    fitted: float
    ci95: tuple[float, float]
    at_bound: bool = False
    held: str | None = None


@dataclass(frozen=True)
class Located:
    """One slice of the drive: its share of the squared sideslip residual (of the calibrated
    model) against its share of the samples."""

    where: str
    share: float
    samples_share: float
    concentration: float
    mean_deg: float
    rms_deg: float


@dataclass(frozen=True)
class CandidateScore:
    """One effect fitted (with the nuisances) on some manoeuvres and scored on the others: the
    held-out sideslip and yaw-rate gaps of the calibrated model before and after."""

    effect: EffectName
    params: Mapping[str, float]
    at_bound: tuple[str, ...]  # parameters whose fit ended on a physical bound
    heldout_rms_before: float  # sideslip gap, deg
    heldout_rms_after: float
    heldout_yaw_rms_before: float  # yaw-rate gap, deg/s
    heldout_yaw_rms_after: float
    shrink_heldout: float  # 1 − after/before of the sideslip gap
    named: bool  # it passes every test a diagnosis must
    why_not: str | None  # the test it failed, when it is not named


@dataclass(frozen=True)
class Secondary:
    """An effect that shrinks the held-out gap further once added to the dominant one."""

    effect: EffectName
    params: Mapping[str, float]
    shrink_heldout: float  # of what the dominant effect left
    action: str


@dataclass(frozen=True)
class GapC2n:
    """C2n: the config's nominal value, the calibrated model's, the method's reading of the
    nominal model, of the measurement, of the model with the effect, of the measurement with the
    effect taken out, and the pipeline's headline."""

    nominal: float | None
    calibrated: float | None
    sim: float | None
    measured: float | None
    after: float | None
    corrected: float | None
    pipeline: float | None


@dataclass(frozen=True)
class BeforeAfter:
    before: float
    after: float


@dataclass(frozen=True)
class GapNoise:
    sideslip_deg: float  # white sensor noise per grid step
    yaw_rate_degps: float
    sideslip_gap_deg: float  # what the held-out gap estimate can tell apart ("beyond noise")


@dataclass(frozen=True)
class C2nEffect:
    """What an effect does to C2n read from zero crossings, %: a single crossing's (the worse
    turn direction), and the headline's (left and right paired); None where the drive has no
    steady turning near a crossing's speed."""

    crossing: float | None
    headline: float | None


@dataclass(frozen=True)
class Effect:
    """One effect the drive holds: its size and 95 % interval (fitted beside the nuisances), the
    held-out gap of its own channel without and with it, how far the held-out test puts its gain
    above the drive's own spread (a normal quantile), what it does to C2n, and whether that is
    beyond the config's tolerance (``matters``) or within it."""

    effect: EffectName
    channel: str  # "sideslip" (at the sensor), "speed" (the vehicle speed signal), "c2n" (the axle's)
    params: Mapping[str, float]
    ci95: Mapping[str, tuple[float, float]]
    shrink_heldout: float  # of its own channel's held-out gap
    heldout_before: float | None  # that gap, deg (sideslip) or m/s (speed); None: not a held-out fit
    heldout_after: float | None
    gain_sigmas: float  # the held-out gain over its standard error (manoeuvres as samples), or the
    # estimate's distance from nothing in standard errors where the method measured it
    c2n_effect_pct: C2nEffect
    matters: bool
    judged: str  # why it matters, or "within tolerance" and of what
    confounded_with: tuple[str, ...]  # effects the drive cannot tell from it
    action: str  # what its size means and what to do
    measured_by: str = "held-out fit"  # or "the C2n regression", "the headline against the tyre rig's C2n"


@dataclass(frozen=True)
class GapResult:
    diagnosis: str  # an effect, "none", or "unexplained"
    confounded_with: tuple[str, ...]
    secondary: tuple[Secondary, ...]
    calibration: Mapping[str, Calibrated]
    located: tuple[Located, ...]
    candidates: tuple[CandidateScore, ...]
    c2n: GapC2n
    shrink_heldout: float  # of the gap the dominant effect was named by
    shrink_heldout_with_secondary: float  # the sideslip gap's, the first secondary effect added
    heldout_rms_deg: BeforeAfter  # the calibrated model's held-out sideslip gap, and with the effect
    heldout_yaw_rms_degps: BeforeAfter
    verdict: str  # the diagnosis in a sentence: what was found and why
    action: str | None  # what the named effect's size means and what to do
    separate_by: Mapping[str, str]
    noise: GapNoise
    manoeuvres: int
    speed_input: str
    effects: tuple[Effect, ...] = ()  # every effect present, the one that matters most first
    tolerances: Mapping[str, float] | None = None  # the config's [gap] tolerances judged against

    def to_json(self) -> dict[str, Any]:
        """The file's content: JSON types only, in the file's key order."""
        return dict(json_ready(self))
