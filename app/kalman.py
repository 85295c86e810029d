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
    """P is kept as a flat row-major list of 36 floats. The measurement update is written out
    term by term: it runs for every measurement of every optical frame, and spelled out it costs
    half what row-by-row list arithmetic does (tools/bench.py, the kernel figure)."""

    def __init__(self, q_u: float, q_v: float, q_r: float) -> None:
        self.q = (q_u, q_v, q_r)
        self.x = [0.0] * 6
        self.p = [0.0] * 36

    def reset(self, x: Sequence[float], p_diagonal: Sequence[float]) -> None:
        self.x = [float(v) for v in x]
        self.p = [float(p_diagonal[k // 6]) if k % 7 == 0 else 0.0 for k in range(36)]

    def predict(self, dt: float) -> None:
        """x = F·x, P = F·P·Fᵀ + Q, written out per 2×2 block of the pairs: a value's row and
        column gain dt × its rate's (the upper triangle, mirrored)."""
        x, p = self.x, self.p
        x[0] += dt * x[1]
        x[2] += dt * x[3]
        x[4] += dt * x[5]
        (
            p0, p1, p2, p3, p4, p5,
            _, p7, p8, p9, p10, p11,
            _, _, p14, p15, p16, p17,
            _, _, _, p21, p22, p23,
            _, _, _, _, p28, p29,
            _, _, _, _, _, p35,
        ) = p  # fmt: skip
        q_u, q_v, q_r = self.q
        cube, square = dt**3 / 3.0, dt * dt / 2.0
        n01 = p1 + dt * p7
        n00 = p0 + dt * p1 + dt * n01 + q_u * cube
        n01 += q_u * square
        n11 = p7 + q_u * dt
        n03 = p3 + dt * p9
        n02 = p2 + dt * p8 + dt * n03
        n12 = p8 + dt * p9
        n05 = p5 + dt * p11
        n04 = p4 + dt * p10 + dt * n05
        n14 = p10 + dt * p11
        n23 = p15 + dt * p21
        n22 = p14 + dt * p15 + dt * n23 + q_v * cube
        n23 += q_v * square
        n33 = p21 + q_v * dt
        n25 = p17 + dt * p23
        n24 = p16 + dt * p22 + dt * n25
        n34 = p22 + dt * p23
        n45 = p29 + dt * p35
        n44 = p28 + dt * p29 + dt * n45 + q_r * cube
        n45 += q_r * square
        n55 = p35 + q_r * dt
        p[:] = (
            n00, n01, n02, n03, n04, n05,
            n01, n11, n12, p9, n14, p11,
            n02, n12, n22, n23, n24, n25,
            n03, p9, n23, n33, n34, p23,
            n04, n14, n24, n34, n44, n45,
            n05, p11, n25, p23, n45, n55,
        )  # fmt: skip

    def innovation(self, z: float, h: H) -> tuple[float, float]:
        x, p = self.x, self.p
        hu, hv, hr = h
        hph = (
            hu * (p[0] * hu + p[2] * hv + p[4] * hr)
            + hv * (p[12] * hu + p[14] * hv + p[16] * hr)
            + hr * (p[24] * hu + p[26] * hv + p[28] * hr)
        )
        return z - (hu * x[0] + hv * x[2] + hr * x[4]), hph

    def update(self, rows: Sequence[Row]) -> None:
        """One scalar update per row: gain K = P·Hᵀ/S, x += K·y, P −= K·(P·Hᵀ)ᵀ (P stays
        symmetric, so the upper triangle is computed and mirrored)."""
        x, p = self.x, self.p
        for z, (hu, hv, hr), r in rows:
            (
                p0, _, p2, _, p4, _,
                p6, p7, p8, _, p10, _,
                p12, p13, p14, _, p16, _,
                p18, p19, p20, p21, p22, _,
                p24, p25, p26, p27, p28, _,
                p30, p31, p32, p33, p34, p35,
            ) = p  # fmt: skip
            h0 = p0 * hu + p2 * hv + p4 * hr  # P·Hᵀ
            h1 = p6 * hu + p8 * hv + p10 * hr
            h2 = p12 * hu + p14 * hv + p16 * hr
            h3 = p18 * hu + p20 * hv + p22 * hr
            h4 = p24 * hu + p26 * hv + p28 * hr
            h5 = p30 * hu + p32 * hv + p34 * hr
            s = hu * h0 + hv * h2 + hr * h4 + r
            y = z - (hu * x[0] + hv * x[2] + hr * x[4])
            k0, k1, k2, k3, k4, k5 = h0 / s, h1 / s, h2 / s, h3 / s, h4 / s, h5 / s
            x[0] += k0 * y
            x[1] += k1 * y
            x[2] += k2 * y
            x[3] += k3 * y
            x[4] += k4 * y
            x[5] += k5 * y
            a0, a1, a2, a3, a4, a5 = (
                p0 - k0 * h0,
                p6 - k0 * h1,
                p12 - k0 * h2,
                p18 - k0 * h3,
                p24 - k0 * h4,
                p30 - k0 * h5,
            )
            b1, b2, b3, b4, b5 = p7 - k1 * h1, p13 - k1 * h2, p19 - k1 * h3, p25 - k1 * h4, p31 - k1 * h5
            c2, c3, c4, c5 = p14 - k2 * h2, p20 - k2 * h3, p26 - k2 * h4, p32 - k2 * h5
            d3, d4, d5 = p21 - k3 * h3, p27 - k3 * h4, p33 - k3 * h5
            e4, e5 = p28 - k4 * h4, p34 - k4 * h5
            f5 = p35 - k5 * h5
            p[:] = (
                a0, a1, a2, a3, a4, a5,
                a1, b1, b2, b3, b4, b5,
                a2, b2, c2, c3, c4, c5,
                a3, b3, c3, d3, d4, d5,
                a4, b4, c4, d4, e4, e5,
                a5, b5, c5, d5, e5, f5,
            )  # fmt: skip

    def value(self, i: int) -> float:
        return self.x[i]

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        return np.array(self.x), np.array(self.p).reshape(6, 6)


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
