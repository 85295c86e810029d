"""A crossing moved to the last slope the regression found, against eq. 7 in closed form."""

import math
from dataclasses import replace

import numpy as np
import pytest

from app.detect.crossings import CrossingDetector
from app.detect.line_fit import fit_line
from app.records import Crossing, SlopeLever
from app.results.crossing_slope import with_tilt
from tests.crossings import D, G, read_crossing

C2N, RADIUS = 14.0, 80.0


def crossing(tilt_in_data: tuple[float, ...], tilt_out: tuple[float, float, float, float]) -> Crossing:
    """A sweep up through u0 on a circle of a sloping pad: y = v/r = d − u²/(g·C2n) plus the
    slope's share Σ tilt_k·X_k at each sample's heading; fitted with ``tilt_out`` taken out."""
    u = np.linspace(11.5, 14.0, 600)
    r = u / RADIUS
    psi = np.cumsum(r * 0.02) + 0.4
    columns = CrossingDetector._slope_columns(u, psi, r)
    y = D - u * u / (G * C2N) + np.asarray(tilt_in_data) @ np.asarray(columns)
    y = y - np.asarray(tilt_out) @ np.asarray(columns)
    x = u * u
    fit = fit_line(x, y)
    levers = tuple((line.a, line.b) for line in (fit_line(x, column) for column in columns))
    lever = SlopeLever(fit.x_mean, fit.a, fit.b, levers, tilt_out)
    return read_crossing(fit.zero().x0, RADIUS, se=0.03, slope_corrected=any(tilt_out), slope_lever=lever)


TILT = (0.0012, -0.0008, 0.0001, 0.00005)  # a 2 % slope's pull and load transfer, C2n 14


def test_a_crossing_fitted_before_the_slope_was_known_is_moved_to_it_exactly() -> None:
    read = crossing(TILT, (0.0, 0.0, 0.0, 0.0))
    assert abs(read.c2n / C2N - 1.0) > 0.01  # the slope's pull at its headings
    moved = with_tilt(read, TILT, D, G)
    assert moved.c2n == pytest.approx(C2N, rel=1e-9) and moved.slope_corrected
    assert moved.u0_mps == pytest.approx(math.sqrt(G * C2N * D), rel=1e-9)
    assert moved.ci95[1] - moved.c2n == pytest.approx(read.ci95[1] - read.c2n, rel=1e-9)
    assert moved.slope_lever is not None and moved.slope_lever.tilt == TILT
    assert with_tilt(moved, TILT, D, G) is moved  # nothing more to move


def test_a_crossing_fitted_with_a_passing_slope_comes_back_to_none() -> None:
    """On a level pad a refit's heading-borne misfit passed for a slope while this crossing was
    fitted; the last fit finds none, and the crossing reads as if it had never been moved."""
    read = crossing((0.0, 0.0, 0.0, 0.0), TILT)
    back = with_tilt(read, (0.0, 0.0, 0.0, 0.0), D, G)
    assert back.c2n == pytest.approx(C2N, rel=1e-9) and not back.slope_corrected


def test_a_crossing_without_a_lever_is_left_as_it_is() -> None:
    read = crossing(TILT, (0.0, 0.0, 0.0, 0.0))
    bare = replace(read, slope_lever=None)
    assert with_tilt(bare, TILT, D, G) is bare
