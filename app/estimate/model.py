"""The Kalman filter arithmetic behind the motion filter, on filterpy: three [value, rate] pairs,
x = [u, u̇, v, v̇, r, ṙ], and scalar measurements of u, v and r.

The transition F is block-diagonal with [[1, dt], [0, 1]] blocks and Q is the white-jerk block per
pair (filterpy's ``Q_continuous_white_noise``); each measurement row touches only u, v and r
(``H = (h_u, h_v, h_r)``). ``FilterpyKalman`` forms F, Q and H as matrices each step and updates
through filterpy's general ``KalmanFilter`` (joint update, Joseph form): the reference that
``app.estimate.compiled`` is tested equal to within 1e-9 over whole drives.
"""

from collections.abc import Sequence

import numpy as np
from filterpy.kalman import KalmanFilter

H = tuple[float, float, float]  # a measurement row's coefficients on u, v and r
Row = tuple[float, H, float]  # (z, H, R): one scalar measurement
_MEASURED = (0, 2, 4)  # where u, v and r sit in x


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
    row[list(_MEASURED)] = h
    return row


class FilterpyKalman:
    """The reference: filterpy's KalmanFilter, F, Q and H formed as matrices each step."""

    def __init__(self, q_u: float, q_v: float, q_r: float) -> None:
        self.q = (q_u, q_v, q_r)
        self.kf = KalmanFilter(dim_x=6, dim_z=1)

    def reset(self, x: Sequence[float], p_diagonal: Sequence[float]) -> None:
        self.kf.x = np.array(x, dtype=float).reshape(6, 1)
        self.kf.P = np.diag(np.asarray(p_diagonal, dtype=float))

    def predict(self, dt: float) -> None:
        f, q = transition(dt, *self.q)
        self.kf.predict(F=f, Q=q)

    def innovation(self, z: float, h: H) -> tuple[float, float]:
        row = full_row(h)
        return z - float(row @ self.kf.x[:, 0]), float(row @ self.kf.P @ row)

    def update(self, rows: Sequence[Row]) -> None:
        if rows:
            z = np.array([[row[0]] for row in rows])
            h = np.array([full_row(row[1]) for row in rows])
            self.kf.update(z, R=np.diag([row[2] for row in rows]), H=h)

    def value(self, i: int) -> float:
        return float(self.kf.x[i, 0])

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.kf.x[:, 0].copy(), self.kf.P.copy()
