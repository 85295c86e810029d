"""A higher-fidelity vehicle model: planar two-track with roll, load transfer and tyre lag.

The simulator's reference for the sim-to-real gap: it has what the bicycle model leaves out, and
each unmodelled effect (app/sim/effects.py) that lives in the vehicle or the road is a parameter here
(zero by default). ISO 8855 throughout: x forward, y left, z up; roll φ > 0 when the body leans
to the right (the outside of a left turn); slip angles positive when they push the tyre left.

States: lateral velocity v and yaw rate r of the body frame (at the CG's x, on the roll axis),
roll angle φ and roll rate p, heading ψ (for the road's cross slope), and the four lateral tyre
forces (first-order relaxation). The longitudinal speed u(t) is prescribed by the manoeuvre.

    m·(v̇ + u·r) − m·h'·φ̈ = ΣFy + m·g_y                       (lateral, whole car)
    I_O·φ̈ − m·h'·(v̇ + u·r) = −m·h'·g_y + m·g_n·h'·φ − K_φ·φ − D_φ·p   (roll about the roll axis)
    I_z·ṙ = ΣM_z,   ψ̇ = r,   σ/u·Ḟ_i + F_i = F_i,ss(α_i, F_z,i)

with h' the CG's height above the roll axis, I_O = I_x,CG + m·h'², g_y and g_n the road-plane
lateral and normal components of gravity. All the mass rolls (no unsprung mass).

Wheel loads: static share, longitudinal transfer m·f_x·h/L (f_x the longitudinal specific force,
u̇ minus the slope's component), and per axle i the lateral transfer

    ΔF_z,i = (K_φi·φ + D_φi·p + F_y,i·h_rc,i) / t_i        (springs + roll-centre share)

(the outer wheel gains it). Tyres: Magic Formula per wheel, F = μ·F_z·sin(C·atan(x − E·(x − atan x))),
x = B·α, with the cornering stiffness B·C·D = c_i·F_z·(1 − k·(F_z − F_z0)/F_z0): c_i is the axle's
normalised stiffness (C1n, C2n), F_z0 the static wheel load and k the load sensitivity. With k = 0
each wheel's force is F_z·f(α), so an axle gives exactly W_i·f(α) whatever the load transfer: in
steady state at small lateral acceleration the model is the bicycle model (vehicle_model.py)
with C1 = C1n·W1 and C2 = C2n·W2, and with its "magic" tyre (same μ, C, E) at any level.
"""

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from app.config import Config
from app.paper import G
from app.sim.drive import _KI, _KP, _MAX_STEER_RATE, DriveTrace, _speed_profile, _steer_commands
from app.sim.scenarios import Scenario
from app.sim.vehicle_model import Axles, BicycleParams

# Defaults where the config has no value; typical of a mid-size front-drive saloon (Mondeo Mk3).
DEFAULT_CG_HEIGHT_M = 0.55
DEFAULT_TRACK_M = 1.50
DEFAULT_ROLL_GRADIENT_DEG_PER_G = 4.5  # body roll per g of lateral specific force, steady state
DEFAULT_ROLL_STIFFNESS_FRONT_SHARE = 0.6  # front anti-roll bar: the usual understeer bias
DEFAULT_ROLL_CENTRE_FRONT_M = 0.08  # MacPherson front
DEFAULT_ROLL_CENTRE_REAR_M = 0.12  # multi-link rear
DEFAULT_ROLL_DAMPING_RATIO = 0.4
DEFAULT_ROLL_GYRATION_M = 0.6  # radius of gyration about the CG's x axis
DEFAULT_RELAXATION_LENGTH_M = 0.5

WHEELS = ("FL", "FR", "RL", "RR")


@dataclass(frozen=True)
class TwoTrackParams(Axles):
    """The car, its tyres, and the vehicle/road effects (all zero: none of them)."""

    mass_kg: float
    yaw_inertia_kgm2: float
    a_m: float  # CG to front axle
    b_m: float  # CG to rear axle
    c1n: float  # front axle normalised cornering stiffness C1/W1 [1/rad], small slip, static load
    c2n: float  # rear axle C2/W2 [1/rad]: the truth the method measures
    cg_height_m: float = DEFAULT_CG_HEIGHT_M
    track_front_m: float = DEFAULT_TRACK_M
    track_rear_m: float = DEFAULT_TRACK_M
    roll_centre_front_m: float = DEFAULT_ROLL_CENTRE_FRONT_M
    roll_centre_rear_m: float = DEFAULT_ROLL_CENTRE_REAR_M
    roll_gradient_deg_per_g: float = DEFAULT_ROLL_GRADIENT_DEG_PER_G
    roll_stiffness_front_share: float = DEFAULT_ROLL_STIFFNESS_FRONT_SHARE
    roll_damping_ratio: float = DEFAULT_ROLL_DAMPING_RATIO
    roll_gyration_m: float = DEFAULT_ROLL_GYRATION_M
    relaxation_length_m: float = DEFAULT_RELAXATION_LENGTH_M
    mu: float = 1.0  # peak friction (Magic Formula D = μ·F_z)
    shape: float = 1.3  # Magic Formula C, as BicycleParams
    curvature: float = -1.0  # Magic Formula E, as BicycleParams
    g: float = G
    # effects (effects.py sets them; zero is "off")
    load_sensitivity: float = 0.0  # k in C(F_z) = c·F_z·(1 − k·(F_z − F_z0)/F_z0)
    roll_steer: float = 0.0  # ε: rear axle steer δ2 = ε·φ [rad/rad]; > 0 roll understeer
    rear_ply_steer_rad: float = 0.0  # slip-angle offset of both rear tyres; > 0 pushes the rear left
    cross_slope_grade: float = 0.0  # tan θ of the road plane's tilt
    slope_downhill_rad: float = -math.pi / 2  # world direction the road falls to (heading 0 = start)

    @classmethod
    def from_config(
        cls, config: Config, c2n: float | None = None, c1n: float | None = None
    ) -> "TwoTrackParams":
        """The config's car; config values where it has them, the documented defaults elsewhere."""
        bicycle = BicycleParams.from_config(config, c2n)
        vehicle = config.vehicle
        track = vehicle.track_m or DEFAULT_TRACK_M
        return cls(
            mass_kg=bicycle.mass_kg,
            yaw_inertia_kgm2=bicycle.yaw_inertia_kgm2,
            a_m=bicycle.a_m,
            b_m=bicycle.b_m,
            c1n=float(config.tyres.c1n_per_rad) if c1n is None else c1n,  # type: ignore[arg-type]
            c2n=float(config.tyres.c2n_per_rad) if c2n is None else c2n,  # type: ignore[arg-type]
            cg_height_m=vehicle.cg_height_m or DEFAULT_CG_HEIGHT_M,
            track_front_m=track,
            track_rear_m=track,
            g=bicycle.g,
        )

    @property
    def roll_axis_height_m(self) -> float:
        """Height of the roll axis below the CG (interpolated between the roll centres)."""
        return self.roll_axis_height_at(0.0)

    def roll_axis_height_at(self, x_m: float) -> float:
        """Roll-axis height x metres ahead of the CG."""
        f = (x_m + self.b_m) / self.wheelbase_m  # 0 at the rear axle, 1 at the front
        return self.roll_centre_rear_m + f * (self.roll_centre_front_m - self.roll_centre_rear_m)

    @property
    def roll_arm_m(self) -> float:
        """h': CG above the roll axis."""
        return self.cg_height_m - self.roll_axis_height_m

    @property
    def roll_gradient_rad_per_mps2(self) -> float:
        """Steady roll per lateral specific force: φ = G_φ·f_y."""
        return math.radians(self.roll_gradient_deg_per_g) / self.g

    @property
    def roll_stiffness_nm_per_rad(self) -> float:
        """Total K_φ that gives the roll gradient: K_φ − m·g·h' = m·h'/G_φ."""
        m, h = self.mass_kg, self.roll_arm_m
        return m * h / self.roll_gradient_rad_per_mps2 + m * self.g * h

    @property
    def roll_inertia_kgm2(self) -> float:
        """I_O: about the roll axis."""
        return self.mass_kg * (self.roll_gyration_m**2 + self.roll_arm_m**2)

    @property
    def roll_damping_nms_per_rad(self) -> float:
        k_eff = self.roll_stiffness_nm_per_rad - self.mass_kg * self.g * self.roll_arm_m
        return 2.0 * self.roll_damping_ratio * math.sqrt(k_eff * self.roll_inertia_kgm2)

    @property
    def cross_slope_rad(self) -> float:
        return math.atan(self.cross_slope_grade)

    def bicycle(self) -> BicycleParams:
        """The linear bicycle model with the same mass, geometry and axle stiffnesses."""
        return BicycleParams(
            self.mass_kg,
            self.yaw_inertia_kgm2,
            self.a_m,
            self.b_m,
            self.c1n * self.w1_n,
            self.c2n * self.w2_n,
            self.g,
        )

    def nominal(self) -> "TwoTrackParams":
        """The same car with every effect off."""
        return replace(
            self, load_sensitivity=0.0, roll_steer=0.0, rear_ply_steer_rad=0.0, cross_slope_grade=0.0
        )

    # closed forms (steady state, small slip) the tests check the integration against
    def rear_load_transfer_n(self, ay_mps2: float) -> float:
        """Steady lateral load transfer of the rear axle at lateral acceleration ay (flat road)."""
        k2 = (1.0 - self.roll_stiffness_front_share) * self.roll_stiffness_nm_per_rad
        phi = self.roll_gradient_rad_per_mps2 * ay_mps2
        f2 = self.mass_kg * ay_mps2 * self.a_m / self.wheelbase_m
        return (k2 * phi + f2 * self.roll_centre_rear_m) / self.track_rear_m

    def rear_stiffness_ratio(self, ay_mps2: float) -> float:
        """C2n(ay)/C2n(0) from load sensitivity alone: the wheels' stiffnesses at F_z0 ± ΔF sum to
        c·(2·F_z0 − 2·k·ΔF²/F_z0), i.e. 1 − k·(ΔF/F_z0)² (the Magic Formula's own softening apart)."""
        ratio = self.rear_load_transfer_n(ay_mps2) / (0.5 * self.w2_n)
        return 1.0 - self.load_sensitivity * ratio * ratio

    @property
    def understeer_rad_per_mps2(self) -> float:
        """K in δ = L/R + K·a_y, including roll steer: the rear steers ε·G_φ·a_y."""
        return (1.0 / self.c1n - 1.0 / self.c2n) / self.g + self.roll_steer * self.roll_gradient_rad_per_mps2


@dataclass(frozen=True)
class TwoTrackTrace(DriveTrace):
    """The motion at each step; ``params`` is the equivalent bicycle model, ``v`` is at the CG's x
    on the roll axis, ``ay`` = v̇ + u·r (kinematic); what a body-fixed accelerometer reads (roll,
    road slope) is ``ay_accelerometer``."""

    two_track: TwoTrackParams
    roll: np.ndarray  # φ [rad], > 0 leaning right
    roll_rate: np.ndarray  # p [rad/s]
    heading: np.ndarray  # ψ [rad] from the start
    x_m: np.ndarray  # position in the road plane, x along the starting heading
    y_m: np.ndarray
    delta_rear: np.ndarray  # rear road-wheel steer (roll steer)
    ay_accelerometer: np.ndarray  # lateral specific force in the rolled body frame
    ax_accelerometer: np.ndarray
    wheel_load_n: np.ndarray  # (n, 4): FL, FR, RL, RR
    tyre_force_n: np.ndarray  # (n, 4): lateral, in wheel axes

    def lateral_velocity_at(self, x_m: float, height_m: float | None = None) -> np.ndarray:
        """Lateral velocity of the body point x metres ahead of the CG; at ``height_m`` above the
        ground it includes the roll rate's share −p·(height − roll-axis height)."""
        lateral = self.v + self.r * x_m
        if height_m is None:
            return lateral
        return lateral - self.roll_rate * (height_m - self.two_track.roll_axis_height_at(x_m))


def simulate_two_track(
    params: TwoTrackParams, scenario: Scenario, steering_ratio: float, dt: float = 0.002
) -> TwoTrackTrace:
    """Integrate through a manoeuvre (RK4, fixed step) with the driver of drive.py: it holds a
    radius (PI on the path curvature r/u around the nominal bicycle model's steady steer), a fixed
    steering-wheel angle, or a straight line (the same PI around zero curvature, so a crabbing or
    slope-pushed car is held straight as a test driver would)."""
    n = round(scenario.duration_s / dt) + 1
    t = np.arange(n) * dt
    u, u_dot = _speed_profile(scenario, t)
    if np.any(u <= 0.5):
        raise ValueError("the two-track model needs a speed above 0.5 m/s throughout")
    kinds, values = _steer_commands(scenario, t)
    segment = np.concatenate([[0], np.cumsum((np.diff(kinds) != 0) | (np.diff(values) != 0))])
    derivative = _dynamics(params)
    driver = params.nominal().bicycle()
    length = params.wheelbase_m
    columns = [np.empty(n) for _ in range(21)]
    state = [0.0] * 9  # v, r, φ, p, ψ, F_FL, F_FR, F_RL, F_RR
    delta = integral = 0.0
    u_list, ud_list = u.tolist(), u_dot.tolist()
    kind_list, value_list, segment_list = kinds.tolist(), values.tolist(), segment.tolist()
    step = _MAX_STEER_RATE * dt
    h2, h6 = 0.5 * dt, dt / 6.0
    for k in range(n):
        uk, udk = u_list[k], ud_list[k]
        if k > 0 and segment_list[k] != segment_list[k - 1]:
            integral = 0.0  # a new command: the driver starts afresh
        kind = kind_list[k]
        if kind == 2:  # a fixed steering-wheel angle
            target = value_list[k] / steering_ratio
        else:
            curvature = 1.0 / value_list[k] if kind == 1 else 0.0
            error = curvature - state[1] / uk
            integral += _KI * length * error * dt
            feedforward = driver.steady_steer(uk, 1.0 / curvature) if kind == 1 else 0.0
            target = feedforward + _KP * length * error + integral
        delta += min(max(target - delta, -step), step)
        out = derivative(uk, udk, delta, state, True)
        columns[0][k] = delta
        for i in range(20):
            columns[i + 1][k] = out[i] if i >= 9 else state[i]
        if k == n - 1:
            break
        # RK4 with the steer held over the step and the speed ramping with the manoeuvre
        u_mid, u_end = uk + 0.5 * dt * udk, u_list[k + 1]
        k1 = out[:9]
        k2 = derivative(u_mid, udk, delta, [x + h2 * d for x, d in zip(state, k1, strict=True)], False)
        k3 = derivative(u_mid, udk, delta, [x + h2 * d for x, d in zip(state, k2, strict=True)], False)
        k4 = derivative(u_end, udk, delta, [x + dt * d for x, d in zip(state, k3, strict=True)], False)
        state = [
            x + h6 * (a + 2.0 * b + 2.0 * c + d) for x, a, b, c, d in zip(state, k1, k2, k3, k4, strict=True)
        ]
    delta_out = columns[0]
    v, r, phi, p, psi = columns[1:6]
    forces = np.column_stack(columns[6:10])
    v_dot, ay_acc, ax_acc, delta_rear = columns[10], columns[15], columns[16], columns[17]
    loads = np.column_stack(columns[11:15])
    # columns 18–20 (φ̈ and the slope's gravity components) are not kept
    x_pos, y_pos = _path(t, u, v, psi)
    return TwoTrackTrace(
        params=params.bicycle(),
        t=t,
        u=u,
        u_dot=u_dot,
        v=v,
        r=r,
        delta=delta_out,
        ay=v_dot + u * r,
        two_track=params,
        roll=phi,
        roll_rate=p,
        heading=psi,
        x_m=x_pos,
        y_m=y_pos,
        delta_rear=delta_rear,
        ay_accelerometer=ay_acc,
        ax_accelerometer=ax_acc,
        wheel_load_n=loads,
        tyre_force_n=forces,
    )


def _path(t: np.ndarray, u: np.ndarray, v: np.ndarray, psi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position in the road plane by the trapezoidal rule."""
    vx = u * np.cos(psi) - v * np.sin(psi)
    vy = u * np.sin(psi) + v * np.cos(psi)
    dt = np.diff(t)
    x = np.concatenate([[0.0], np.cumsum(0.5 * (vx[1:] + vx[:-1]) * dt)])
    y = np.concatenate([[0.0], np.cumsum(0.5 * (vy[1:] + vy[:-1]) * dt)])
    return x, y


_Derivative = Callable[[float, float, float, list[float], bool], tuple[float, ...]]


def _dynamics(p: TwoTrackParams) -> _Derivative:
    """The right-hand side as a closure over the constants (scalar maths: 4 wheels are too few
    for numpy to pay). Returns (state derivatives…) or, with ``full``, 11 outputs more:
    v̇, the four wheel loads, ay_accelerometer, ax_accelerometer, δ_rear, φ̈, g_y, g_x."""
    sin, cos, atan = math.sin, math.cos, math.atan
    m, g = p.mass_kg, p.g
    a, b, length = p.a_m, p.b_m, p.wheelbase_m
    half1, half2 = 0.5 * p.track_front_m, 0.5 * p.track_rear_m
    t1, t2 = p.track_front_m, p.track_rear_m
    h_cg, h1, h2, arm = p.cg_height_m, p.roll_centre_front_m, p.roll_centre_rear_m, p.roll_arm_m
    k_roll, d_roll = p.roll_stiffness_nm_per_rad, p.roll_damping_nms_per_rad
    share = p.roll_stiffness_front_share
    k1, k2, d1, d2 = share * k_roll, (1 - share) * k_roll, share * d_roll, (1 - share) * d_roll
    inertia_o, iz = p.roll_inertia_kgm2, p.yaw_inertia_kgm2
    det = m * inertia_o - (m * arm) ** 2
    theta = p.cross_slope_rad
    g_plane, g_normal = g * sin(theta), g * cos(theta)
    downhill = p.slope_downhill_rad
    fz01, fz02 = 0.5 * p.w1_n * cos(theta), 0.5 * p.w2_n * cos(theta)
    mu, shape_c, curv_e = p.mu, p.shape, p.curvature
    sens = p.load_sensitivity
    # B = c·(1 − k·(F_z − F_z0)/F_z0)/(C·μ): the F_z of B·C·D cancels against D = μ·F_z
    b1, b2 = p.c1n / (shape_c * mu), p.c2n / (shape_c * mu)
    ref1, ref2 = 0.5 * p.w1_n, 0.5 * p.w2_n
    eps, ply = p.roll_steer, p.rear_ply_steer_rad
    inv_sigma = 1.0 / p.relaxation_length_m
    long_transfer = m * h_cg / length

    def force(alpha: float, fz: float, stiffness: float, ref: float) -> float:
        if fz <= 0.0:
            return 0.0
        x = stiffness * (1.0 - sens * (fz - ref) / ref) * alpha
        return mu * fz * sin(shape_c * atan(x - curv_e * (x - atan(x))))

    def derivative(u: float, u_dot: float, delta: float, s: list[float], full: bool) -> tuple[float, ...]:
        v, r, phi, rate, psi, f_fl, f_fr, f_rl, f_rr = s
        if g_plane != 0.0:
            rel = downhill - psi
            g_y, g_x = g_plane * sin(rel), g_plane * cos(rel)
        else:
            g_y = g_x = 0.0
        cos_d = cos(delta)
        delta2 = eps * phi
        cos_d2 = cos(delta2)
        front = (f_fl + f_fr) * cos_d
        rear = (f_rl + f_rr) * cos_d2
        # wheel loads
        dz_long = 0.5 * long_transfer * (u_dot - g_x)
        dz1 = (k1 * phi + d1 * rate + front * h1) / t1
        dz2 = (k2 * phi + d2 * rate + rear * h2) / t2
        z_fl, z_fr = fz01 - dz_long - dz1, fz01 - dz_long + dz1
        z_rl, z_rr = fz02 + dz_long - dz2, fz02 + dz_long + dz2
        # slip angles and relaxed forces
        lat1, lat2 = v + a * r, v - b * r
        rate_relax = u * inv_sigma
        df_fl = (force(delta - atan(lat1 / (u - half1 * r)), z_fl, b1, ref1) - f_fl) * rate_relax
        df_fr = (force(delta - atan(lat1 / (u + half1 * r)), z_fr, b1, ref1) - f_fr) * rate_relax
        df_rl = (force(delta2 + ply - atan(lat2 / (u - half2 * r)), z_rl, b2, ref2) - f_rl) * rate_relax
        df_rr = (force(delta2 + ply - atan(lat2 / (u + half2 * r)), z_rr, b2, ref2) - f_rr) * rate_relax
        # body
        sum_fy = front + rear
        m_z = a * front - b * rear + half1 * (f_fl - f_fr) * sin(delta) + half2 * (f_rl - f_rr) * sin(delta2)
        rhs_lat = sum_fy + m * g_y - m * u * r
        rhs_roll = m * arm * (u * r - g_y) + m * g_normal * arm * phi - (k1 + k2) * phi - (d1 + d2) * rate
        v_dot = (inertia_o * rhs_lat + m * arm * rhs_roll) / det
        phi_dd = (m * arm * rhs_lat + m * rhs_roll) / det
        derivs = (v_dot, m_z / iz, rate, phi_dd, r, df_fl, df_fr, df_rl, df_rr)
        if not full:
            return derivs
        f_y = v_dot + u * r - arm * phi_dd - g_y  # specific force at the CG, road-plane axes
        ay_acc = f_y * cos(phi) + g_normal * sin(phi)
        ax_acc = u_dot - v * r - g_x
        return (*derivs, v_dot, z_fl, z_fr, z_rl, z_rr, ay_acc, ax_acc, delta2, phi_dd, g_y, g_x)

    return derivative
