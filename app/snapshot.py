"""The run as it stands: what the sinks show and write, never the machine that made it.

``Pipeline.snapshot()`` takes one; the dashboard, the progress bar, the result line and the
summary read it. It is frozen and holds copies, so a sink can neither change the run nor see it
change under its feet.
"""

from collections.abc import Mapping
from dataclasses import dataclass, field

from app.decode.counts import FrameCounts
from app.detect.quasi_steady import NO_CORNERING, Cornering
from app.detect.signs import SignVotes, odd_sign
from app.detect.speeds import SpeedVotes, speed_backwards, speed_unit_problem
from app.estimate.motion_model import FOLLOWS, FilterCounts
from app.paper import crossing_speed
from app.records import Crossing, CrossingRejected, Direction, Record
from app.results.combine import Combined
from app.results.headline import Headline, Method
from app.results.pairing import Paired
from app.results.parts import Part
from app.results.refusal import (
    d_witnessed,
    drives_disagree,
    refusal,
    replay_hint,
    resting_fit,
    sign_problem,
    standing_headline,
    unbounded_fit,
    witness,
)
from app.results.regression import RegressionFit
from app.results.sideslip_profile import ProfileView
from app.results.support import unbounded_crossings, unsteady_crossings

_FITTED = (Method.REGRESSION, Method.QUASI_STEADY)  # headlines that are a regression's C2n


@dataclass(frozen=True, slots=True)
class Pending:
    """A sign change whose crossing is still being fitted."""

    direction: Direction | None
    t: float
    u_mps: float


@dataclass(frozen=True)
class FilterState:
    counts: FilterCounts
    health: float  # mean normalised innovation²: ≈ 1 when the noise model fits
    noise_sigma: Mapping[str, float]  # the learnt noise of each optical channel
    lost_in_samples: int = 0  # of counts' times it lost the car, those in a steady or quasi-steady sample


def lagged(state: FilterState, lowered: Mapping[str, str]) -> bool:
    """The filter lost the car in the samples C2n rests on, where the config lowered the process
    noise that follows the sensor it lost, or narrowed its gate (``lowered``:
    ``config.lowered_filter``): its estimates lag the car there by what the drive cannot tell
    (q_u = 1e-6 read 16–17 for 15.1) — no C2n, the setting named (``refusal``,
    ``advice.filter_lost``). At the defaults a loss in the samples (a sensor's glitch) is said
    beside the C2n."""
    lost = state.counts.lost
    knobs = {FOLLOWS[kind] for kind in lost} | {"innovation_gate"}
    return bool(state.lost_in_samples and lost and knobs & lowered.keys())


@dataclass(frozen=True)
class Snapshot:
    t_first: float | None
    t_last: float | None
    last: Record | None  # the last record with an estimate
    latest: Mapping[str, float]  # role -> last usable value
    sensor_problem: str | None  # why optical samples are being dropped, if they are
    crossings: tuple[Crossing, ...]
    rejections: tuple[CrossingRejected, ...]
    combined: Combined | None  # inverse-variance mean of the crossings
    paired: Paired | None  # crossings with misalignment and lag removed
    regression: RegressionFit | None  # every steady sample: the headline C2n
    pending: tuple[Pending, ...]
    frames: FrameCounts
    status: Mapping[str, float]  # the sensor status signals' latest values
    filter: FilterState
    message_names: Mapping[tuple[int, bool], str]  # (id, extended) -> the DBC's message name
    d_m: float
    g_mps2: float
    profile: ProfileView | None = None  # the steady samples' sideslip against speed, per direction
    quasi: RegressionFit | None = None  # every quasi-steady sample, while no sweep crossed zero
    quasi_drives: tuple[RegressionFit | None, ...] = ()  # drives pooled: each one's samples alone
    cornering: Cornering = NO_CORNERING  # seconds of cornering, by what the quasi-steady gate made of them
    signs: SignVotes = field(default_factory=SignVotes)  # do a_y and the steering turn with the yaw rate?
    speeds: SpeedVotes = field(default_factory=SpeedVotes)  # do the vehicle speed and vx agree in size?
    settle_s: float = 1.0  # the steady-state gate's settling time ([detector] settle_s)
    speed_min_mps: float = 4.0  # the gates' least speed ([detector] speed_min_mps)
    vx_scale: float = 1.0  # the config's vx scale, whose sign a drive read backwards turns
    speed_scale: float = 1.0  # the config's vehicle speed scale, likewise
    raised_noise: tuple[str, ...] = ()  # the config's [filter] process noises above their defaults, said
    lowered_filter: Mapping[str, str] = field(default_factory=dict)  # and those below (config.lowered_filter)
    # c2n live: the parts between the optical sensor's pauses, each alone (``app.pipeline.PartedPipeline``),
    # and why they give no one C2n where they disagree (``results.parts.parts_disagree``)
    parts: tuple[Part, ...] = ()
    parts_disagree: str | None = None

    @property
    def t0(self) -> float:
        """The first frame's time (0 before any): event times are shown from it."""
        return self.t_first or 0.0

    @property
    def elapsed_s(self) -> float:
        return (self.t_last or self.t0) - self.t0

    @property
    def headline(self) -> Headline | None:
        """The C2n to report, unless a refusal stands (``refusal.standing_headline``, or the run's
        parts disagree)."""
        if self.parts_disagree or self.filter_lagged:
            return None
        return standing_headline(
            self.sign_problem,
            self.drives_disagree,
            self.crossings_problem,
            self.fit,
            self.regression,
            self.quasi,
            self.paired,
            self.combined,
        )

    @property
    def fit(self) -> RegressionFit | None:
        """The regression the result rests on (``refusal.resting_fit``)."""
        return resting_fit(self.regression, self.quasi, bool(self.crossings))

    @property
    def refusal(self) -> str:
        """Why there is no C2n: a speed in the wrong unit (said before the filter's losing the car,
        which it causes), a wrong sign, or the manoeuvre the drive lacked (``refusal.refusal``)."""
        return self.unit_problem or refusal(
            self.sign_problem,
            self.parts_disagree or self.drives_disagree,
            self.crossings_problem,
            self.regression,
            self.cornering,
            unbounded_fit(self.fit),
            self.filter.lost_in_samples,
            self.vx_scale,
            self.speed_min_mps,
            self.raised_noise,
        )

    @property
    def crossings_problem(self) -> str | None:
        """Why the crossings give no C2n: their sweeps disagree, or they do not bound it
        (``support.unbounded_crossings``: said only where no regression stands for them)."""
        return self.unsteady_crossings or unbounded_crossings(self.paired, self.combined)

    @property
    def unsteady_crossings(self) -> str | None:
        """Why the crossings give no C2n: their sweeps disagree beyond any settled lag."""
        return unsteady_crossings(self.paired, self.settle_s)

    @property
    def drives_disagree(self) -> str | None:
        """Why drives pooled give no one C2n (``refusal.drives_disagree``)."""
        return drives_disagree(self.fit, self.quasi, self.quasi_drives)

    @property
    def sign_problem(self) -> str | None:
        """Why no C2n of the drive is a result: a speed in the wrong unit (``unit_problem``), or
        a role the wrong way round (``refusal.sign_problem``)."""
        return self.unit_problem or sign_problem(self.fit, self._witness, self.signs)

    @property
    def filter_lagged(self) -> bool:
        """The filter lagged the car where C2n is measured, by the config (``lagged``): no C2n."""
        return lagged(self.filter, self.lowered_filter)

    @property
    def unit_problem(self) -> str | None:
        """The vehicle speed and the optical vx apart beyond any tyre or speedometer: one of
        them in the wrong unit (``speeds.speed_unit_problem``); or the vehicle speed the wrong
        way round, which the filter rejects, losing the car in the samples
        (``speeds.speed_backwards``: 14.772 for 15.121 on a simulated drive)."""
        return speed_unit_problem(self.speeds) or speed_backwards(self.speeds, self.speed_scale)

    @property
    def _witness(self) -> RegressionFit | None:
        """The fit whose own d shows the roles' signs (``refusal.witness``)."""
        return witness(self.fit, self.regression, self.quasi)

    @property
    def d_witnessed(self) -> bool:
        """Do the samples place d themselves (``refusal.d_witnessed``)?"""
        return d_witnessed(self._witness)

    @property
    def odd_sign(self) -> str | None:
        """A role the wrong way round that leaves C2n as it is (``signs.odd_sign``), where no sign
        problem stands."""
        return None if self.sign_problem else odd_sign(self.signs, self.d_witnessed)

    @property
    def replay_hint(self) -> str | None:
        """Optical frames far faster than a sensor sends them (``refusal.replay_hint``)."""
        return replay_hint(self.elapsed_s, self.optical_frames)

    @property
    def optical_frames(self) -> int:
        """The most frames any optical role (vx, vy, beta) had."""
        return max((self.frames.role_frames[role] for role in ("vx", "vy", "beta")), default=0)

    @property
    def u0_mps(self) -> float | None:
        """The crossing speed the headline C2n stands for (paper eq. 7: u0 = √(C2n·g·d)), with the d
        it rests on: a fit's own (a sensor 1.5 m ahead where the config says 1.11: the sideslip
        changes sign at √(C2n·g·1.5), not at the config's speed), else the config's."""
        headline, fit = self.headline, self.fit
        on_fit = fit is not None and headline is not None and headline.method in _FITTED
        d_m = fit.d.m if on_fit and fit is not None else self.d_m
        if headline is None or headline.c2n * self.g_mps2 * d_m < 0:
            return None
        return crossing_speed(headline.c2n, d_m, self.g_mps2)
