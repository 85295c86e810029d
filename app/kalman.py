"""The Kalman filter arithmetic behind the motion filter: three [value, rate] pairs, x = [u, u̇, v,
v̇, r, ṙ], and scalar measurements of u, v and r.

``PairKalman`` is written for that structure, in plain floats. The transition F is block-diagonal
with [[1, dt], [0, 1]] blocks, so F·P·Fᵀ is row and column additions; Q is the white-jerk block per
pair; every measurement row touches only u, v and r (``H = (h_u, h_v, h_r)``), and the noise is
diagonal, so a frame's rows are applied as scalar updates one after another — the same posterior as
a joint update, without a matrix inverse. On 6×6 matrices numpy's per-call cost is the whole cost
(tools/bench.py measures the kernel at several times filterpy's speed).

``FilterpyKalman`` does the same through filterpy's general ``KalmanFilter`` (joint update, Joseph
form): the reference the fast kernel is tested equal to within 1e-9 over whole drives.
"""

from collections.abc import Sequence
from typing import Protocol

import numpy as np
from filterpy.kalman import KalmanFilter

H = tuple[float, float, float]  # a measurement row's coefficients on u, v and r
Row = tuple[float, H, float]  # (z, H, R): one scalar measurement
_MEASURED = (0, 2, 4)  # where u, v and r sit in x


class Kalman(Protocol):
    def reset(self, x: Sequence[float], p_diagonal: Sequence[float]) -> None: ...

    def predict(self, dt: float) -> None: ...

    def innovation(self, z: float, h: H) -> tuple[float, float]:
        """(z − H·x, H·P·Hᵀ) at the current state."""
        ...

    def update(self, rows: Sequence[Row]) -> None: ...

    def value(self, i: int) -> float: ...

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        """Copies of x (6,) and P (6, 6)."""
        ...


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


class PairKalman:
    def __init__(self, q_u: float, q_v: float, q_r: float) -> None:
        self.q = (q_u, q_v, q_r)
        self.x = [0.0] * 6
        self.p = [[0.0] * 6 for _ in range(6)]

    def reset(self, x: Sequence[float], p_diagonal: Sequence[float]) -> None:
        self.x = [float(v) for v in x]
        self.p = [[float(p_diagonal[i]) if i == j else 0.0 for j in range(6)] for i in range(6)]

    def predict(self, dt: float) -> None:
        x, p = self.x, self.p
        for i in (0, 2, 4):
            x[i] += dt * x[i + 1]
            p[i] = [a + dt * b for a, b in zip(p[i], p[i + 1], strict=True)]  # F·P
        for row in p:  # (F·P)·Fᵀ
            row[0] += dt * row[1]
            row[2] += dt * row[3]
            row[4] += dt * row[5]
        cube, square = dt**3 / 3.0, dt * dt / 2.0
        for i, density in zip((0, 2, 4), self.q, strict=True):
            p[i][i] += density * cube
            p[i][i + 1] += density * square
            p[i + 1][i] += density * square
            p[i + 1][i + 1] += density * dt

    def innovation(self, z: float, h: H) -> tuple[float, float]:
        x, p = self.x, self.p
        hu, hv, hr = h
        pu, pv, pr = p[0], p[2], p[4]
        hph = (
            hu * (pu[0] * hu + pu[2] * hv + pu[4] * hr)
            + hv * (pv[0] * hu + pv[2] * hv + pv[4] * hr)
            + hr * (pr[0] * hu + pr[2] * hv + pr[4] * hr)
        )
        return z - (hu * x[0] + hv * x[2] + hr * x[4]), hph

    def update(self, rows: Sequence[Row]) -> None:
        x, p = self.x, self.p
        for z, (hu, hv, hr), r in rows:
            ph = [row[0] * hu + row[2] * hv + row[4] * hr for row in p]  # P·Hᵀ
            s = hu * ph[0] + hv * ph[2] + hr * ph[4] + r
            y = z - (hu * x[0] + hv * x[2] + hr * x[4])
            gain = [v / s for v in ph]
            for i, g in enumerate(gain):
                x[i] += g * y
                p[i] = [a - g * b for a, b in zip(p[i], ph, strict=True)]

    def value(self, i: int) -> float:
        return self.x[i]

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array(self.x), np.array(self.p)


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
