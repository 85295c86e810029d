"""Offline: the Kalman filter forward, then filterpy's Rauch–Tung–Striebel smoother backward.

Live runs can only filter (each estimate uses the past); a recorded drive can also use the
future, which removes the filter's lag and most of its noise. The smoother serves offline plots
and exports and the filter-quality bench; `c2n analyze` keeps the filtered estimates so that its
numbers stay identical to a live run's.

Memory stays bounded: each stretch of driving is smoothed in chunks that overlap by a few
seconds (far longer than the filter's memory), and each chunk's overlap is dropped.
"""

from collections.abc import Iterable
from dataclasses import dataclass

import can
import numpy as np
from filterpy.kalman import rts_smoother

from app.config import Config
from app.decode.decoder import Decoder
from app.estimate.compiled import CompiledMotionFilter

_FILTER_ROLES = frozenset({"vx", "vy", "beta", "speed", "yaw_rate", "ay"})
_EPSILON = 1e-12  # keeps P invertible for states nothing observes (r without a yaw rate)


@dataclass(frozen=True)
class Track:
    """One uninterrupted stretch of filtering. States x = [u, u̇, v, v̇, r, ṙ] per step."""

    t: np.ndarray
    filtered: np.ndarray  # (n, 6)
    smoothed: np.ndarray  # (n, 6)

    def sideslip(self, smoothed: bool = True) -> np.ndarray:
        states = self.smoothed if smoothed else self.filtered
        return np.asarray(np.arctan2(states[:, 2], states[:, 0]))


def smooth(
    config: Config, messages: Iterable[can.Message], chunk: int = 20_000, overlap: int = 1_000
) -> list[Track]:
    """Filter and smooth a drive; one Track per stretch between filter restarts."""
    decoder = Decoder(config)
    motion = CompiledMotionFilter(
        config.filter,
        config.vehicle.sensor_lateral_m,
        frozenset(config.roles),
        {role: spec.resolution for role, spec in config.roles.items()},
    )
    tracks: list[Track] = []
    t: list[float] = []
    xs: list[np.ndarray] = []
    ps: list[np.ndarray] = []
    fs: list[np.ndarray] = []  # fs[k]: the transition from step k to k + 1
    qs: list[np.ndarray] = []
    for message in messages:
        record = decoder.decode(message)
        if record is None or _FILTER_ROLES.isdisjoint(record.signals):
            continue
        resets = motion.counts.resets
        if motion.step(record) is None:
            continue
        if motion.counts.resets != resets or not t:
            tracks += _smooth_stretch(t, xs, ps, fs, qs, chunk, overlap)
            t, xs, ps, fs, qs = [], [], [], [], []
        else:
            fs.append(motion.last_transition[0])
            qs.append(motion.last_transition[1] + _EPSILON * np.eye(6))
        t.append(record.t)
        x, p = motion.state()
        xs.append(x)
        ps.append(p + _EPSILON * np.eye(6))
    tracks += _smooth_stretch(t, xs, ps, fs, qs, chunk, overlap)
    return tracks


def _smooth_stretch(
    t: list[float],
    xs: list[np.ndarray],
    ps: list[np.ndarray],
    fs: list[np.ndarray],
    qs: list[np.ndarray],
    chunk: int,
    overlap: int,
) -> list[Track]:
    if len(t) < 2:
        return []
    n = len(t)
    x, p = np.array(xs), np.array(ps)
    f, q = np.array([*fs, np.eye(6)]), np.array([*qs, np.zeros((6, 6))])  # the last step has no successor
    smoothed = np.empty_like(x)
    start = 0
    while start < n:
        end = min(start + chunk, n)
        stop = min(end + overlap, n)  # smooth a little further than kept: the future that matters
        part, _, _, _ = rts_smoother(x[start:stop], p[start:stop], f[start:stop], q[start:stop])
        smoothed[start:end] = part[: end - start]
        start = end
    return [Track(np.array(t), x, smoothed)]
