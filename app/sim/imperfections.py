"""A real test day's imperfections, beside a session's one effect: every drive has them.

The sensors' own errors (a gyro's bias and scale, the steering wheel's centre offset, the
steering ratio the car really has), tyres a few per cent off the values the simulator was
given, and sensor rates as they come. ``c2n gap`` calibrates these (docs/gap.md); they are not
effects. The ranges are those of a well-kept car on a quiet test day.

| imperfection                      | drawn from               |
|-----------------------------------|--------------------------|
| sensor gyro bias                  | ±0.02–0.08 °/s           |
| sensor gyro scale                 | ±0.5 %                   |
| vehicle gyro bias                 | ±0.02–0.08 °/s           |
| steering-wheel centre offset      | ±0.5–2°                  |
| steering ratio (the car's)        | the config's ±3 %        |
| C1n, C2n (the car's tyres)        | the nominal ±2–5 %       |
| optical / vehicle / speed rates   | 50–250 / 50–100 / 20–50 Hz |
"""

from dataclasses import dataclass
from typing import Any

import numpy as np

_OPTICAL_HZ = (50.0, 100.0, 200.0, 250.0)
_VEHICLE_HZ = (50.0, 100.0)
_SPEED_HZ = (20.0, 50.0)


@dataclass(frozen=True)
class Imperfections:
    gyro_bias_degps: float = 0.0  # the sensor's yaw gyro reads this much high ...
    gyro_scale: float = 1.0  # ... and this many times the true rate
    vehicle_gyro_bias_degps: float = 0.0
    steer_offset_deg: float = 0.0  # the steering wheel reads this with the wheels straight
    steering_ratio_error: float = 0.0  # the car's ratio is the config's × (1 + this)
    c1n_error: float = 0.0  # the car's tyres: the nominal C1n × (1 + this)
    c2n_error: float = 0.0
    optical_hz: float | None = None  # None: the sensor model's default
    vehicle_hz: float | None = None
    speed_hz: float | None = None

    def sensor(self, config_ratio: float) -> dict[str, Any]:
        """Overrides of the sensor model (app.sim.sensors.SensorSetup)."""
        rates = {"optical_hz": self.optical_hz, "vehicle_hz": self.vehicle_hz, "speed_hz": self.speed_hz}
        return {
            "gyro_bias_degps": self.gyro_bias_degps,
            "gyro_scale": self.gyro_scale,
            "vehicle_gyro_bias_degps": self.vehicle_gyro_bias_degps,
            "steer_offset_deg": self.steer_offset_deg,
            "steering_ratio": config_ratio * (1.0 + self.steering_ratio_error),
        } | {name: hz for name, hz in rates.items() if hz is not None}


NO_IMPERFECTIONS = Imperfections()


def draw_imperfections(rng: np.random.Generator) -> Imperfections:
    """One test day's imperfections: magnitudes uniform in their ranges, signs at random."""

    def signed(low: float, high: float) -> float:
        return float(rng.uniform(low, high)) * (1.0 if rng.random() < 0.5 else -1.0)

    return Imperfections(
        gyro_bias_degps=signed(0.02, 0.08),
        gyro_scale=1.0 + signed(0.0, 0.005),
        vehicle_gyro_bias_degps=signed(0.02, 0.08),
        steer_offset_deg=signed(0.5, 2.0),
        steering_ratio_error=signed(0.0, 0.03),
        c1n_error=signed(0.02, 0.05),
        c2n_error=signed(0.02, 0.05),
        optical_hz=float(rng.choice(_OPTICAL_HZ)),
        vehicle_hz=float(rng.choice(_VEHICLE_HZ)),
        speed_hz=float(rng.choice(_SPEED_HZ)),
    )


STREAM = 0x1A9E4F  # a session's imperfections are drawn from [seed, STREAM]: apart from its noise


def of_session(seed: int) -> Imperfections:
    """The imperfections of the session (or pack case) with this seed."""
    return draw_imperfections(np.random.default_rng([seed, STREAM]))


HANDBOOK_SPREAD = 0.2  # a handbook's C1n and C2n against the car's: ± this share


def handbook(
    rng: np.random.Generator, c1n: float, c2n: float, spread: float = HANDBOOK_SPREAD
) -> tuple[float, float]:
    """Nominal C1n and C2n as a handbook or a rig would give them: each the car's own perturbed
    independently by a uniform ±``spread``."""
    return (
        c1n * (1.0 + float(rng.uniform(-spread, spread))),
        c2n * (1.0 + float(rng.uniform(-spread, spread))),
    )
