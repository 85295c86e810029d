"""Bicycle model (paper Fig. 1) with linear or saturating axle tyres.

States v (lateral velocity at the CG) and r (yaw rate); the longitudinal speed u(t) is
prescribed by the manoeuvre. ISO 8855 signs; slip angles positive when they push left:
    α1 = δ − (v + a·r)/u,   α2 = −(v − b·r)/u
    m·(v̇ + u·r) = F1 + F2,  Iz·ṙ = a·F1 − b·F2
"""

import math
from dataclasses import dataclass
from typing import Literal

from app.config import Config
from app.errors import ConfigError
from app.paper import G

TyreModel = Literal["linear", "magic"]


class Axles:
    """Axle geometry and static loads of a model with ``mass_kg``, ``g``, ``a_m`` and ``b_m``."""

    mass_kg: float
    g: float
    a_m: float  # CG to front axle
    b_m: float  # CG to rear axle

    @property
    def wheelbase_m(self) -> float:
        return self.a_m + self.b_m

    @property
    def w1_n(self) -> float:
        return self.mass_kg * self.g * self.b_m / self.wheelbase_m

    @property
    def w2_n(self) -> float:
        return self.mass_kg * self.g * self.a_m / self.wheelbase_m


@dataclass(frozen=True)
class BicycleParams(Axles):
    mass_kg: float
    yaw_inertia_kgm2: float
    a_m: float  # CG to front axle
    b_m: float  # CG to rear axle
    c1_n_per_rad: float  # front axle cornering stiffness
    c2_n_per_rad: float  # rear axle cornering stiffness
    g: float = G
    tyre: TyreModel = "linear"
    mu: float = 1.0  # peak friction for the saturating tyre
    shape: float = 1.3  # Magic Formula C (lateral)
    curvature: float = -1.0  # Magic Formula E

    @property
    def c1n(self) -> float:
        return self.c1_n_per_rad / self.w1_n

    @property
    def c2n(self) -> float:
        """Normalised rear axle cornering stiffness C2/W2 (eq. 9): the truth the method measures."""
        return self.c2_n_per_rad / self.w2_n

    @property
    def understeer_rad_per_mps2(self) -> float:
        """K in δ = L/R + K·a_y (linear steady state)."""
        return (1.0 / self.c1n - 1.0 / self.c2n) / self.g

    @classmethod
    def from_axle_loads(
        cls,
        wheelbase_m: float,
        w1_n: float,
        w2_n: float,
        c1n: float,
        c2n: float,
        g: float = G,
        **tyre: float | str,
    ) -> "BicycleParams":
        mass = (w1_n + w2_n) / g
        a = wheelbase_m * w2_n / (w1_n + w2_n)
        b = wheelbase_m - a
        # radius of gyration² ≈ a·b, the usual estimate for a passenger car
        return cls(mass, mass * a * b, a, b, c1n * w1_n, c2n * w2_n, g, **tyre)  # type: ignore[arg-type]

    @classmethod
    def from_config(cls, config: Config, c2n: float | None = None, **tyre: float | str) -> "BicycleParams":
        v, t = config.vehicle, config.tyres
        needed = {
            "[vehicle] wheelbase_m": v.wheelbase_m,
            "[vehicle] front_axle_load_N": v.front_axle_load_N,
            "[vehicle] rear_axle_load_N": v.rear_axle_load_N,
            "[tyres] c1n_per_rad": t.c1n_per_rad,
            "[tyres] c2n_per_rad": t.c2n_per_rad if c2n is None else c2n,
        }
        missing = [k for k, value in needed.items() if value is None]
        if missing:
            raise ConfigError(f"{config.path}: the vehicle model needs {', '.join(missing)} — add them")
        for key, value in needed.items():
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{config.path}: the vehicle model needs {key} > 0, got {value}")
        return cls.from_axle_loads(
            float(v.wheelbase_m),  # type: ignore[arg-type]
            float(v.front_axle_load_N),  # type: ignore[arg-type]
            float(v.rear_axle_load_N),  # type: ignore[arg-type]
            float(t.c1n_per_rad),  # type: ignore[arg-type]
            float(c2n if c2n is not None else t.c2n_per_rad),  # type: ignore[arg-type]
            v.gravity_mps2,
            **tyre,
        )

    def axle_force(self, alpha: float, stiffness: float, load: float) -> float:
        if self.tyre == "linear":
            return stiffness * alpha
        # Magic Formula with B·C·D = cornering stiffness, so it is linear for small slip
        d = self.mu * load
        b = stiffness / (self.shape * d)
        x = b * alpha
        return d * math.sin(self.shape * math.atan(x - self.curvature * (x - math.atan(x))))

    def derivatives(self, u: float, v: float, r: float, delta: float) -> tuple[float, float]:
        """(v̇, ṙ) at speed u with road-wheel steer angle delta."""
        alpha1 = delta - (v + self.a_m * r) / u
        alpha2 = -(v - self.b_m * r) / u
        f1 = self.axle_force(alpha1, self.c1_n_per_rad, self.w1_n)
        f2 = self.axle_force(alpha2, self.c2_n_per_rad, self.w2_n)
        v_dot = (f1 * math.cos(delta) + f2) / self.mass_kg - u * r
        r_dot = (self.a_m * f1 * math.cos(delta) - self.b_m * f2) / self.yaw_inertia_kgm2
        return v_dot, r_dot

    def steady_steer(self, u: float, radius_m: float) -> float:
        """Road-wheel angle for steady cornering on a signed radius (linear tyres): L/R + K·u²/R."""
        return self.wheelbase_m / radius_m + self.understeer_rad_per_mps2 * u * u / radius_m

    def steady_state(self, u: float, delta: float) -> tuple[float, float]:
        """(v, r) in linear steady state for a road-wheel angle delta."""
        radius = (self.wheelbase_m + self.understeer_rad_per_mps2 * u * u) / delta
        r = u / radius
        alpha2 = u * r / (self.c2n * self.g)  # eq. 4
        return -u * alpha2 + self.b_m * r, r
