"""Do the yaw rate, the lateral acceleration and the steering agree in sign while cornering?

A role the wrong way round in the config (`scale = -1` missing or extra) shows in the fit where
the speeds are apart: the sensor lands behind the rear axle (``Snapshot.sign_problem``). Where
they are not — circles at one speed, d held at the tape's value — a flipped yaw rate moves C2n
to 1/(g·(2d/u² − 1/(g·C2n))) and nothing in the sideslip shows it (circles at 1.25·u0: 55.7 for
14.9). The car's own sensors can: in a steady corner the lateral acceleration points into the
turn, as u·r does, and so does the steering wheel of a car that understeers. So the steady and
quasi-steady samples vote (one per ``VOTE_EVERY_S``), and the votes name the odd one out.
"""

import math
from dataclasses import dataclass, replace

MIN_AY_MPS2 = 1.0  # |u·r|: a corner, not a straight with a gyro's noise on it
MIN_STEER_RAD = 0.05  # |steering-wheel angle| (≈ 3°): beyond a steering offset
VOTE_EVERY_S = 0.1  # one sample votes per 0.1 s: a comparison per frame, not a call per steady frame
MIN_VOTES = 200  # votes (20 s of cornering) before they count
AGAINST_SHARE = 0.8  # of the votes against: a sign the wrong way round, not a noisy sensor


@dataclass
class SignVotes:
    """Cornering samples whose measured lateral acceleration and steering agree in sign with the
    yaw rate, and those against it (nothing counted where a role is missing). Callers offer a
    sample only from ``next_t`` on."""

    ay_with: int = 0
    ay_against: int = 0
    steer_with: int = 0
    steer_against: int = 0
    next_t: float = -math.inf

    def add(self, t: float, u: float, r: float, ay: float | None, steer: float | None) -> None:
        """One steady sample at t: filtered speed and yaw rate, the latest measured a_y and steering
        (None or NaN: none)."""
        self.next_t = t + VOTE_EVERY_S
        if abs(u * r) < MIN_AY_MPS2:
            return
        if ay is not None and ay == ay:  # NaN: none
            if (ay > 0) == (r > 0):
                self.ay_with += 1
            else:
                self.ay_against += 1
        if steer is not None and abs(steer) >= MIN_STEER_RAD:  # NaN compares False
            if (steer > 0) == (r > 0):
                self.steer_with += 1
            else:
                self.steer_against += 1

    def copy(self) -> "SignVotes":
        return replace(self)


def _against(against: int, with_: int) -> bool | None:
    """Do the votes say the sign is against the yaw rate's (True), with it (False), or nothing?"""
    votes = against + with_
    if votes < MIN_VOTES:
        return None
    if against >= AGAINST_SHARE * votes:
        return True
    return False if with_ >= AGAINST_SHARE * votes else None


def yaw_rate_flipped(votes: SignVotes) -> bool | None:
    """Is the yaw rate the wrong way round? True where it turns against the lateral acceleration
    and the steering does not side with it; False where it turns with a_y, or where the steering
    does (then a_y is the odd one out); None where the votes are too few or split. Without a_y
    (no role, or a_y giving the yaw rate itself) the steering alone says."""
    steer = _against(votes.steer_against, votes.steer_with)
    if not votes.ay_with + votes.ay_against:
        return steer
    ay = _against(votes.ay_against, votes.ay_with)
    if not ay:
        return ay
    return steer is not False


def _steer_against(votes: SignVotes) -> bool:
    return _against(votes.steer_against, votes.steer_with) is True


def _against_words(votes: SignVotes) -> str:
    """What the yaw rate turns against, and how often: "the lateral acceleration and the steering
    in 100 % of the cornering"."""
    if not votes.ay_with + votes.ay_against:
        share = 100.0 * votes.steer_against / max(votes.steer_against + votes.steer_with, 1)
        return f"the steering in {share:.0f} % of the cornering"
    share = 100.0 * votes.ay_against / (votes.ay_against + votes.ay_with)
    steering = " and the steering" if _steer_against(votes) else ""
    return f"the lateral acceleration{steering} in {share:.0f} % of the cornering"


def yaw_rate_problem(votes: SignVotes) -> str | None:
    """Where nothing in the fit shows the signs (d held: circles at one speed): why its C2n is no
    result, or None. a_y and the steering usually share one bus, and with it its axes, so both
    against the yaw rate may be either."""
    if not yaw_rate_flipped(votes):
        return None
    if not votes.ay_with + votes.ay_against:
        fix = (
            "one of the two is the wrong way round (no lateral acceleration to tell which) — check "
            "`scale` of the roles yaw_rate (or ay, where it gives the yaw rate; + turning left) and "
            "steer (+ to the left)"
        )
    elif _steer_against(votes):
        fix = (
            "the yaw rate is the wrong way round, or ay and steer both are (a vehicle bus in SAE axes, "
            "+ to the right) — check `scale` of the role yaw_rate (+ turning left), or of ay and steer "
            "(+ to the left)"
        )
    else:
        fix = (
            "one of the two is the wrong way round (no steering to tell which) — check `scale` of the "
            "roles yaw_rate (+ turning left) and ay (+ to the left)"
        )
    return f"the yaw rate turns against {_against_words(votes)}: {fix}"


def which_of_the_two(votes: SignVotes) -> str:
    """Where the fit puts the sensor behind the rear axle (the yaw rate and the sideslip disagree):
    which of the two the votes point at."""
    flipped = yaw_rate_flipped(votes)
    if flipped and _steer_against(votes):
        return (
            f"the yaw rate is the one (it turns against {_against_words(votes)}) — check `scale` of "
            "the role yaw_rate (+ turning left)"
        )
    if flipped:  # one flip explains it; two (a_y or the steering, and the sideslip) would too
        return (
            f"most likely the yaw rate (it turns against {_against_words(votes)}; else that role and "
            "vy/beta both are) — check `scale` of the role yaw_rate (+ turning left)"
        )
    if flipped is False and _odd_one(votes) is None:  # a_y, and the steering if any, with it
        return (
            "the sideslip is the wrong way round (the yaw rate turns with the lateral acceleration) — "
            "check `scale` of the roles vy and beta (+ to the left)"
        )
    return (
        "a role is the wrong way round — check `scale` of the roles yaw_rate (+ turning left) and "
        "vy/beta (+ to the left)"
    )


def odd_sign(votes: SignVotes, d_witnessed: bool) -> str | None:
    """A warning for a role the wrong way round that leaves C2n as it is: a_y or the steering
    against the other two, a_y that follows no sign; or, where the fit's own d shows the sideslip
    turning with the yaw rate, the yaw rate against a_y (the flips cancel, or do not enter C2n)."""
    odd = _odd_one(votes)
    if odd is None and d_witnessed and yaw_rate_flipped(votes):
        roles = "the role ay"
        if not votes.ay_with + votes.ay_against:
            roles = "the role steer"
        elif _steer_against(votes):
            roles = "ay and steer (a vehicle bus in SAE axes)"
        odd = (
            f"the yaw rate turns against {_against_words(votes)} while the sideslip turns with it (the "
            f"fit puts the sensor ahead of the axle), so C2n stands: {roles}, or both yaw_rate and "
            "vy/beta, are the wrong way round — check their `scale`"
        )
    return odd


def _odd_one(votes: SignVotes) -> str | None:
    """a_y or the steering against the other two, or a_y that follows no sign (a logger's
    accelerometer on another axis: a real CANedge drive's IMU agrees with u·r in 49 % of its
    corners)."""
    ay = _against(votes.ay_against, votes.ay_with)
    steer = _against(votes.steer_against, votes.steer_with)
    if ay and steer is False:
        return (
            "the lateral acceleration points out of the turn the yaw rate and the steering show: "
            "check `scale` of the role ay (+ to the left)"
        )
    votes_ay = votes.ay_with + votes.ay_against
    if ay is None and votes_ay >= MIN_VOTES:  # neither with it nor against: another axis?
        return (
            f"the lateral acceleration agrees in sign with the yaw rate in only "
            f"{100.0 * votes.ay_with / votes_ay:.0f} % of the cornering: is the role ay the car's lateral "
            "axis (a logger's accelerometer mounted turned)?"
        )
    if steer and ay is False:
        return (
            "the steering turns against the yaw rate and the lateral acceleration: check `scale` "
            "of the role steer (+ to the left) — or of yaw_rate and ay both, if one unit mounted "
            "upside down gives the two"
        )
    return None
