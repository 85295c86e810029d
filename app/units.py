"""Unit conversion of decoded signal values to the SI units the pipeline works in.

Each role has one internal unit (m/s, rad, rad/s, m/s²); the DBC's unit text (or the config's
``[units]`` entry) says what the decoded value is in. Conversions are pure factors (no offsets).
"""

import math

# Internal unit of each role.
ROLE_UNITS: dict[str, str] = {
    "vx": "m/s",
    "vy": "m/s",
    "speed": "m/s",
    "beta": "rad",
    "yaw_rate": "rad/s",
    "ay": "m/s^2",
    "steer": "rad",
    "roll_rate": "rad/s",
}

Z95 = 1.959963984540054  # the normal's 97.5 % quantile: a 95 % interval is ±Z95 standard errors

_DEG = math.pi / 180.0
G0 = 9.80665  # standard gravity, m/s² (ISO 80000-3)
_G = G0

# unit text (normalised: lower case, no spaces) -> (dimension, factor to SI)
_UNITS: dict[str, tuple[str, float]] = {
    "m/s": ("speed", 1.0),
    "mps": ("speed", 1.0),
    "km/h": ("speed", 1 / 3.6),
    "kph": ("speed", 1 / 3.6),
    "kmh": ("speed", 1 / 3.6),
    "mph": ("speed", 0.44704),
    "rad": ("angle", 1.0),
    "deg": ("angle", _DEG),
    "degree": ("angle", _DEG),
    "degrees": ("angle", _DEG),
    "°": ("angle", _DEG),
    "rad/s": ("rate", 1.0),
    "deg/s": ("rate", _DEG),
    "°/s": ("rate", _DEG),
    "degrees/s": ("rate", _DEG),
    "m/s^2": ("accel", 1.0),
    "m/s²": ("accel", 1.0),
    "m/s2": ("accel", 1.0),
    "mps2": ("accel", 1.0),
    "g": ("accel", _G),
}

_ROLE_DIMENSION = {"m/s": "speed", "rad": "angle", "rad/s": "rate", "m/s^2": "accel"}


def normalise_unit(text: str) -> str:
    return text.strip().lower().replace(" ", "")


def known_units(role: str) -> list[str]:
    """Unit texts accepted for a role, for error messages."""
    dim = _ROLE_DIMENSION[ROLE_UNITS[role]]
    return [u for u, (d, _) in _UNITS.items() if d == dim]


def si_factor(role: str, unit_text: str) -> float | None:
    """Factor that converts a value in ``unit_text`` to the role's internal unit.

    Returns None when the unit is unknown or of the wrong dimension for the role.
    """
    entry = _UNITS.get(normalise_unit(unit_text))
    if entry is None:
        return None
    dimension, factor = entry
    if dimension != _ROLE_DIMENSION[ROLE_UNITS[role]]:
        return None
    return factor
