"""What the sensors would put on the bus: noise, DBC quantisation, rates, and chosen errors.

The optical sensor (Kistler S-Motion layout) sits d ahead of the rear axle and y_s left of the
centre line on its own channel; the vehicle's frames (Ford layout) on another. Every value goes
through cantools' encoder, so the log carries exactly the DBCs' resolution.

A two-track trace (two_track.py) brings more physics: the optical head at its height sees the
roll rate, the accelerometer reads roll and road slope, and both gyros carry the roll rate.
"""

import math
from collections.abc import Iterator
from dataclasses import dataclass, replace
from typing import Any

import can
import numpy as np

from app.config import Config
from app.sim.drive import DriveTrace
from app.sim.two_track import TwoTrackTrace

LOG_START = 1_763_900_000.0  # 2025-11-23, so logs carry plausible absolute times


@dataclass(frozen=True)
class SensorSetup:
    d_m: float  # true sensor position ahead of the rear axle
    lateral_m: float = 0.0  # true lateral offset, + left
    optical_hz: float = 100.0
    vehicle_hz: float = 100.0  # yaw rate, lateral acceleration, steering, wheel speeds
    speed_hz: float = 50.0  # vehicle speed
    status_hz: float = 50.0
    sigma_velocity_mps: float = 0.02  # optical vx, vy white noise
    sigma_yaw_rate_degps: float = 0.05
    sigma_ay_mps2: float = 0.05
    sigma_speed_kph: float = 0.05
    yaw_misalignment_deg: float = 0.0  # sensor head turned left by this much
    gyro_bias_degps: float = 0.0  # the sensor's yaw gyro reads this much high
    gyro_scale: float = 1.0  # ... and this many times the true rate
    vehicle_gyro_bias_degps: float = 0.0  # the vehicle's yaw-rate sensor
    steer_offset_deg: float = 0.0  # the steering-wheel angle reads this when the wheels are straight
    speed_scale: float = 1.0  # vehicle speed scale error (tyre radius)
    speed_latency_s: float = 0.0  # vehicle speed delay (on top of vehicle_latency_s)
    vehicle_latency_s: float = 0.0  # every vehicle-bus signal carries the value of this long ago
    wheel_speed_scale: float = 1.0  # wheel speeds' scale error (true rolling radius / nominal)
    height_m: float = 0.0  # optical head above the ground (two-track traces: roll rate share)
    angle_cutoff_mps: float = 1.4  # the sensor forces Angle to 0 below this (AngleSwitchedOff)
    steering_ratio: float = 15.0
    track_m: float = 1.5
    tyre_radius_m: float = 0.31
    sensor_channel: int = 1
    vehicle_channel: int = 0
    jitter_s: float = 0.0002  # transmission delay after the sample, uniform

    @classmethod
    def from_config(cls, config: Config, **overrides: Any) -> "SensorSetup":
        """The sensors where the config says they are (the truth, unless an effect moves them)."""
        v = config.vehicle
        setup = cls(
            d_m=config.d_m,
            lateral_m=v.sensor_lateral_m,
            steering_ratio=v.steering_ratio or 15.0,
            track_m=v.track_m or 1.5,
            tyre_radius_m=v.tyre_radius_m or 0.31,
            height_m=v.sensor_height_m,
        )
        return replace(setup, **overrides)


def frames(
    trace: DriveTrace, setup: SensorSetup, kistler: Any, ford: Any, rng: np.random.Generator
) -> list[can.Message]:
    """All frames of the drive, in timestamp order. ``kistler``/``ford``: cantools databases."""
    sources = [
        _optical(trace, setup, kistler, rng),
        _status(trace, setup, kistler),
        _vehicle(trace, setup, ford, rng),
    ]
    messages = [m for source in sources for m in source]
    jitter = rng.uniform(0.0, setup.jitter_s, len(messages))
    for message, delay in zip(messages, jitter.tolist(), strict=True):
        message.timestamp += delay  # a Python float: log writers print its repr
    messages.sort(key=lambda m: m.timestamp)
    return messages


def _times(trace: DriveTrace, hz: float) -> np.ndarray:
    return np.arange(0.0, trace.t[-1] + 1e-9, 1.0 / hz)


def _at(trace: DriveTrace, times: np.ndarray, values: np.ndarray) -> np.ndarray:
    return np.asarray(np.interp(times, trace.t, values))


def _encode(
    message: Any, channel: int, times: np.ndarray, columns: dict[str, np.ndarray]
) -> Iterator[can.Message]:
    signals = {s.name: s for s in message.signals}
    clipped = {}
    for name, values in columns.items():
        signal = signals[name]
        clipped[name] = np.clip(values, signal.minimum, signal.maximum)
    names = list(clipped)
    for i, t in enumerate(times):
        data = message.encode({name: float(clipped[name][i]) for name in names}, scaling=True, strict=False)
        yield can.Message(
            timestamp=LOG_START + float(t),
            arbitration_id=message.frame_id,
            is_extended_id=message.is_extended_frame,
            data=data,
            channel=channel,
        )


def _optical(trace: DriveTrace, s: SensorSetup, db: Any, rng: np.random.Generator) -> Iterator[can.Message]:
    t = _times(trace, s.optical_hz)
    x_s = s.d_m - trace.params.b_m  # ahead of the CG
    u, r = _at(trace, t, trace.u), _at(trace, t, trace.r)
    vx = u - r * s.lateral_m
    if isinstance(trace, TwoTrackTrace):
        vy = _at(trace, t, trace.lateral_velocity_at(x_s, s.height_m))
    else:
        vy = _at(trace, t, trace.lateral_velocity_at(x_s))
    psi = math.radians(s.yaw_misalignment_deg)  # head turned left: it sees the velocity turned right
    vx, vy = vx * math.cos(psi) + vy * math.sin(psi), -vx * math.sin(psi) + vy * math.cos(psi)
    vx = vx + rng.normal(0.0, s.sigma_velocity_mps, len(t))
    vy = vy + rng.normal(0.0, s.sigma_velocity_mps, len(t))
    angle = np.degrees(np.arctan2(vy, vx))
    angle = np.where(np.hypot(vx, vy) < s.angle_cutoff_mps, 0.0, angle)
    kmh = 3.6
    velocity = {"vx": vx * kmh, "vy": vy * kmh, "vel": np.hypot(vx, vy) * kmh}
    yaw = s.gyro_scale * np.degrees(r) + s.gyro_bias_degps + rng.normal(0.0, s.sigma_yaw_rate_degps, len(t))
    zeros = np.zeros(len(t))
    roll = zeros
    if isinstance(trace, TwoTrackTrace):
        roll = np.degrees(_at(trace, t, trace.roll_rate)) + rng.normal(0.0, s.sigma_yaw_rate_degps, len(t))
    channel = s.sensor_channel
    yield from _encode(
        db.get_message_by_name("Correvit"),
        channel,
        t,
        {
            "VelX_cor": velocity["vx"],
            "VelY_cor": velocity["vy"],
            "Vel_cor": velocity["vel"],
            "Angle_cor": angle,
        },
    )
    yield from _encode(
        db.get_message_by_name("Vel_Angle"),
        channel,
        t,
        {"VelX": velocity["vx"], "VelY": velocity["vy"], "Vel": velocity["vel"], "Angle": angle},
    )
    yield from _encode(
        db.get_message_by_name("AngVelHor"),
        channel,
        t,
        {"AngVelX_hor": roll, "AngVelY_hor": zeros, "AngVelZ_hor": yaw},
    )


def _status(trace: DriveTrace, s: SensorSetup, db: Any) -> Iterator[can.Message]:
    t = _times(trace, s.status_hz)
    speed = _at(trace, t, trace.u)
    ones, zeros = np.ones(len(t)), np.zeros(len(t))
    columns = {signal.name: zeros for signal in db.get_message_by_name("Status").signals}
    columns |= {
        "SensorID": ones * 2055,
        "Temperature": ones * 35,
        "LampCurrent": ones * 1.2,
        "HeadStatus": ones,
        "TemperatureOK": ones,
        "STST": (speed < 0.1).astype(float),
        "AngleSwitchedOff": (speed < s.angle_cutoff_mps).astype(float),
        "DirectionMounting": ones,
        "DirectionMotion": ones,
    }
    yield from _encode(db.get_message_by_name("Status"), s.sensor_channel, t, columns)


def _vehicle(trace: DriveTrace, s: SensorSetup, db: Any, rng: np.random.Generator) -> Iterator[can.Message]:
    channel = s.vehicle_channel
    lag = s.vehicle_latency_s
    t_speed = _times(trace, s.speed_hz)
    speed = _at(trace, t_speed - lag - s.speed_latency_s, trace.u) * s.speed_scale * 3.6
    speed = speed + rng.normal(0.0, s.sigma_speed_kph, len(t_speed))
    yield from _encode(
        db.get_message_by_name("BrakeSysFeatures"),
        channel,
        t_speed,
        {"Veh_V_ActlBrk": speed, "VehVActlBrk_D_Qf": np.full(len(t_speed), 3.0)},
    )
    t = _times(trace, s.vehicle_hz)
    n = len(t)
    sampled = t - lag  # the values the frames at t carry
    u, r = _at(trace, sampled, trace.u), _at(trace, sampled, trace.r)
    if isinstance(trace, TwoTrackTrace):  # the body-fixed sensors feel roll and the road's slope
        ay, ax = trace.ay_accelerometer, trace.ax_accelerometer
        roll_rate = _at(trace, sampled, trace.roll_rate)
    else:
        ay, ax, roll_rate = trace.ay, trace.u_dot, np.zeros(n)
    qf_ok = np.full(n, 3.0)
    yield from _encode(
        db.get_message_by_name("Yaw_Data_FD1"),
        channel,
        t,
        {
            "VehYaw_W_Actl": r
            + math.radians(s.vehicle_gyro_bias_degps)
            + rng.normal(0.0, math.radians(s.sigma_yaw_rate_degps), n),
            "VehRol_W_Actl": roll_rate,
            "VehYawWActl_D_Qf": qf_ok,
            "VehRolWActl_D_Qf": qf_ok,
        },
    )
    yield from _encode(
        db.get_message_by_name("Accel_Data_FD1"),
        channel,
        t,
        {
            "VehLat2_A_Actl": _at(trace, sampled, ay) + rng.normal(0.0, s.sigma_ay_mps2, n),
            "VehLong2_A_Actl": _at(trace, sampled, ax),
            "VehLatAActl_D_Qf": qf_ok,
            "VehLongAActl_D_Qf": qf_ok,
        },
    )
    yield from _encode(
        db.get_message_by_name("SteeringPinion_Data"),
        channel,
        t,
        {
            "StePinComp_An_Est": np.degrees(_at(trace, sampled, trace.delta)) * s.steering_ratio
            + s.steer_offset_deg,
            "StePinCompAnEst_D_Qf": qf_ok,
        },
    )
    half_track = 0.5 * s.track_m
    scale, radius = s.wheel_speed_scale, s.tyre_radius_m
    left, right = (u - r * half_track) * scale / radius, (u + r * half_track) * scale / radius
    yield from _encode(
        db.get_message_by_name("WheelSpeed"),
        channel,
        t,
        {"WhlFl_W_Meas": left, "WhlFr_W_Meas": right, "WhlRl_W_Meas": left, "WhlRr_W_Meas": right},
    )
