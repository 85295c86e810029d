"""The effects the method measured (app.gap.method_effects) against their closed forms: a rear
steer from the axle's C2n against the tyre's, d from the regression against the tape, the a_y³
softening at the crossings."""

import math
from dataclasses import replace
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from app.config import Config, load_config
from app.gap.method_effects import (
    BY_PAIRING,
    BY_REGRESSION,
    BY_RIG,
    HELDOUT_FIT,
    method_effects,
    with_method_effects,
)
from app.gap.result import C2nEffect, Effect
from app.results.fit_groups import DResult, SofteningResult

G = 9.81


def _config(rig: float = 16.4, tolerance: float = 5.0, tape: float = 0.8) -> Config:
    config = load_config()
    return replace(
        config,
        tyres=replace(config.tyres, c2n_per_rad=rig, c2n_tolerance_pct=tolerance),
        vehicle=replace(config.vehicle, sensor_ahead_of_rear_axle_m=tape, gravity_mps2=G),
    )


def _measured(
    headline: float = 16.4,
    ci: tuple[float, float] = (16.1, 16.7),
    d: float = 0.8,
    d_ci: tuple[float, float] = (0.79, 0.81),
    s: float | None = None,
    s_se: float | None = None,
    crossing_ay: tuple[float, ...] = (2.0,),
    head_deg: float | None = None,
    radius_m: float = 60.0,
) -> Any:
    fit = SimpleNamespace(
        c2n=headline,
        d=DResult(m=d, ci95_m=d_ci),
        softening=None if s is None else SofteningResult(s, s_se or 0.0),
        models=SimpleNamespace(chosen="softening" if s is not None else "linear"),
    )
    paired = (
        None
        if head_deg is None
        else SimpleNamespace(
            misalignment_deg=head_deg, misalignment_ci95_deg=(head_deg - 0.002, head_deg + 0.002)
        )
    )
    summary = SimpleNamespace(c2n=headline, c2n_ci95=ci, c2n_method="regression", paired=paired)
    ay = np.linspace(0.0, 4.0, 401)
    return SimpleNamespace(
        regression=fit,
        summary=summary,
        crossings=tuple(SimpleNamespace(ay_mps2=a, radius_m=radius_m) for a in crossing_ay),
        ay=ay,
    )


def _one(effects: list[Effect], name: str) -> Effect:
    (found,) = [e for e in effects if e.effect == name]
    return found


def test_an_axle_stiffer_than_its_tyre_is_a_rear_steer_into_the_turn_of_the_closed_form_size() -> None:
    effects = method_effects(_measured(headline=18.06, ci=(17.76, 18.36)), _config(rig=16.4))
    roll = _one(effects, "roll_steer")
    k_deg = math.degrees((1 / 16.4 - 1 / 18.06) / G)  # 1/C2n_axle = 1/C2n_tyre − g·k
    assert roll.params["rear_steer_deg_per_mps2"] == pytest.approx(k_deg, abs=1e-5)
    low, high = roll.ci95["rear_steer_deg_per_mps2"]
    assert low < k_deg < high and low > 0
    assert roll.matters and roll.measured_by == BY_RIG and roll.channel == "c2n"
    assert roll.c2n_effect_pct.headline == pytest.approx(100 * (18.06 / 16.4 - 1), abs=1e-3)
    assert "into the turn" in roll.action


def test_an_axle_within_the_rigs_tolerance_or_a_handbooks_is_no_rear_steer() -> None:
    same = _one(method_effects(_measured(headline=16.5), _config(rig=16.4)), "roll_steer")
    assert not same.matters and same.judged.startswith("not present")
    handbook = _one(
        method_effects(_measured(headline=18.06, ci=(17.76, 18.36)), _config(rig=16.4, tolerance=20.0)),
        "roll_steer",
    )
    assert not handbook.matters  # a handbook's ±20 % holds a 10 % difference


def test_d_placed_by_the_regression_away_from_the_tape_is_a_position_error_moving_single_crossings() -> None:
    effects = method_effects(_measured(d=0.664, d_ci=(0.652, 0.675)), _config(tape=0.8))
    d = _one(effects, "sensor_position_error")
    assert d.params["d_error_m"] == pytest.approx(0.664 - 0.8)
    assert d.ci95["d_error_m"] == pytest.approx((0.652 - 0.8, 0.675 - 0.8), abs=2e-3)
    # a crossing reads u0²/(g·tape), the car's C2n is u0²/(g·d)
    assert d.c2n_effect_pct.crossing == pytest.approx(100 * (0.664 / 0.8 - 1), abs=1e-3)
    assert d.c2n_effect_pct.headline == 0.0  # the regression places d itself
    assert d.matters and d.measured_by == BY_REGRESSION


def test_d_within_its_interval_of_the_tape_or_held_at_it_is_no_finding() -> None:
    near = _one(method_effects(_measured(d=0.797, d_ci=(0.786, 0.808)), _config()), "sensor_position_error")
    assert not near.matters
    held = _measured(d=0.7, d_ci=(0.7, 0.7))
    held.regression.d = replace(held.regression.d, held=True)
    assert not [e for e in method_effects(held, _config()) if e.effect == "sensor_position_error"]


def test_softening_moves_a_crossing_at_a_y_by_its_closed_form() -> None:
    s, ay = 0.0035, (1.5, 2.5)
    soft = _one(
        method_effects(_measured(s=s, s_se=0.0005, crossing_ay=ay), _config()), "load_transfer_nonlinearity"
    )
    expected = np.mean([-100 * s * a * a / (1 + s * a * a) for a in ay])  # C2n/(1 + s·a_y²)
    assert soft.c2n_effect_pct.crossing == pytest.approx(expected, abs=1e-3)
    assert soft.params["rear_softening_pct_at_3mps2"] == pytest.approx(100 * s * 9)
    assert soft.matters
    faint = _one(method_effects(_measured(s=0.0004, s_se=0.0005), _config()), "load_transfer_nonlinearity")
    assert not faint.matters


def _fitted(name: str, matters: bool) -> Effect:
    return Effect(
        effect=name,
        channel="sideslip",
        params={"x": 1.0},
        ci95={"x": (0.5, 1.5)},
        shrink_heldout=0.5,
        heldout_before=0.04,
        heldout_after=0.02,
        gain_sigmas=3.0,
        c2n_effect_pct=C2nEffect(1.0, 0.0),
        matters=matters,
        judged="matters" if matters else "within tolerance",
        confounded_with=(),
        action="",
    )


def test_one_entry_per_effect_a_held_out_finding_kept_the_largest_finding_first() -> None:
    config = _config(tape=0.8)
    measured = method_effects(_measured(d=0.664, d_ci=(0.652, 0.675), headline=16.45), config)
    fitted = [_fitted("sensor_yaw_misalignment", True), _fitted("sensor_position_error", False)]
    merged = with_method_effects(fitted, measured, lead_importance=2.0, config=config)
    names = [e.effect for e in merged]
    assert len(names) == len(set(names))
    assert merged[0].effect == "sensor_position_error" and merged[0].measured_by == BY_REGRESSION  # −17 %
    assert merged[1].effect == "sensor_yaw_misalignment" and merged[1].measured_by == HELDOUT_FIT
    # d is the regression's own parameter: its measurement replaces even a held-out finding (which
    # sees d only through what the calibrated C2n leaves); an offset the held-out fit proved keeps
    # the fit's entry, with its held-out gap
    offset = method_effects(_measured(head_deg=0.3), config)
    proven = [_fitted("sensor_position_error", True), _fitted("sensor_yaw_misalignment", True)]
    merged = with_method_effects(proven, measured + offset, 2.0, config)
    by = {e.effect: e.measured_by for e in merged}
    assert by["sensor_position_error"] == BY_REGRESSION and by["sensor_yaw_misalignment"] == HELDOUT_FIT


def test_the_pairings_offset_is_a_head_yaw_or_ply_steer_moving_single_crossings_by_r_psi_over_d() -> None:
    effects = method_effects(_measured(head_deg=0.3, radius_m=60.0), _config(tape=0.8))
    head = _one(effects, "sensor_yaw_misalignment")
    assert head.params["misalignment_deg"] == pytest.approx(0.3) and head.measured_by == BY_PAIRING
    assert head.confounded_with == ("tyre_ply_steer",)
    # a crossing on R reads C2n·(1 ± R·ψ/d), left and right opposite; pairing cancels it
    assert head.c2n_effect_pct.crossing == pytest.approx(100 * 60.0 * math.radians(0.3) / 0.8, abs=1e-3)
    assert head.c2n_effect_pct.headline == 0.0 and head.matters and "left" in head.action
    nothing = _one(method_effects(_measured(head_deg=0.0005), _config()), "sensor_yaw_misalignment")
    assert not nothing.matters
