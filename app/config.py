"""The vehicle config: one TOML file read once into frozen dataclasses and checked against its DBCs.

Every mistake becomes a one-line ConfigError naming the file, the key and the fix.
"""

import difflib
import math
import os
import stat
import tomllib
import types
import typing
from collections.abc import Mapping, Sequence
from dataclasses import MISSING, dataclass, field, fields, replace
from pathlib import Path
from typing import Any, Literal

from app.dbc import ChannelSpec, Dbc, load_dbc
from app.errors import ConfigError
from app.paper import G
from app.units import ROLE_UNITS, Z95, known_units, si_factor

DEFAULT_CONFIG = Path(__file__).resolve().parent.parent / "config" / "mondeo.toml"
COMMONROAD_CONFIG = DEFAULT_CONFIG.with_name("commonroad_vehicle2.toml")  # c2n simulate --model commonroad

OPTICAL_ROLES = ("vx", "vy", "beta")


@dataclass(frozen=True)
class Vehicle:
    sensor_ahead_of_rear_axle_m: float = field(
        metadata={"help": "d: metres from the rear axle forward to the sensor"}
    )
    sensor_lateral_m: float = field(
        default=0.0, metadata={"help": "sensor offset from the centre line, + left"}
    )
    sensor_height_m: float = 0.0
    wheelbase_m: float | None = None
    rear_axle_load_N: float | None = None
    front_axle_load_N: float | None = None
    cg_height_m: float | None = None
    roll_axis_height_m: float | None = None  # at the sensor: its height above it times the roll rate
    track_m: float | None = None
    steering_ratio: float | None = None
    tyre_radius_m: float | None = None
    gravity_mps2: float = G  # the paper's g; local gravity may differ by 0.3 %

    @property
    def load_transfer_per_g(self) -> float | None:
        """The rear axle's load moved per g of longitudinal acceleration, as a share of its own load:
        h·W/(l·W2) (W·h/l moved, W2 carried); None where the config lacks a figure for it."""
        h, length = self.cg_height_m, self.wheelbase_m
        w1, w2 = self.front_axle_load_N, self.rear_axle_load_N
        if h is None or length is None or w1 is None or w2 is None:
            return None
        return h * (w1 + w2) / (length * w2)


@dataclass(frozen=True)
class Tyres:
    """The tyres' figures as a rig gives them, and how far the car's tyres on the day may be from
    the rig's C2n (± %, 95 %): the rig's surface against the road's, wear, temperature and the
    pressure on the day. ``c2n gap`` compares the axle's C2n the drive measures with it (a rear
    steer with roll or compliance is the difference); a handbook figure is known to 15–20 %."""

    c1n_per_rad: float | None = None
    c2n_per_rad: float | None = None
    c2n_tolerance_pct: float = 5.0


@dataclass(frozen=True)
class Calibration:
    """The sensors' scale tolerances from their data sheets, ± % (a bound, read as uniform: a
    standard error of x/√3; 0: not counted), and how well the tape measured d, ± mm (a person's
    error, read as normal with 95 % inside: a standard error of x/1.96). No drive can show them —
    C2n scales with them — so they are counted in its interval beside the data's own error: the
    scales always, the tape's d where C2n rests on it (a crossing's u0²/(g·d), a fit whose d is
    held at the tape's value; a fit that places d itself does not use the tape)."""

    yaw_rate_scale_pct: float = 0.0  # the regression's C2n scales as (1 + s)
    speed_scale_pct: float = 0.0  # the optical speed: the regression's C2n as (1 + k), a crossing's (1 + 2k)
    d_tolerance_mm: float = 10.0  # the tape's d: a crossing's C2n scales as 1/(1 + δd/d)

    @property
    def fit_se(self) -> float:
        """The relative standard error the scales add to a regression's C2n."""
        return math.hypot(self.yaw_rate_scale_pct, self.speed_scale_pct) / (100.0 * math.sqrt(3.0))

    @property
    def d_se_m(self) -> float:
        """The tape's standard error on d, metres."""
        return self.d_tolerance_mm / (1000.0 * Z95)

    def crossing_se(self, d_m: float) -> float:
        """The relative standard error the speed's scale and the tape's d add to a crossing's
        C2n = u0²/(g·d)."""
        return math.hypot(2.0 * self.speed_scale_pct / (100.0 * math.sqrt(3.0)), self.d_se_m / d_m)

    def c2n_se(self, fit: bool, d_m: float) -> float:
        """What the scales add to a headline C2n's relative error: a fit's (``fit_se``) or a
        crossing's (``crossing_se``)."""
        return self.fit_se if fit else self.crossing_se(d_m)


@dataclass(frozen=True)
class GapSettings:
    """What ``c2n gap`` counts as mattering: an effect found in a drive is a finding when it moves
    C2n or its own channel by more than these, else "within tolerance" (docs/gap.md says where each
    default comes from), and whether CommonRoad's camber-step nuisance is
    calibrated."""

    c2n_pct: float = 0.5  # a tyre rig's repeatability on C2n, ± %
    sideslip_deg: float = 0.1  # an optical sideslip sensor's angle accuracy (Kistler S-Motion sheet)
    speed_pct: float = 1.0  # a wheel-speed signal: the rolling radius moves ~1 % with wear and pressure
    latency_s: float = 0.1  # a vehicle bus's signal ages a few 10–20 ms cycles; beyond, it is late
    turn_force: bool = False  # calibrate a lateral force that follows the turn (a camber step)


@dataclass(frozen=True)
class DetectorSettings:
    """Steady-state gate and crossing detection; docs/method.md says what each limit protects."""

    ay_max_mps2: float = 4.0  # tyres must stay linear
    sweep_max_mps2: float = 0.6  # |du/dt| above this is not steady
    speed_min_mps: float = 4.0
    radius_max_m: float = 500.0  # straighter than this is "driving straight"
    yaw_accel_max_radps2: float = 0.08  # transients (step steers) are not steady
    lateral_accel_rate_max_mps2: float = 0.2  # |dv/dt| at the sensor: transients again
    settle_s: float = 1.0  # the gate must hold this long before samples count
    debounce_s: float = 0.3  # a rate limit failing this briefly does not restart settling
    fit_half_width_mps: float = (
        1.5  # local fit uses samples within u0 ± this (widened up to 3× for sparse data)
    )
    min_side_fraction: float = 0.4  # each side of u0 must cover this share of the half width
    min_fit_samples: int = 40
    hysteresis_sigmas: float = 3.0  # sign change must clear this many sigmas of the filtered sideslip
    reversal_mps: float = 0.3  # speed reversal that starts a new sweep
    max_gap_s: float = 30.0  # longer without steady samples starts a new run
    min_slope_t: float = 5.0  # the local fit's slope must be this many standard errors from 0


@dataclass(frozen=True)
class FilterSettings:
    """Kalman filter noise model (standard deviations of measurements, process spectral densities)."""

    sigma_velocity_mps: float = 0.02  # optical vx, vy
    sigma_beta_deg: float | None = None  # None: sigma_velocity_mps / u
    sigma_speed_mps: float = 0.5  # vehicle speed: weak, wheel-speed based
    sigma_yaw_rate_radps: float = 0.003
    sigma_ay_mps2: float = 0.15
    q_u: float = 0.05  # jerk spectral density of longitudinal velocity [m²/s⁵]
    q_v: float = 0.02  # lateral velocity [m²/s⁵]
    q_r: float = 0.5  # yaw rate [rad²/s⁵]: turn-ins are quick
    gap_reset_s: float = 1.0  # longer without optical data resets the filter
    status_timeout_s: float = 1.0  # sensor status older than this is unknown
    sideslip_source: Literal["auto", "beta", "vy"] = "auto"
    innovation_gate: float = 30.0  # normalised innovation² beyond this rejects a sample


# What each number may be: (lowest, highest, lowest allowed itself). Anything else — out of range,
# NaN, ±inf — is one error line naming the file, the key and the range.
_OPEN, _CLOSED = False, True
_RANGES: dict[tuple[str, str], tuple[float, float, bool]] = {
    ("vehicle", "sensor_ahead_of_rear_axle_m"): (0.0, 10.0, _OPEN),
    ("vehicle", "sensor_lateral_m"): (-3.0, 3.0, _CLOSED),
    ("vehicle", "sensor_height_m"): (0.0, 5.0, _CLOSED),
    ("vehicle", "wheelbase_m"): (0.0, 20.0, _OPEN),
    ("vehicle", "rear_axle_load_N"): (0.0, 1e6, _OPEN),
    ("vehicle", "front_axle_load_N"): (0.0, 1e6, _OPEN),
    ("vehicle", "cg_height_m"): (0.0, 5.0, _OPEN),
    ("vehicle", "roll_axis_height_m"): (-1.0, 5.0, _CLOSED),
    ("vehicle", "track_m"): (0.0, 5.0, _OPEN),
    ("vehicle", "steering_ratio"): (0.0, 100.0, _OPEN),
    ("vehicle", "tyre_radius_m"): (0.0, 3.0, _OPEN),
    ("vehicle", "gravity_mps2"): (9.7, 9.9, _CLOSED),  # on Earth: 9.78 at the equator, 9.83 at a pole
    ("tyres", "c1n_per_rad"): (0.0, 200.0, _OPEN),
    ("tyres", "c2n_per_rad"): (0.0, 200.0, _OPEN),
    ("tyres", "c2n_tolerance_pct"): (0.0, 100.0, _OPEN),
    ("calibration", "yaw_rate_scale_pct"): (0.0, 10.0, _CLOSED),
    ("calibration", "speed_scale_pct"): (0.0, 10.0, _CLOSED),
    ("calibration", "d_tolerance_mm"): (0.0, 100.0, _CLOSED),
    ("gap", "c2n_pct"): (0.0, 100.0, _OPEN),
    ("gap", "sideslip_deg"): (0.0, 10.0, _OPEN),
    ("gap", "speed_pct"): (0.0, 100.0, _OPEN),
    ("gap", "latency_s"): (0.0, 10.0, _OPEN),
    ("priors", "confidence"): (0.0, 1.0, _OPEN),
    ("priors", "head_yaw_deg"): (0.0, 10.0, _OPEN),
    ("priors", "slope_pct"): (0.0, 20.0, _OPEN),
    ("priors", "load_transfer_per_g"): (0.0, 2.0, _OPEN),
    ("priors", "softening_per_mps2_2"): (0.0, 0.1, _OPEN),
    ("priors", "softening_ratio"): (0.0, 100.0, _CLOSED),
    ("priors", "softening_ratio_sd"): (0.0, 100.0, _CLOSED),
    ("priors", "gyro_bias_degps"): (0.0, 10.0, _OPEN),
    ("priors", "yaw_inertia_wheelbases"): (0.0, 10.0, _OPEN),
    ("priors", "two_wheels_wheelbases2"): (0.0, 10.0, _OPEN),
    ("priors", "turn_force_pct"): (0.0, 20.0, _CLOSED),
    ("priors", "d_gross_share"): (0.0, 1.0, _OPEN),
    ("priors", "d_gross_wheelbases"): (0.0, 10.0, _OPEN),
    ("detector", "ay_max_mps2"): (0.0, 20.0, _OPEN),
    ("detector", "sweep_max_mps2"): (0.0, 10.0, _OPEN),
    ("detector", "speed_min_mps"): (0.0, 100.0, _CLOSED),
    ("detector", "radius_max_m"): (0.0, 1e5, _OPEN),
    ("detector", "yaw_accel_max_radps2"): (0.0, 10.0, _OPEN),
    ("detector", "lateral_accel_rate_max_mps2"): (0.0, 10.0, _OPEN),
    ("detector", "settle_s"): (0.0, 60.0, _CLOSED),
    ("detector", "debounce_s"): (0.0, 10.0, _CLOSED),
    ("detector", "fit_half_width_mps"): (0.0, 20.0, _OPEN),
    ("detector", "min_side_fraction"): (0.0, 1.0, _OPEN),
    ("detector", "min_fit_samples"): (3.0, 1e6, _CLOSED),
    ("detector", "hysteresis_sigmas"): (0.0, 100.0, _CLOSED),
    ("detector", "reversal_mps"): (0.0, 10.0, _OPEN),
    ("detector", "max_gap_s"): (0.0, 3600.0, _OPEN),
    ("detector", "min_slope_t"): (0.0, 100.0, _CLOSED),
    ("filter", "sigma_velocity_mps"): (0.0, 10.0, _OPEN),
    ("filter", "sigma_beta_deg"): (0.0, 10.0, _OPEN),
    ("filter", "sigma_speed_mps"): (0.0, 100.0, _OPEN),
    ("filter", "sigma_yaw_rate_radps"): (0.0, 1.0, _OPEN),
    ("filter", "sigma_ay_mps2"): (0.0, 100.0, _OPEN),
    ("filter", "q_u"): (0.0, 1e6, _OPEN),
    ("filter", "q_v"): (0.0, 1e6, _OPEN),
    ("filter", "q_r"): (0.0, 1e6, _OPEN),
    # the filter predicts across a gap as if the car drove on: 8 s of a circle's dropout bridged with
    # C2n as without it (0.01 %); 600 s across a parked car lost it for good (11,236 samples
    # rejected, the drive after the pause gone without a word). Longer is a pause: it restarts
    ("filter", "gap_reset_s"): (0.0, 10.0, _OPEN),
    ("filter", "status_timeout_s"): (0.0, 3600.0, _OPEN),
    ("filter", "innovation_gate"): (0.0, 1e9, _OPEN),
}


def _check_range(path: Path, section: str, key: str, value: float) -> None:
    limits = _RANGES.get((section, key))
    if limits is None:
        return
    low, high, low_allowed = limits
    inside = math.isfinite(value) and (low <= value if low_allowed else low < value) and value <= high
    if not inside:
        lowest = f"{low:g} to" if low_allowed else f"above {low:g} up to"
        raise ConfigError(f"{path}: [{section}] {key} = {value!r} is out of range — use {lowest} {high:g}")


@dataclass(frozen=True)
class RoleSpec:
    """A role mapped to a DBC signal, with the factor that takes it to the role's SI unit."""

    role: str
    message: str
    signal: str
    scale: float  # the config's scale (sign flips, unit changes)
    unit: str  # the decoded unit (from [units] or the DBC)
    si_factor: float  # unit conversion to the role's internal unit
    channel: ChannelSpec | None
    resolution: float = 0.0  # one DBC bit in the role's SI unit

    @property
    def name(self) -> str:
        return f"{self.message}.{self.signal}"

    @property
    def factor(self) -> float:
        """Decoded physical value × factor = value in the role's SI unit."""
        return self.scale * self.si_factor


@dataclass(frozen=True)
class StatusCondition:
    message: str
    signal: str
    value: float
    applies_to: tuple[str, ...]  # the roles it gates

    @property
    def name(self) -> str:
        return f"{self.message}.{self.signal}"


# the rear axle's load moved per g as a share of its own, where a config gives no figure for its
# car: a CG 0.55 m high over a 2.7 m wheelbase with 45 % of the weight on the rear axle
GENERIC_LOAD_TRANSFER_PER_G = 0.55 / (0.45 * 2.7)


@dataclass(frozen=True)
class Priors:
    """The policy of the marginal fit: its confidence level and each nuisance's prior standard
    deviation (mean zero unless said), each from physics or a data sheet, never from a bench."""

    # which regression gives the result: "marginal" (this one, every nuisance under its prior: the
    # default) or "cascade" (terms chosen by tests)
    estimator: Literal["cascade", "marginal"] = "marginal"
    confidence: float = 0.95
    # the head's yaw on the car: mounted by eye against the body, ±1° at 95 %
    head_yaw_deg: float = 0.5
    # a test pad's grade, each of its two components: ISO 4138 asks for a test surface within 2 %
    # in any direction, and drainage slopes of 1–2 % are common
    slope_pct: float = 2.0
    # how much the rear axle's stiffness changes, as a share of itself, per unit of longitudinal
    # acceleration in g (a slope's gravity along the heading, braking), with cornering stiffness
    # about proportional to load: the load moved, W·h/l, over the rear axle's own W2 — h·W/(l·W2),
    # which is h over the CG's distance from the front axle. A config whose [vehicle] gives
    # cg_height_m, wheelbase_m and both axle loads has its car's own (``Vehicle.load_transfer_per_g``:
    # the Mondeo's 0.51); else a car's CG at 0.55 m over a 2.7 m wheelbase with 45 % of its weight
    # on the rear: 0.45. A slope's load transfer is tied to its pull with this L as N(L, L²): on a
    # level pad it has no room of its own
    load_transfer_per_g: float = GENERIC_LOAD_TRANSFER_PER_G
    # the tyres' softening s in α = a_y/(g·C2n)·(1 + s·a_y²), (m/s²)⁻²: a Magic-Formula tyre loses
    # 3–4 % of its stiffness by 4 m/s² (s ≈ 0.002); 0.004 holds twice that within one σ
    softening_per_mps2_2: float = 0.004
    # the softening's next term, α = a_y/(g·C2n)·(1 + s·a_y² + r·s²·a_y⁴), s the fit's own: r is 1
    # where a tyre's stiffness falls with load (a soft, heavy car: the series of 1/(1 − s·a_y²)) and
    # 1.5–8.5 for a Magic-Formula tyre's own curve (C 1.2–1.5, E −1…0.5); 4.75 and 3.75 hold that
    # range within one σ. Off by default (0, 0): on an independent simulator's car and CommonRoad's
    # it read C2n 0.3–0.8 % low, where the cubic alone was right; a soft heavy car whose softening
    # is strong reads 1–2.5 % high without it, which the result says (``next_term_pct``)
    softening_ratio: float = 0.0
    softening_ratio_sd: float = 0.0
    # the yaw-rate gyro's bias after zeroing at standstill, °/s: a MEMS automotive yaw-rate sensor's
    # data sheet quotes ±0.3 °/s over temperature; a day's drift is within it
    gyro_bias_degps: float = 0.15
    # the yaw inertia's share of the rear force: I_z·ṙ/l over the rear's share of m·a_y, a lever of
    # about the front's distance a — at most a wheelbase (units of a_y's coefficient per m)
    yaw_inertia_wheelbases: float = 1.0
    # the axle's two wheels on a tight turn: slips and loads apart by shares of (κ·track)², so a
    # term κ²·a_y of at most a wheelbase² times a_y's coefficient
    two_wheels_wheelbases2: float = 1.0
    # a rear force that follows the turn's direction, % of the axle's weight: 0 leaves it out (real
    # cars); CommonRoad's Pacejka tyres carry a camber step of 2–3 %
    turn_force_pct: float = 0.0
    # the share of setups whose d is wrong beyond the tape's tolerance (the head moved, d measured
    # from the wrong point, a config copied from another car): d's prior is then the tape's with
    # this weight on a second, wide one. The data move the weight (the two priors' evidence), so
    # the share only sets where: a drive's d apart from the tape by 4.0, 4.4, 4.9 σ at 0.05, 0.01,
    # 0.001 takes the wide prior; under 5 % it cannot, alone, open a 95 % interval (one speed)
    d_gross_share: float = 0.01
    # the wide prior's σ, in wheelbases: a head put (or its d written) wrongly is still on the car,
    # within a wheelbase of the tape's value at 95 %
    d_gross_wheelbases: float = 0.5


def raised_noise(settings: FilterSettings) -> tuple[str, ...]:
    """The process noises ``settings`` raises above their defaults, as the config says them
    (``[filter] q_v = 1e+06 (default 0.02)``): a filter whose rates follow the sensor's noise."""
    return tuple(_against_default(settings, _NOISES, 1.0).values())


def lowered_filter(settings: FilterSettings) -> dict[str, str]:
    """The process noises and the innovation gate ``settings`` lowers below their defaults, each
    as the config says it: a filter that lags the car, or rejects the sensor's own noise."""
    return _against_default(settings, (*_NOISES, "innovation_gate"), -1.0)


_NOISES = ("q_u", "q_v", "q_r")


def _against_default(settings: FilterSettings, names: Sequence[str], sign: float) -> dict[str, str]:
    default = FilterSettings()
    return {
        name: f"[filter] {name} = {getattr(settings, name):g} (default {getattr(default, name):g})"
        for name in names
        if sign * (getattr(settings, name) - getattr(default, name)) > 0.0
    }


@dataclass(frozen=True)
class Config:
    path: Path
    vehicle: Vehicle
    tyres: Tyres
    dbcs: tuple[Dbc, ...]
    roles: Mapping[str, RoleSpec]
    status: tuple[StatusCondition, ...]
    detector: DetectorSettings
    filter: FilterSettings
    calibration: Calibration = Calibration()
    gap: GapSettings = GapSettings()
    priors: Priors = field(default_factory=Priors)  # the regression's ([priors] estimator = "marginal")

    @property
    def d_m(self) -> float:
        return self.vehicle.sensor_ahead_of_rear_axle_m


_SECTIONS = {
    "vehicle",
    "tyres",
    "dbc",
    "roles",
    "sensor_status",
    "beta_status",
    "units",
    "channels",
    "detector",
    "filter",
    "calibration",
    "gap",
    "priors",
}


def load_config(path: Path | str = DEFAULT_CONFIG, dbc_dir: Path | None = None) -> Config:
    """Read, validate and resolve a vehicle config (and load its DBCs).

    ``dbc_dir`` takes each DBC by its file name from that folder instead of the path the config
    gives: a recorded session keeps copies of the config and its DBCs side by side.
    """
    path = Path(path)
    try:
        # without waiting (O_NONBLOCK): a pipe with no writer held `--config` forever
        with os.fdopen(os.open(path, os.O_RDONLY | os.O_NONBLOCK), "rb") as file:
            if not stat.S_ISREG(os.fstat(file.fileno()).st_mode):  # a folder fails to open: EISDIR
                raise ConfigError(f"{path}: not a file (a pipe or a device) — pass --config with a TOML file")
            # a byte-order mark (Windows Notepad's "UTF-8") is no TOML: read past it
            table = tomllib.loads(file.read().decode("utf-8").removeprefix("\ufeff"))
    except FileNotFoundError as error:
        raise ConfigError(f"{path}: config file not found — pass --config with a TOML file") from error
    except tomllib.TOMLDecodeError as error:
        raise ConfigError(f"{path}: not valid TOML ({error}) — fix the syntax") from error
    except UnicodeDecodeError as error:
        raise ConfigError(f"{path}: not UTF-8 text (byte {error.start}) — save it as UTF-8") from error
    except OSError as error:
        raise ConfigError(f"{path}: cannot read ({error.strerror})") from error
    return _build(path, table, dbc_dir)


def _own_load_transfer(path: Path, vehicle: Vehicle, priors: Priors, stated: Mapping[str, Any]) -> Priors:
    """The priors with the car's own load transfer where its [vehicle] gives the figures and
    [priors] (``stated``) gives none; a car whose figures put it beyond the priors' range (its rear
    axle would lift braking at 0.5 g) is refused."""
    own = vehicle.load_transfer_per_g
    if own is None or "load_transfer_per_g" in stated:
        return priors
    top = _RANGES[("priors", "load_transfer_per_g")][1]
    if not own <= top:
        raise ConfigError(
            f"{path}: [vehicle] cg_height_m, wheelbase_m and the axle loads move {own:.3g} of the rear "
            f"axle's load per g (its wheels would lift braking at {1.0 / own:.2g} g) — check them, or "
            f"set [priors] load_transfer_per_g (0–{top:g})"
        )
    return replace(priors, load_transfer_per_g=own)


def _build(path: Path, table: dict[str, Any], dbc_dir: Path | None = None) -> Config:
    _check_keys(path, "", table, _SECTIONS)
    vehicle = _dataclass_from(path, "vehicle", Vehicle, _section(path, table, "vehicle", required=True))
    tyres = _dataclass_from(path, "tyres", Tyres, _section(path, table, "tyres"))
    detector = _dataclass_from(path, "detector", DetectorSettings, _section(path, table, "detector"))
    filter_settings = _dataclass_from(path, "filter", FilterSettings, _section(path, table, "filter"))
    calibration = _dataclass_from(path, "calibration", Calibration, _section(path, table, "calibration"))
    gap = _dataclass_from(path, "gap", GapSettings, _section(path, table, "gap"))
    stated = _section(path, table, "priors")
    priors = _own_load_transfer(path, vehicle, _dataclass_from(path, "priors", Priors, stated), stated)
    if priors.confidence != Priors.confidence:  # 0.5 printed a 50 % interval as "95 %", 1.0 [0, 0]
        raise ConfigError(
            f"{path}: [priors] confidence = {priors.confidence!r}: c2n's intervals and tests are "
            f"{100 * Priors.confidence:g} % throughout (the result file's c2n_ci95, the comparisons of "
            "drives) — remove the key"
        )
    dbcs = _load_dbcs(path, table, dbc_dir)
    roles = _roles(path, table, dbcs)
    source = filter_settings.sideslip_source
    if source != "auto" and source not in roles:  # it gave no result, and blamed the driving
        raise ConfigError(
            f'{path}: [filter] sideslip_source = "{source}" but [roles] has no {source} — add the role, '
            'or set sideslip_source = "auto"'
        )
    status = _status(path, table, "sensor_status", OPTICAL_ROLES, dbcs) + _status(
        path, table, "beta_status", ("beta",), dbcs
    )
    return Config(
        path, vehicle, tyres, dbcs, roles, status, detector, filter_settings, calibration, gap, priors
    )


def _section(path: Path, table: dict[str, Any], name: str, required: bool = False) -> dict[str, Any]:
    value = table.get(name)
    if value is None:
        if required:
            raise ConfigError(f"{path}: section [{name}] is missing — add it (see config/mondeo.toml)")
        return {}
    if not isinstance(value, dict):
        raise ConfigError(f"{path}: '{name}' must be a table [{name}]")
    return value


def _check_keys(path: Path, section: str, table: Mapping[str, Any], allowed: typing.Iterable[str]) -> None:
    allowed = list(allowed)
    for key in table:
        if key not in allowed:
            where = f" in [{section}]" if section else ""
            close = difflib.get_close_matches(key, allowed, n=1)
            hint = f"did you mean '{close[0]}'?" if close else f"known: {', '.join(sorted(allowed))}"
            raise ConfigError(f"{path}: unknown key '{key}'{where} — {hint}")


def _dataclass_from(path: Path, section: str, cls: type[Any], table: dict[str, Any]) -> Any:
    """Build a settings dataclass from a TOML table, checking names, presence and types."""
    hints = typing.get_type_hints(cls)
    _check_keys(path, section, table, [f.name for f in fields(cls)])
    values: dict[str, Any] = {}
    for f in fields(cls):
        if f.name not in table:
            if f.default is MISSING:
                help_text = f.metadata.get("help", "")
                raise ConfigError(
                    f"{path}: [{section}] is missing key '{f.name}' — add it"
                    + (f" ({help_text})" if help_text else "")
                )
            continue
        values[f.name] = _typed(path, section, f.name, table[f.name], hints[f.name])
        if isinstance(values[f.name], int | float) and not isinstance(values[f.name], bool):
            _check_range(path, section, f.name, float(values[f.name]))
    return cls(**values)


def _typed(path: Path, section: str, key: str, value: Any, hint: Any) -> Any:
    options = typing.get_args(hint) if isinstance(hint, types.UnionType) else (hint,)
    for option in options:
        if option is float and isinstance(value, int | float) and not isinstance(value, bool):
            return float(value)
        if option is int and isinstance(value, int) and not isinstance(value, bool):
            return value
        if option is str and isinstance(value, str):
            return value
        if option is bool and isinstance(value, bool):
            return value
        if typing.get_origin(option) is Literal and value in typing.get_args(option):
            return value
    wanted = " or ".join(_type_name(o) for o in options if o is not type(None))
    raise ConfigError(f"{path}: [{section}] {key} must be {wanted}, got {value!r}")


def _type_name(option: Any) -> str:
    if typing.get_origin(option) is Literal:
        return " | ".join(repr(v) for v in typing.get_args(option))
    return {float: "a number", int: "an integer", str: "a string", bool: "true or false"}.get(
        option, str(option)
    )


def _load_dbcs(path: Path, table: dict[str, Any], dbc_dir: Path | None) -> tuple[Dbc, ...]:
    section = _section(path, table, "dbc", required=True)
    _check_keys(path, "dbc", section, ["files"])
    files = section.get("files")
    if not isinstance(files, list) or not files or not all(isinstance(f, str) for f in files):
        raise ConfigError(f'{path}: [dbc] files must be a list of DBC paths, e.g. files = ["../dbc/x.dbc"]')
    channels = _section(path, table, "channels")

    def locate(name: str) -> Path:
        where = dbc_dir / Path(name).name if dbc_dir else path.parent / name
        try:
            return where.resolve()
        except (OSError, RuntimeError) as error:  # a link that leads to itself (RuntimeError to 3.12)
            why = error.strerror if isinstance(error, OSError) and error.strerror else "a symbolic link loop"
            raise ConfigError(f"{path}: [dbc] files: {where} cannot be read ({why})") from error

    resolved = {name: locate(name) for name in files}
    for name, where in resolved.items():  # it said "id 0x7E0 is in both x.dbc and x.dbc"
        first = next(other for other, there in resolved.items() if there == where)
        if first != name:
            raise ConfigError(
                f'{path}: [dbc] files lists {where.name} twice ("{first}" and "{name}") — list it once'
            )
    for key, channel in channels.items():
        if key not in resolved and locate(key) not in resolved.values():
            raise ConfigError(
                f"{path}: [channels] names '{key}', which is not in [dbc] files — use one of {files}"
            )
        if not isinstance(channel, int | str) or isinstance(channel, bool):
            raise ConfigError(f"{path}: [channels] '{key}' must be a channel name or number, got {channel!r}")
    dbcs = []
    for dbc_path in resolved.values():
        channel = next((c for k, c in channels.items() if locate(k) == dbc_path), None)
        dbcs.append(load_dbc(dbc_path, channel))
    _check_id_collisions(path, dbcs)
    return tuple(dbcs)


def _check_id_collisions(path: Path, dbcs: list[Dbc]) -> None:
    from app.dbc import channel_matches

    seen: dict[tuple[int, bool], Dbc] = {}
    for dbc in dbcs:
        for message in dbc.database.messages:
            key = (message.frame_id, message.is_extended_frame)
            other = seen.get(key)
            if other is not None and (
                other.channel is None or dbc.channel is None or channel_matches(other.channel, dbc.channel)
            ):
                raise ConfigError(
                    f"{path}: id 0x{message.frame_id:X} is in both {other.path.name} and {dbc.path.name} "
                    "— set [channels] so each DBC is decoded on its own channel"
                )
            seen[key] = dbc


def _find_signal(path: Path, where: str, name: str, dbcs: tuple[Dbc, ...]) -> tuple[Dbc, Any, Any]:
    """Resolve "Message.Signal" to (dbc, cantools message, cantools signal)."""
    message_name, dot, signal_name = name.partition(".")
    if not dot or not message_name or not signal_name:
        raise ConfigError(f'{path}: {where} must be "Message.Signal", got {name!r}')
    candidates = []
    for dbc in dbcs:
        for message in dbc.database.messages:
            for signal in message.signals:
                full = f"{message.name}.{signal.name}"
                if full == name:
                    return dbc, message, signal
                candidates.append(full)
    close = difflib.get_close_matches(name, candidates, n=1, cutoff=0.5)
    hint = f"did you mean '{close[0]}'?" if close else "check the message and signal names"
    files = ", ".join(str(d.path.name) for d in dbcs)
    raise ConfigError(f"{path}: {where} names signal '{name}' that no DBC has ({files}) — {hint}")


def _roles(path: Path, table: dict[str, Any], dbcs: tuple[Dbc, ...]) -> dict[str, RoleSpec]:
    section = _section(path, table, "roles", required=True)
    _check_keys(path, "roles", section, ROLE_UNITS)
    units = _section(path, table, "units")
    _check_keys(path, "units", units, ROLE_UNITS)
    if "vx" not in section:
        raise ConfigError(
            f"{path}: [roles] is missing key 'vx' — add vx = \"Message.Signal\" "
            "(optical longitudinal velocity)"
        )
    if "vy" not in section and "beta" not in section:
        raise ConfigError(
            f"{path}: [roles] needs 'vy' or 'beta' — add the optical lateral velocity or sideslip angle"
        )
    roles = {}
    for role, value in section.items():
        where = f"[roles] {role}"
        if isinstance(value, str):
            value = {"signal": value}
        if not isinstance(value, dict):
            raise ConfigError(
                f'{path}: {where} must be "Message.Signal" or {{signal = "Message.Signal", scale = 1.0}}'
            )
        _check_keys(path, f"roles.{role}", value, ["signal", "scale", "unit", "channel"])
        if "signal" not in value or not isinstance(value["signal"], str):
            raise ConfigError(f'{path}: {where} needs signal = "Message.Signal"')
        dbc, message, signal = _find_signal(path, where, value["signal"], dbcs)
        scale = value.get("scale", 1.0)
        if (
            not isinstance(scale, int | float)
            or isinstance(scale, bool)
            or scale == 0
            or not math.isfinite(scale)
        ):
            # NaN was taken, and every value it gave dropped as the log's: "not a number (yaw_rate)"
            raise ConfigError(f"{path}: {where} scale must be a finite non-zero number, got {scale!r}")
        unit = value.get("unit", units.get(role)) or signal.unit or ""
        if not isinstance(unit, str):
            raise ConfigError(f'{path}: [units] {role} must be a unit text such as "km/h"')
        factor = si_factor(role, unit)
        if factor is None:
            said = f"unit '{unit}'" if unit else "no unit"
            raise ConfigError(
                f"{path}: {where} signal {value['signal']} has {said}, not one for {role} — "
                f"set [units] {role} to one of {', '.join(known_units(role))}"
            )
        channel = value.get("channel", dbc.channel)
        if channel is not None and (not isinstance(channel, int | str) or isinstance(channel, bool)):
            raise ConfigError(f"{path}: {where} channel must be a channel name or number, got {channel!r}")
        resolution = abs(float(signal.scale) * float(scale) * factor) if not signal.is_float else 0.0
        roles[role] = RoleSpec(
            role, message.name, signal.name, float(scale), unit, factor, channel, resolution
        )
    _each_its_own_signal(path, roles)
    return roles


# roles that may read one signal: a car without a vehicle-speed signal of its own given the optical vx
_ONE_SIGNAL_ALLOWED = frozenset({"vx", "speed"})


def _each_its_own_signal(path: Path, roles: Mapping[str, RoleSpec]) -> None:
    """Two roles of one quantity reading one signal is a copied line (vy given vx's: accepted, and
    the sideslip's two sensors then disagree for no reason the drive holds)."""
    specs = list(roles.values())
    for i, spec in enumerate(specs):
        for other in specs[:i]:
            one_bus = spec.channel is None or other.channel is None or spec.channel == other.channel
            if (
                spec.name == other.name
                and one_bus  # a role without a channel reads every channel (helper-33)
                and {spec.role, other.role} != _ONE_SIGNAL_ALLOWED
            ):
                raise ConfigError(
                    f"{path}: [roles] {spec.role} and {other.role} both read {spec.name} — each is a "
                    f"quantity of its own: give {spec.role} its signal, or leave it out"
                )


def _status(
    path: Path, table: dict[str, Any], name: str, applies_to: tuple[str, ...], dbcs: tuple[Dbc, ...]
) -> tuple[StatusCondition, ...]:
    conditions = []
    for key, value in _section(path, table, name).items():
        _dbc, message, signal = _find_signal(path, f"[{name}] key", key, dbcs)
        if not isinstance(value, int | float) or isinstance(value, bool) or not math.isfinite(value):
            raise ConfigError(
                f"{path}: [{name}] {key} must be the number the signal must equal, got {value!r}"
            )
        conditions.append(StatusCondition(message.name, signal.name, float(value), applies_to))
    return tuple(conditions)
