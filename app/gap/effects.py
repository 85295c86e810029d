"""Every effect a drive holds, each in its own channel, sized, and judged against the config's
tolerances — decided in the data's own units.

**Present.** An effect is present when adding it shrinks the held-out gap of its own channel
(the sideslip at the sensor; the vehicle speed signal for a speed scale or a late bus) beyond
what the drive's own spread allows: the held-out gap is split by manoeuvre, each manoeuvre's
share compared with and without the effect, and the mean gain must stand ``Z_TEST`` standard
errors above zero (a one-sided test at ``CONFIDENCE``, shared among the candidates). The
manoeuvres carry the model's own misfit — the floor a bicycle model leaves on a real car — so
that floor, not a constant, is what an effect must beat. A sideslip effect is tested on the steady
samples (every effect of the vocabulary that moves the sideslip acts in steady state, while the
transients carry what a bicycle model lacks: the tyres' relaxation, the body's roll); the speed
signal's on every sample (a late bus shows where the speed changes). It may not make the
channels' held-out gap together (weighed as the fit weighs them) worse by the same test, and its
fit must end inside its physical bounds.

**Matters.** A present effect is a finding when what it does exceeds a tolerance of the config's
``[gap]`` section: C2n moved by more than ``c2n_pct`` on a single crossing or on the headline
(left and right crossings paired), or its own size beyond its channel's tolerance (the sideslip
sensor's angle accuracy, the tape's d, the speed signal's scale, a bus's age). Below, it is
"within tolerance", reported with its size.

**Together.** The effect that matters most leads; each other effect that matters is added to it
and kept as a finding only where it shrinks, held out, what the leader left (the same test):
else the drive cannot tell it from the leader, and it is reported as confounded.
"""

import math
from collections.abc import Mapping
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np

from app.config import Config
from app.gap.measured import Measured
from app.sim.effects import EffectName

CONFIDENCE = 0.95  # the one statistical constant: intervals cover this much, a test errs 1 − it
Z_INTERVAL = float(NormalDist().inv_cdf(0.5 + CONFIDENCE / 2))  # two-sided: a 95 % interval is ±1.96 σ
TESTS = 8  # the candidate effects each drive is tested for (the vocabulary but "none")
# one-sided, the error shared among the candidates tested (Bonferroni): a drive with nothing
# wrong names a spurious effect in at most 1 − CONFIDENCE of drives, not in 1 − CONFIDENCE of
# every candidate's tests (eight of them would name one in a third of clean drives)
Z_TEST = float(NormalDist().inv_cdf(1.0 - (1.0 - CONFIDENCE) / TESTS))  # 2.50 σ

SPEED_CHANNEL = frozenset({"speed_scale_error", "signal_latency"})


def channel(effect: EffectName) -> str:
    """The channel an effect shows in first: the vehicle speed signal, or the sideslip."""
    return "speed" if effect in SPEED_CHANNEL else "sideslip"


def own_size(effect: EffectName, params: Mapping[str, float], config: Config) -> tuple[float, float] | None:
    """An effect's size in its own unit and the config's tolerance for it, where one is stated."""
    gap = config.gap
    sizes = {
        "sensor_yaw_misalignment": ("misalignment_deg", gap.sideslip_deg),
        "tyre_ply_steer": ("ply_steer_deg", gap.sideslip_deg),
        "sensor_position_error": ("d_error_m", config.calibration.d_tolerance_mm / 1000.0),
        "speed_scale_error": ("speed_scale_pct", gap.speed_pct),
        "signal_latency": ("latency_s", gap.latency_s),
    }
    if effect not in sizes:
        return None
    name, tolerance = sizes[effect]
    return abs(float(params[name])), tolerance


MIN_UNITS = 10  # the fewest samples a gain's standard error is taken from: with ten, Student's t
# at 95 % is within 15 % of the normal's 1.96


def test_units(ids: np.ndarray) -> np.ndarray:
    """The held-out test's samples: the manoeuvres, each cut into equal consecutive pieces where a
    drive has fewer than ``MIN_UNITS`` of them (a single long circle)."""
    units = np.unique(ids)
    if len(units) >= MIN_UNITS:
        return ids
    pieces = -(-MIN_UNITS // len(units))  # ceil
    out = np.zeros(len(ids), dtype=np.int64)
    for k, unit in enumerate(units):
        rows = np.flatnonzero(ids == unit)
        out[rows] = k * pieces + (np.arange(len(rows)) * pieces) // max(len(rows), 1)
    return out


def unit_gaps(t: np.ndarray, residual: np.ndarray, rows: np.ndarray, ids: np.ndarray) -> np.ndarray:
    """Each manoeuvre's share of the squared gap: its 1-s blocks' sums squared over their counts
    (the white noise adds the same to every fit compared, so it cancels in a difference)."""
    units = np.unique(ids)
    out = np.zeros(len(units))
    if not rows.any():
        return out
    unit = np.searchsorted(units, ids[rows])
    block = np.floor(t[rows]).astype(np.int64)
    key = unit.astype(np.int64) * (int(block.max()) + 1) + block
    keys, inverse = np.unique(key, return_inverse=True)
    sums = np.bincount(inverse, residual[rows])
    counts = np.bincount(inverse)
    np.add.at(out, keys // (int(block.max()) + 1), sums**2 / counts)
    return out


def gain_z(before: np.ndarray, after: np.ndarray) -> float:
    """How many standard errors the held-out gain (before − after, per manoeuvre) stands above
    zero; manoeuvres without held-out samples do not count."""
    seen = (before > 0) | (after > 0)
    d = (before - after)[seen]
    if len(d) < 3:
        return 0.0
    se = float(np.std(d, ddof=1)) / math.sqrt(len(d))
    mean = float(np.mean(d))
    if se <= 0.0:
        return math.copysign(math.inf, mean) if mean else 0.0
    return mean / se


MIN_CROSSING_S = 2.0  # of steady turning near a crossing per direction: a manoeuvre's least


def near_crossings(m: Measured, rows: np.ndarray, d_m: float, c2n: float, g: float) -> np.ndarray:
    """The steady turning samples near a crossing's speed (u² from half to one and a half times
    g·d·C2n): where the zero-crossing method reads C2n."""
    u, r = np.nan_to_num(m.u_optical), np.nan_to_num(m.r)
    turning = rows & m.steady & (u > 0) & (np.abs(r) > 1e-3)
    return np.asarray(turning & (np.abs(u * u / (g * d_m * c2n) - 1.0) <= 0.5))


@dataclass(frozen=True)
class C2nShift:
    crossing: float | None  # % on a single crossing (the worse turn direction), None: no crossing
    headline: float | None  # % on the headline (left and right crossings paired)


def c2n_shift(m: Measured, rows: np.ndarray, delta: np.ndarray, d_m: float, c2n: float, g: float) -> C2nShift:
    """What a sideslip ``delta`` (rad, what the effect adds to the sensor's reading) does to C2n
    read from zero crossings. A crossing on radius R is where d/R − u²/(R·g·C2n) + Δ = 0, so it
    reads C2n·(1 + R·Δ/d): evaluated on the steady turning samples near the crossing's speed
    (u² from half to one and a half times g·d·C2n), per turn direction; a single crossing is the
    worse direction's RMS, the headline the two directions' mean (pairing cancels an offset)."""
    u, r = np.nan_to_num(m.u_optical), np.nan_to_num(m.r)
    near = near_crossings(m, rows, d_m, c2n, g)
    per_side = []
    for side in (1.0, -1.0):
        inside = near & (np.sign(r) == side)
        if inside.sum() * m.dt < MIN_CROSSING_S:
            continue
        shift = 100.0 * delta[inside] * (u[inside] / r[inside]) / d_m
        per_side.append((float(np.mean(shift)), float(np.sqrt(np.mean(shift**2)))))
    if not per_side:
        return C2nShift(None, None)
    mean, rms = max(per_side, key=lambda s: s[1])
    crossing = math.copysign(rms, mean)
    headline = float(np.mean([s[0] for s in per_side])) if len(per_side) == 2 else crossing
    return C2nShift(round(crossing, 3), round(headline, 3))


def importance(shift: C2nShift, size: tuple[float, float] | None, config: Config) -> float:
    """The largest of what the effect does over what the config tolerates: ≥ 1 matters."""
    ratios = [abs(x) / config.gap.c2n_pct for x in (shift.crossing, shift.headline) if x is not None]
    if size is not None and size[1] > 0:
        ratios.append(size[0] / size[1])
    return max(ratios, default=0.0)
