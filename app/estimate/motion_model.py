"""The motion filter's model, shared by the readable reference (``app.estimate.reference``) and
the compiled filter the pipeline runs (``app.estimate.compiled``).

State x = [u, u̇, v, v̇, r, ṙ] (ISO 8855): u the longitudinal velocity, v the lateral velocity at
the sensor's longitudinal position (d ahead of the rear axle) on the centre line, r the yaw rate.
Each pair is a continuous white-noise-jerk model, discretised for the time since the last frame,
so sensors at different rates update the same state as their frames arrive: the transition F is
block-diagonal with [[1, dt], [0, 1]] blocks and Q is the white-jerk block per pair (filterpy's
``Q_continuous_white_noise``).

Measurement models (y_s: sensor's lateral offset, + left), each a scalar row on u, v and r
(``H = (h_u, h_v, h_r)``):
    optical vx      = u − r·y_s                 (rigid body: the head sees the yaw's share)
    optical vy      = v
    optical angle β = atan2(v, u − r·y_s)       (linearised about the prior, as in an EKF; its
                                                innovation taken modulo 180°, so a head reading
                                                atan(vy/vx) and one reading atan2 agree reversing)
    vehicle speed   = u, or −u reversing where it reads ≥ 0 (weak: wheel-speed scale errors and
                      lags; a wheel speed is unsigned, |u|, on most cars)
    yaw rate        = r                         (or ay/u without a gyro)

The constants below tune both filters alike; numba compiles them in as they are.
"""

import math
from dataclasses import dataclass

import numpy as np

H = tuple[float, float, float]  # a measurement row's coefficients on u, v and r
Row = tuple[float, H, float]  # (z, H, R): one scalar measurement
MEASURED = (0, 2, 4)  # where u, v and r sit in x

LATE_TOLERANCE_S = 0.05  # frames up to this much out of order are applied at the current time
YAW_TIMEOUT_S = 0.5  # yaw information older than this leaves r unobserved
HEALTH_ALPHA = 0.02  # memory of the health figure: about 50 updates
MIN_SPEED_FOR_ANGLE = 1.0  # m/s: below this the angle says nothing about v
MAX_CONSECUTIVE_REJECTS = 3  # a sensor rejected this often in a row is right and the model wrong
NOISE_ALPHA = 0.002  # memory of the measured noise: about 500 optical frames
NOISE_CEILING = 5.0  # the measured noise may grow to this many times the configured σ


def angle_innovation(beta: float, h: float) -> float:
    """β − h taken into [−90°, 90°): reversing, the angle is about ±180° as atan2 reads it (and
    flips sign with the noise) but about 0° as atan(vy/vx) reads it (the S-Motion's ``Angle`` is
    ±45°): the two are one angle modulo 180°, and its slope on u and v is the same. The compiled
    filter writes the same arithmetic inline."""
    d = beta - h
    return d - math.pi * math.floor(d / math.pi + 0.5)


# the process noise that lets the filter follow what each sensor measures (``FilterCounts.lost``'s kinds)
FOLLOWS = {"vx": "q_u", "speed": "q_u", "lateral": "q_v", "yaw": "q_r"}


@dataclass
class FilterCounts:
    resets: int = 0
    time_jumps: int = 0  # timestamps that went backwards
    late_frames: int = 0
    outliers: int = 0  # measurements rejected by the innovation gate
    # Times the model lost the car, per sensor: a frame beyond the gate after MAX_CONSECUTIVE_REJECTS
    # of that sensor's frames were rejected running, and so believed. Under the filter's own noise
    # model a frame beyond the gate is a 1-in-2·10⁷ event (χ²₁ beyond 30), three running none at
    # all; a sensor's glitch is one frame. Each is the filter's state left behind by the car.
    lost_vx: int = 0
    lost_lateral: int = 0
    lost_speed: int = 0
    lost_yaw: int = 0

    @property
    def lost(self) -> dict[str, int]:
        """The sensors on which the model lost the car, and how often (those with none left out)."""
        counts = {
            "vx": self.lost_vx,
            "lateral": self.lost_lateral,
            "speed": self.lost_speed,
            "yaw": self.lost_yaw,
        }
        return {kind: n for kind, n in counts.items() if n}


def white_jerk(dt: float, q_u: float, q_v: float, q_r: float) -> np.ndarray:
    """Q over dt: q·[[dt³/3, dt²/2], [dt²/2, dt]] per pair (filterpy's Q_continuous_white_noise)."""
    q = np.zeros((6, 6))
    block = np.array([[dt**3 / 3.0, dt**2 / 2.0], [dt**2 / 2.0, dt]])
    for i, density in enumerate((q_u, q_v, q_r)):
        q[2 * i : 2 * i + 2, 2 * i : 2 * i + 2] = density * block
    return q


def transition(dt: float, q_u: float, q_v: float, q_r: float) -> tuple[np.ndarray, np.ndarray]:
    """F and Q for the three [value, rate] pairs over dt."""
    f = np.eye(6)
    f[0, 1] = f[2, 3] = f[4, 5] = dt
    return f, white_jerk(dt, q_u, q_v, q_r)


def full_row(h: H) -> np.ndarray:
    row = np.zeros(6)
    row[list(MEASURED)] = h
    return row
