"""The run as it stands: what the sinks show and write, never the machine that made it.

``Pipeline.snapshot()`` takes one; the dashboard, the progress bar, the result line and the
summary read it. It is frozen and holds copies, so a sink can neither change the run nor see it
change under its feet.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

from app.decode.counts import FrameCounts
from app.detect.quasi_steady import NO_CORNERING, Cornering
from app.detect.signs import SignVotes, odd_sign, which_of_the_two, yaw_rate_problem
from app.estimate.model import FilterCounts
from app.records import Crossing, CrossingRejected, Direction, Record
from app.results.agreement import DriveResult, disagreement
from app.results.combine import Combined
from app.results.headline import Headline, headline, positive
from app.results.pairing import Paired
from app.results.regression import RegressionFit
from app.results.sideslip_profile import ProfileView
from app.results.support import unsteady_crossings

_SENSOR_MAX_HZ = 400.0  # an optical sensor sends at 50–250 Hz; far beyond that is not its own pace
_HINT_AFTER_S = 2.0  # of frame time: a burst at the start is no rate


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
    settle_s: float = 1.0  # the steady-state gate's settling time ([detector] settle_s)

    @property
    def t0(self) -> float:
        """The first frame's time (0 before any): event times are shown from it."""
        return self.t_first or 0.0

    @property
    def elapsed_s(self) -> float:
        return (self.t_last or self.t0) - self.t0

    @property
    def headline(self) -> Headline | None:
        """The C2n to report (``headline.py``: by what the drive held), unless a refusal stands: a
        role's sign the wrong way round (``sign_problem``), pooled drives that disagree, or — with
        no fit to rest on — crossings whose sweeps disagree."""
        if self.sign_problem:
            return None
        fit = self.fit
        quasi = fit if fit is not None and fit is self.quasi else None  # no sweep crossed zero
        if (quasi is not None and self.drives_disagree) or (fit is None and self.unsteady_crossings):
            return None
        return headline(None if quasi else self.regression, quasi, self.paired, self.combined)

    @property
    def fit(self) -> RegressionFit | None:
        """The regression the result rests on: the steady samples', or where no sweep crossed
        zero, the quasi-steady samples'. Without a sweep the car's speed and yaw rate were never
        held for the method's own measurement, and samples that passed the steady gate still carry
        slow transients (corners taken braking gently: C2n 0.5–1.1 % low on four simulated track
        days, the truth outside each interval; −0.06 to −0.41 % and inside with the quasi-steady
        model's terms)."""
        if self.quasi is None or self.crossings:
            return self.regression
        return self.quasi

    @property
    def refusal(self) -> str:
        """Why there is no C2n: a wrong sign, or the manoeuvre the drive lacked."""
        if self.sign_problem:
            return self.sign_problem
        if self.drives_disagree:
            return self.drives_disagree
        if self.unsteady_crossings and (self.regression is None or not positive(self.regression.c2n)):
            return self.unsteady_crossings
        c = self.cornering
        if c.turning_s < 1.0:
            return (
                "no cornering in the drive: drive steady circles at 2–4 m/s² with the speed swept "
                "slowly through the sign change"
            )
        tight = f"{c.tight_s:.0f} s on radii under eight wheelbases, " if c.tight_s >= 0.5 else ""
        return (
            f"no sideslip sign change and too little quasi-steady cornering: of {c.turning_s:.0f} s "
            f"cornering, {c.ay_high_s:.0f} s beyond the tyres' linear range of a_y, {c.transient_s:.0f} s "
            f"speed or steering changing too fast, {tight}{c.usable_s:.0f} s quasi-steady — drive steady "
            "circles at 2–4 m/s² with the speed swept slowly through the sign change, or corners held "
            "at 1–4 m/s² at several speeds"
        )

    @property
    def unsteady_crossings(self) -> str | None:
        """Why the crossings give no C2n: their sweeps disagree beyond any settled lag."""
        return unsteady_crossings(self.paired, self.settle_s)

    @property
    def drives_disagree(self) -> str | None:
        """Why drives pooled give no one C2n: drives each alone whose C2n differ beyond their errors
        (each pair's z, Holm's step-down at 95 % over all pairs: ``agreement.py``, as analyze checks
        drives before pooling them) — not one car on one set of tyres, whose C2n a pooled fit would
        bend its terms to split."""
        if self.fit is None or self.fit is not self.quasi:
            return None
        alone = [(k, f) for k, f in enumerate(self.quasi_drives, 1) if f is not None and positive(f.c2n)]
        if disagreement([DriveResult(f"drive {k}", f.c2n, f.c2n_ci95) for k, f in alone]) is None:
            return None
        each = "; ".join(
            f"drive {k} {f.c2n:.3f} [{f.c2n_ci95[0]:.3f}, {f.c2n_ci95[1]:.3f}]" for k, f in alone
        )
        return (
            f"the drives pooled disagree, each alone: {each} — not one car on one set of tyres "
            "(a tyre change, pressures, temperatures?): analyse them apart"
        )

    @property
    def sign_problem(self) -> str | None:
        """Why the regression's C2n is not a result, when it is not positive. A role the wrong way
        round (the yaw rate, or the sideslip) turns both of β = ψ0 + d·κ − a_y/(g·C2n)'s terms
        over: the fit then puts the sensor behind the rear axle and C2n below zero; the car's a_y
        and steering (``signs``) say which of the two it is. Where d is held (circles at one
        speed), nothing in the fit shows a flipped yaw rate: the votes alone do."""
        fit = self.fit
        if fit is None:
            return None
        d, where = fit.d.m, f"{-fit.d.m:.2f} m behind the rear axle and C2n at {fit.c2n:.2f}"
        witness = self._witness
        assert witness is not None  # there is a fit
        if witness.estimator == "marginal" and not self.d_witnessed:  # d is the tape's prior's: the
            problem = yaw_rate_problem(self.signs)  # votes alone show the signs, as where d is held
            if problem is not None or positive(fit.c2n):
                return problem
            d = 0.0
        elif witness.d.free_m is not None and witness.d.free_m < 0:
            d, where = witness.d.free_m, f"at least {-witness.d.free_m:.2f} m behind the rear axle"
        elif not witness.d.held and witness.d.m < 0:
            d, where = witness.d.m, f"{-witness.d.m:.2f} m behind the rear axle"
        if positive(fit.c2n) and d >= 0:  # no d of the samples' own (one speed): the votes show the signs
            return None if self.d_witnessed else yaw_rate_problem(self.signs)
        if d < 0:
            return (
                f"the sideslip and the yaw rate disagree in sign (the regression puts the sensor "
                f"{where}): {which_of_the_two(self.signs)}"
            )
        return (
            f"the regression's C2n is {fit.c2n:.2f}, not positive: the steady samples do not show the "
            "sideslip falling with speed on a circle — not a result"
        )

    @property
    def _witness(self) -> RegressionFit | None:
        """The fit whose own d shows the roles' signs (d held at the tape's hides them): the steady
        samples' where there are any (the quasi-steady ones' transitions can place d anywhere:
        circles at one speed, 4 m behind), else the result's."""
        fit = self.fit
        return self.regression if fit is self.quasi and self.regression is not None else fit

    @property
    def d_witnessed(self) -> bool:
        """Do the samples place d themselves (speeds apart: ``DResult.free_m`` where d is held)?"""
        witness = self._witness
        if witness is None:
            return False
        if witness.estimator == "marginal":  # d under the tape's prior: the samples' own, if any
            return witness.d.free_m is not None
        return not witness.d.held or witness.d.free_m is not None

    @property
    def odd_sign(self) -> str | None:
        """A role the wrong way round that leaves C2n as it is: a_y or the steering against the
        other two; or the yaw rate against both where the sideslip turns with it (the fit's d
        ahead of the axle: the two flips cancel in C2n)."""
        return None if self.sign_problem else odd_sign(self.signs, self.d_witnessed)

    @property
    def replay_hint(self) -> str | None:
        """Optical frames far faster than a sensor sends them: a drive replayed faster than it was
        driven and taken at arrival time, so every sweep looks that much too fast to use."""
        elapsed = self.elapsed_s
        frames = max((self.frames.role_frames[role] for role in ("vx", "vy", "beta")), default=0)
        if elapsed < _HINT_AFTER_S or frames / elapsed <= _SENSOR_MAX_HZ:
            return None
        return (
            f"optical frames arrive at {frames / elapsed:.0f} Hz, faster than a sensor sends them "
            f"(≤ {_SENSOR_MAX_HZ:g} Hz): a replay faster than it was driven? Its sweeps look that much "
            "too fast to use: give c2n live the replay's rate (--rate)"
        )

    @property
    def u0_mps(self) -> float | None:
        """The crossing speed the headline C2n stands for (paper eq. 7: u0 = √(C2n·g·d))."""
        headline = self.headline
        if headline is None or headline.c2n * self.g_mps2 * self.d_m < 0:
            return None
        return math.sqrt(headline.c2n * self.g_mps2 * self.d_m)
