"""Steady cornering and the sideslip's sign changes: the steady-state gate, the crossing detector and
its line fit.
"""
