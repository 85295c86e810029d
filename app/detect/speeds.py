"""Do the optical sensor's speed and the car's vehicle speed agree in size?

A speed in the wrong unit (a DBC's km/h taken for mph, a ``[units]`` entry on the wrong role,
m/s taken for km/h) scales what the filter fuses: a vx read in mph gave C2n 23.40 [21.92, 25.09]
for 14.87, and the warnings blamed d and the filter's q_u. The two measure one thing (u is the
same at every point of the car's centre line), so their ratio shows it, within what physics and
regulation let a vehicle speed differ from the true one:

- the tyres' rolling radius within ±3 % of the nominal the car computes its speed with (8 mm of
  tread on a 310 mm radius is 2.6 %; pressure and load about 1 %);
- one wheel's speed, on the outside or the inside of the turn: half a track (0.3 wheelbases) on
  the tightest radius the steady gate takes (eight wheelbases), ±4 %;
- a speedometer's reading, where the bus carries the shown speed: up to 10 % + 4 km/h above the
  true speed, never below (UNECE Regulation No. 39, §5.3).

One vote per ``VOTE_EVERY_S`` of driving above the steady gate's least speed, each against the
band at its own speed; where most of at least ``MIN_VOTES`` fall outside (``AGAINST_SHARE``, as
the sign votes'), the run has no C2n (``Snapshot.sign_problem``), and the ratio's nearest unit
mistake is named.
"""

import math
from dataclasses import dataclass, field, replace

import numpy as np

from app.detect.signs import AGAINST_SHARE, MIN_VOTES, VOTE_EVERY_S

TYRE_RADIUS = 0.03  # rolling radius against the nominal: tread wear 2.6 %, pressure and load ~1 %
WHEEL_IN_TURN = 0.04  # half a track (0.3 wheelbases) over the tightest radius gated (8 wheelbases)
SPEEDO_OVER = 0.10  # UNECE R39 §5.3: a shown speed up to 10 % + 4 km/h above the true one
SPEEDO_PLUS_MPS = 4.0 / 3.6
_LOW = (1.0 - TYRE_RADIUS) * (1.0 - WHEEL_IN_TURN)
_HIGH = (1.0 + TYRE_RADIUS) * (1.0 + WHEEL_IN_TURN)
_BIN = 0.01  # the ratio's histogram: bins of 1 % in its logarithm, from 1/20 to 20
_SPAN = 3.0
_BINS = int(2 * _SPAN / _BIN)
_UNITS = {"m/s": 1.0, "km/h": 1.0 / 3.6, "mph": 0.44704}  # the speed units c2n reads (app/units.py)
_NEAR_UNIT = 0.05  # a ratio within 5 % of two units' is named as that mistake


def _bin(ratio: float) -> int:
    """The histogram's bin of one ratio (``add_many``'s, for one)."""
    return min(max(int((math.log(ratio) + _SPAN) / _BIN), 0), _BINS - 1) if ratio > 0.0 else 0


def band(speed_mps: float) -> tuple[float, float]:
    """The vehicle speed's ratio to the true speed that a tyre's radius, a wheel's place in the
    turn and a speedometer's tolerance allow at ``speed_mps``."""
    return _LOW, _HIGH * (1.0 + SPEEDO_OVER + SPEEDO_PLUS_MPS / speed_mps)


@dataclass(eq=False)
class SpeedVotes:
    """Votes of the vehicle speed against the optical vx, each inside or outside ``band``, and a
    histogram of their ratio (for its median). Callers offer a vote only from ``next_t`` on."""

    min_speed_mps: float = 4.0  # votes only from here (the steady gate's least speed)
    inside: int = 0
    outside: int = 0
    backwards: int = 0  # of the votes, those whose vehicle speed reads below zero, vx above
    ratios: np.ndarray = field(default_factory=lambda: np.zeros(_BINS, np.int64))
    next_t: float = -math.inf

    def add(self, t: float, speed: float, vx: float) -> None:
        """One vote at t: the latest vehicle speed and optical vx (NaN: none)."""
        self.next_t = (math.floor(t / VOTE_EVERY_S) + 1.0) * VOTE_EVERY_S  # the next slot, as add_block's
        u = abs(vx)
        if not (speed == speed and u >= self.least_mps):  # NaN compares False
            return
        ratio = abs(speed) / u  # as ``add_many`` does, without arrays: this runs in the live loop
        if speed < 0.0 < vx:
            self.backwards += 1
        if _LOW <= ratio <= _HIGH * (1.0 + SPEEDO_OVER + SPEEDO_PLUS_MPS / u):
            self.inside += 1
        else:
            self.outside += 1
        self.ratios[_bin(ratio)] += 1

    def add_block(self, t: np.ndarray, speed: np.ndarray, vx: np.ndarray) -> None:
        """Votes over a block's rows at times t, from ``next_t`` on, one per ``VOTE_EVERY_S``."""
        slots = np.floor(t / VOTE_EVERY_S)
        first = np.flatnonzero(np.r_[True, np.diff(slots) > 0] & (t >= self.next_t))
        if not len(first):
            return
        self.next_t = (float(slots[first[-1]]) + 1.0) * VOTE_EVERY_S
        u = np.abs(vx[first])
        keep = (u >= self.least_mps) & ~np.isnan(speed[first])
        self.backwards += int(np.count_nonzero(keep & (speed[first] < 0.0) & (vx[first] > 0.0)))
        self.add_many(np.abs(speed[first][keep]) / u[keep], u[keep])

    @property
    def least_mps(self) -> float:
        return max(self.min_speed_mps, 1.0)  # the speedometer's 4 km/h over u: from walking pace

    def add_many(self, ratio: np.ndarray, u: np.ndarray) -> None:
        """Votes of ``ratio`` (vehicle speed over optical vx) at speeds ``u``."""
        low, high = _LOW, _HIGH * (1.0 + SPEEDO_OVER + SPEEDO_PLUS_MPS / u)
        out = int(np.count_nonzero((ratio < low) | (ratio > high)))
        self.outside += out
        self.inside += len(ratio) - out
        with np.errstate(divide="ignore"):
            index = np.clip((np.log(ratio) + _SPAN) / _BIN, 0, _BINS - 1).astype(np.int64)
        np.add.at(self.ratios, index, 1)

    def median(self) -> float | None:
        """The votes' median ratio (to 1 %), or None without votes."""
        total = int(self.ratios.sum())
        if not total:
            return None
        k = int(np.searchsorted(np.cumsum(self.ratios), (total + 1) / 2))
        return math.exp((k + 0.5) * _BIN - _SPAN)

    def copy(self) -> "SpeedVotes":
        return replace(self, ratios=self.ratios.copy())

    def __eq__(self, other: object) -> bool:  # the histogram compared whole, not as an array's truth
        if not isinstance(other, SpeedVotes):
            return NotImplemented
        mine, theirs = vars(self).copy(), vars(other).copy()
        return bool(np.array_equal(mine.pop("ratios"), theirs.pop("ratios"))) and mine == theirs


def reads_off(votes: SpeedVotes) -> float | None:
    """The vehicle speed's median ratio to the optical vx where at least ``MIN_VOTES`` votes
    put it beyond a tyre's radius and a wheel's place in the turn (a speedometer's reading, or
    a scale off), for the filter's advice; None where it is within them."""
    ratio = votes.median()
    if votes.inside + votes.outside < MIN_VOTES or ratio is None or _LOW <= ratio <= _HIGH:
        return None
    return ratio


def speed_unit_problem(votes: SpeedVotes) -> str | None:
    """Why the run has no C2n where the vehicle speed and the optical vx disagree beyond what
    a tyre, a wheel's place and a speedometer allow, in most of at least ``MIN_VOTES`` votes;
    None where they agree, or the votes are too few."""
    votes_n = votes.inside + votes.outside
    ratio = votes.median()
    if votes_n < MIN_VOTES or votes.outside < AGAINST_SHARE * votes_n or ratio is None:
        return None
    low, high = band(votes.least_mps)
    share, seconds = 100.0 * votes.outside / votes_n, votes_n * VOTE_EVERY_S
    return (
        f"the vehicle speed reads {ratio:.2f} × the optical vx ({share:.0f} % of {seconds:.0f} s of driving "
        f"outside {low:.2f}–{high:.2f} × at {votes.least_mps:g} m/s, what a tyre's radius, a wheel's "
        f"place in the turn and a speedometer's tolerance allow){_unit_mistake(ratio)} — "
        "check the unit of the roles speed and vx (the DBC's, or [units] in the config)"
    )


def speed_backwards(votes: SpeedVotes, scale: float) -> str | None:
    """Why the run has no C2n where the vehicle speed reads below zero while the optical vx reads
    forwards, in most of at least ``MIN_VOTES`` votes: its sign is the wrong way round (a signed
    speed's DBC, or the role's ``scale``, the config's now). The filter rejects it, losing the car
    on it in the samples: C2n read 14.772 [14.577, 14.983] for 15.121 on a simulated drive. A car
    reversing reads both below zero, and a wheel speed reversing (unsigned) reads above: neither
    votes here. None where it does not."""
    votes_n = votes.inside + votes.outside
    if votes_n < MIN_VOTES or votes.backwards < AGAINST_SHARE * votes_n:
        return None
    share, seconds = 100.0 * votes.backwards / votes_n, votes_n * VOTE_EVERY_S
    return (
        f"the vehicle speed reads backwards while the optical vx reads forwards ({share:.0f} % of "
        f"{seconds:.0f} s of driving): its sign is the wrong way round — set [roles] speed's scale = "
        f"{-scale:g} (the filter rejects it, losing the car on it, and C2n with it)"
    )


def _unit_mistake(ratio: float) -> str:
    """The two units whose ratio ``ratio`` is nearest, within ``_NEAR_UNIT``: ": 1.61 is mph
    against km/h"; "" where none is."""
    near = [
        (abs(math.log(ratio * b / a)), f"{x} against {y}")
        for x, a in _UNITS.items()
        for y, b in _UNITS.items()
        if x != y
    ]
    off, words = min(near)
    return f": {ratio:.2f} is {words}" if off < math.log1p(_NEAR_UNIT) else ""
