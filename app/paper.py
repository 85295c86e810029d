"""The paper's closed forms (Tuononen, Lehtonen, Juhala, FISITA 2006, F2006V122).

These are the oracle the tests check every stage against.
"""

import math

G = 9.81  # the paper's g (eq. 10 gives 14.99 with it)
DEG_PER_RAD = 57.3  # the paper's rounding of 180/π in eqs. 1 and 8


def rear_slip_angle(ay_mps2: float, c2n_per_rad: float, g: float = G) -> float:
    """Eq. 4: rear axle slip angle α2 = a_y / (C2n·g) [rad]."""
    return ay_mps2 / (c2n_per_rad * g)


def sideslip_at_sensor(u_mps: float, radius_m: float, d_m: float, c2n_per_rad: float, g: float = G) -> float:
    """Eq. 6: steady-state sideslip d metres ahead of the rear axle, β_d = d/R − u²/(R·g·C2n)."""
    return d_m / radius_m - u_mps**2 / (radius_m * g * c2n_per_rad)


def c2n_from_crossing(u0_mps: float, d_m: float, g: float = G) -> float:
    """Eq. 7: C2n = u0²/(g·d) [1/rad]."""
    return u0_mps**2 / (g * d_m)


def crossing_speed(c2n_per_rad: float, d_m: float, g: float = G) -> float:
    """Eq. 10 (first): u0 = √(C2n·g·d), where the sideslip at the sensor changes sign."""
    return math.sqrt(c2n_per_rad * g * d_m)


def zero_sideslip_speed_at_cg(c_r_n_per_deg: float, w_r_n: float, c_m: float, g: float = G) -> float:
    """Eq. 1: v = √(57.3·g·c·C_r/W_r), sideslip zero at the centre of gravity (C_r in N/deg)."""
    return math.sqrt(DEG_PER_RAD * g * c_m * c_r_n_per_deg / w_r_n)


def normalised_stiffness(c2_n_per_rad: float, w2_n: float) -> float:
    """Eq. 9: C2n = C2/W2."""
    return c2_n_per_rad / w2_n
