"""c2n: tyre cornering stiffness (C2n) from a driving car, live on CAN."""

__version__ = "0.2.0"
