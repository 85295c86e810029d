"""The advice functions and the refusal's checks, each alone: an input that raises it, one that does not."""

import math
from collections import Counter
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from typing import Any

from app.config import Config
from app.decode.counts import FrameCounts
from app.detect.quasi_steady import Cornering
from app.detect.signs import SignVotes
from app.results import advice, refusal
from app.results.advice import Findings
from app.results.fit_groups import (
    DResult,
    FitSamples,
    ModelChoice,
    ModelFit,
    Psi0Result,
    SlopeResult,
    YawBiasResult,
)
from app.results.headline import Headline, Method
from app.results.pairing import Paired
from app.results.regression import RegressionFit
from tests.simulated import REPO
from tests.test_campaign import run_cli

FIT = RegressionFit(
    c2n=14.0,
    c2n_se=0.1,
    c2n_ci95=(13.8, 14.2),
    samples=FitSamples(
        count=5000,
        blocks=200,
        ay_range_mps2=(1.0, 4.0),
        curvature_range_per_m=(0.01, 0.02),
        speed_range_mps=(8.0, 17.0),
    ),
    d=DResult(m=1.2, ci95_m=(1.1, 1.3)),
    psi0=Psi0Result(rad=0.0, ci95_rad=(-0.001, 0.001)),
    models=ModelChoice(
        chosen="linear", softening_t=0.3, linear=ModelFit(14.0, None), softening=ModelFit(14.0, None)
    ),
)
HEADLINE = Headline(14.0, (13.8, 14.2), Method.REGRESSION)
FLIPPED = SignVotes(ay_with=0, ay_against=200, steer_with=0, steer_against=200)  # a_y and steering against
AGREED = SignVotes(ay_with=200, ay_against=0, steer_with=200, steer_against=0)


def _findings(config: Config, fit: RegressionFit | None = FIT, **kwargs: Any) -> Findings:
    return Findings(config=config, result_fit=fit, regression=fit, **kwargs)


def test_slope_says_where_the_pad_falls(config: Config) -> None:
    sloped = replace(FIT, slope=SlopeResult(pct=2.0, ci95_pct=(1.5, 2.5), downhill_deg=-30.0, tilt=None))
    said = advice.slope(_findings(config, sloped))
    assert said is not None
    assert said.startswith("the test pad slopes 2.0 % [1.5, 2.5] (falling 30° right of the start heading)")
    assert "pair left and right circles, or find a level pad" in said


def test_slope_within_its_noise_or_gentle_says_nothing(config: Config) -> None:
    noisy = replace(FIT, slope=SlopeResult(pct=2.0, ci95_pct=(-0.1, 4.1), downhill_deg=10.0, tilt=None))
    gentle = replace(FIT, slope=SlopeResult(pct=0.5, ci95_pct=(0.3, 0.7), downhill_deg=10.0, tilt=None))
    assert advice.slope(_findings(config, noisy)) is None
    assert advice.slope(_findings(config, gentle)) is None
    assert advice.slope(_findings(config, FIT)) is None


def test_no_fit_to_speak_of_where_a_sign_is_wrong(config: Config) -> None:
    sloped = replace(FIT, slope=SlopeResult(pct=2.0, ci95_pct=(1.5, 2.5), downhill_deg=30.0, tilt=None))
    assert advice.slope(_findings(config, sloped)) is not None
    assert advice.slope(_findings(config, sloped, sign_problem="a role the wrong way round")) is None


def test_yaw_bias_clear_of_zero(config: Config) -> None:
    biased = replace(FIT, yaw_bias=YawBiasResult(degps=0.30004, ci95_degps=(0.1, 0.5)))
    assert advice.yaw_bias(_findings(config, biased)) == (
        "the yaw rate reads +0.300 °/s [+0.100, +0.500] high: the quasi-steady fit takes it out of "
        "C2n (on corners turning mostly one way it would lean on it); zero the gyro at standstill "
        "before the drive"
    )


def test_yaw_bias_within_its_noise_says_nothing(config: Config) -> None:
    unsure = replace(FIT, yaw_bias=YawBiasResult(degps=0.2, ci95_degps=(-0.1, 0.5)))
    assert advice.yaw_bias(_findings(config, unsure)) is None
    assert advice.yaw_bias(_findings(config, FIT)) is None


def test_crossings_apart_from_the_regression(config: Config) -> None:
    # 15/(1 ± 1.96·0.2/15), the reading a share of C2n (combine.ratio_ci95): clear of 13.8–14.2
    paired = Paired(15.0, 0.2, None, None, None, None, {}, 4, 1.0)
    said = advice.crossings_apart(_findings(config, paired=paired, headline=HEADLINE))
    assert said is not None
    assert said.startswith(
        "the paired crossings read 15.000 [14.618, 15.403], apart from the regression's 14.000"
    )
    assert said.endswith("the regression's C2n is the result")


def test_crossings_that_meet_the_regression_say_nothing(config: Config) -> None:
    near = Paired(14.3, 0.2, None, None, None, None, {}, 4, 1.0)
    far = Paired(15.0, 0.2, None, None, None, None, {}, 4, 1.0)
    assert advice.crossings_apart(_findings(config, paired=near, headline=HEADLINE)) is None
    quasi = Headline(14.0, (13.8, 14.2), Method.QUASI_STEADY)  # not the regression's headline
    assert advice.crossings_apart(_findings(config, paired=far, headline=quasi)) is None


def test_head_yawed(config: Config) -> None:
    yawed = Paired(14.0, 0.2, math.radians(0.5), math.radians(0.1), None, None, {}, 4, 1.0)
    said = advice.head_yawed(_findings(config, paired=yawed))
    assert said is not None and said.startswith("the sensor head looks yawed by +0.50°")
    straight = Paired(14.0, 0.2, math.radians(0.05), math.radians(0.01), None, None, {}, 4, 1.0)
    assert advice.head_yawed(_findings(config, paired=straight)) is None


def test_d_disagrees_with_the_config(config: Config) -> None:
    far = replace(FIT, d=DResult(m=config.d_m + 0.5, ci95_m=(config.d_m + 0.4, config.d_m + 0.6)))
    said = advice.d_disagrees(_findings(config, far))
    assert said is not None and "check sensor_ahead_of_rear_axle_m" in said
    near = replace(FIT, d=DResult(m=config.d_m, ci95_m=(config.d_m - 0.1, config.d_m + 0.1)))
    assert advice.d_disagrees(_findings(config, near)) is None


def test_a_d_apart_from_the_tape_is_not_said_to_rest_on_it(config: Config) -> None:
    """A fit whose d lies apart from the config's (the warning above says so) does not rest on
    the tape, whatever its information: the two warnings said opposite things of one drive."""
    weak = DResult(m=config.d_m, ci95_m=(config.d_m - 0.01, config.d_m + 0.01), information=0.7)
    said = advice.d_from_tape(_findings(config, replace(FIT, d=weak)))
    assert said is not None and "rests on the config's" in said
    apart = replace(weak, m=config.d_m + 0.39, ci95_m=(config.d_m + 0.38, config.d_m + 0.40))
    assert advice.d_from_tape(_findings(config, replace(FIT, d=apart))) is None
    assert advice.d_disagrees(_findings(config, replace(FIT, d=apart))) is not None


def test_no_sign_change_found(config: Config) -> None:
    sensed = FrameCounts(role_frames=Counter(dict.fromkeys(config.roles, 100)))
    said = advice.no_crossing(_findings(config, None, started=True, frames=sensed))
    assert said == (
        "no sideslip sign change was found in steady cornering: sweep the speed through u0 on a circle"
    )
    assert advice.no_crossing(_findings(config, None, started=True, crossings=3, frames=sensed)) is None
    assert advice.no_crossing(_findings(config, None, frames=sensed)) is None  # no frame at all
    # a vehicle bus without the optical sensor: no sideslip to change sign (its error names the role)
    assert advice.no_crossing(_findings(config, None, started=True)) is None


def test_a_quasi_steady_estimate_says_it_is_extrapolated_and_what_its_interval_counts(config: Config) -> None:
    quasi = Headline(14.0, (13.8, 14.2), Method.QUASI_STEADY)
    marginal = replace(FIT, estimator="marginal")
    said = advice.no_crossing(_findings(config, marginal, headline=quasi))
    assert said is not None
    assert "the corners' curve from 1.0 m/s² extrapolated to zero lateral acceleration" in said
    assert "its interval counts the samples' noise and the softening's spread under its prior" in said
    assert advice.TRACK_LAPS in said
    cascade = advice.no_crossing(_findings(config, replace(FIT, estimator="cascade"), headline=quasi))
    assert cascade is not None and "the samples' noise, not the model's reach" in cascade


def test_multi_line_advice_and_the_registry_order(config: Config) -> None:
    both = replace(
        FIT,
        slope=SlopeResult(pct=2.0, ci95_pct=(1.5, 2.5), downhill_deg=30.0, tilt=None),
        yaw_bias=YawBiasResult(degps=0.3, ci95_degps=(0.1, 0.5)),
    )
    heard = FrameCounts(role_frames=Counter(dict.fromkeys(config.roles, 1)))  # every role had frames
    said = advice.advise(_findings(config, both, frames=heard, crossings=2, rejections=1))
    assert [line.split(" ")[1] for line in said] == ["test", "yaw", "sign"]  # slope, yaw bias, rejected
    assert said[-1] == "1 sign changes not used (see 'rejected_crossings')"
    assert advice.ADVICE.index(advice.slope) < advice.ADVICE.index(advice.yaw_bias)
    assert advice.advise(_findings(config, both), (advice.values_dropped,)) == []


# the refusal's checks: snapshot.py delegates to these


def test_sign_problem_where_the_fit_puts_the_sensor_behind_the_axle() -> None:
    behind = replace(FIT, c2n=-14.0, c2n_ci95=(-14.2, -13.8), d=DResult(m=-1.2, ci95_m=(-1.3, -1.1)))
    said = refusal.sign_problem(behind, behind, FLIPPED)
    assert said is not None
    assert said.startswith(
        "the sideslip and the yaw rate disagree in sign (the regression puts the sensor 1.20 m behind the "
        "rear axle): the yaw rate is the one"
    )


def test_no_sign_problem_where_the_fit_and_votes_agree() -> None:
    assert refusal.sign_problem(FIT, FIT, AGREED) is None
    assert refusal.sign_problem(None, None, FLIPPED) is None


def test_sign_problem_where_c2n_is_not_positive() -> None:
    negative = replace(FIT, c2n=-3.0, c2n_ci95=(-3.5, -2.5))
    said = refusal.sign_problem(negative, negative, AGREED)
    assert said is not None and said.startswith("the regression's C2n is -3.00, not positive")


def test_held_d_leaves_the_votes_to_show_a_flipped_yaw_rate() -> None:
    held = replace(FIT, d=DResult(m=1.2, ci95_m=(1.2, 1.2), held=True))
    assert not refusal.d_witnessed(held)
    said = refusal.sign_problem(held, held, FLIPPED)
    assert said is not None and said.startswith("the yaw rate turns against")
    assert refusal.sign_problem(held, held, AGREED) is None


def test_pooled_drives_that_disagree() -> None:
    one = replace(FIT, c2n=14.0, c2n_ci95=(13.8, 14.2))
    other = replace(FIT, c2n=16.0, c2n_ci95=(15.8, 16.2))
    said = refusal.drives_disagree(FIT, FIT, (one, other))
    assert said == (
        "the drives pooled disagree, each alone: drive 1 14.000 [13.800, 14.200]; drive 2 16.000 "
        "[15.800, 16.200] — not one car on one set of tyres (a tyre change, pressures, temperatures?): "
        "analyse them apart"
    )
    assert refusal.drives_disagree(FIT, None, (one, other)) is None  # not the quasi-steady fit: no pool
    assert refusal.drives_disagree(FIT, FIT, (one, replace(one, c2n=14.05))) is None


def test_refusal_names_the_manoeuvre_lacked() -> None:
    nothing = refusal.refusal(None, None, None, None, Cornering())
    assert nothing.startswith("no cornering in the drive")
    some = refusal.refusal(
        None, None, None, None, Cornering(turning_s=60.0, ay_high_s=20.0, transient_s=30.0, usable_s=10.0)
    )
    assert some.startswith("no sideslip sign change and too little quasi-steady cornering: of 60 s cornering")
    assert refusal.refusal("sign", "apart", None, None, Cornering()) == "sign"  # the sign first


def test_a_filter_whose_process_noise_the_config_raised_is_named_beside_the_driving() -> None:
    """`[filter] q_v = 1e6` (helper-32): the filter's rates follow the sensor's noise, all 139 s of
    cornering read as changing too fast, and only the driving was blamed."""
    from app.config import FilterSettings, raised_noise

    raised = raised_noise(FilterSettings(q_v=1e6, q_u=1e-3))
    assert raised == ("[filter] q_v = 1e+06 (default 0.02)",)  # a lowered one is not this
    assert raised_noise(FilterSettings()) == ()
    shaky = Cornering(turning_s=139.0, transient_s=139.0)
    said = refusal.refusal(None, None, None, None, shaky, raised_noise=raised)
    assert (
        "— the config raises the filter's process noise ([filter] q_v = 1e+06 (default 0.02)): its rates"
        in said
    )
    assert said.endswith("corners held at 1–4 m/s² at several speeds")
    assert "process noise" not in refusal.refusal(
        None, None, None, None, shaky
    )  # at its default: the driving
    steady_enough = Cornering(turning_s=139.0, transient_s=60.0, ay_high_s=79.0)
    assert "process noise" not in refusal.refusal(None, None, None, None, steady_enough, raised_noise=raised)


def test_quasi_steady_cornering_at_one_a_y_is_told_as_that_not_as_too_little() -> None:
    """A 30 s window of circles at one speed: 29 s quasi-steady, but all at one a_y, where C2n is
    the slope over a_y: it said "too little quasi-steady cornering … 29 s quasi-steady"."""
    one_ay = Cornering(
        turning_s=30.0, transient_s=1.0, usable_s=29.0, usable_ay_mps2=(2.93, 3.08), usable_samples=2900
    )
    said = refusal.refusal(None, None, None, None, one_ay)
    assert said.startswith("no sideslip sign change and quasi-steady cornering at one a_y only: of 30 s")
    assert (
        "29 s quasi-steady, all at a_y 2.9–3.1 m/s² where a fit needs 0.5 m/s² between its least and most"
        in said
    )
    assert "too little" not in said
    for short in (  # a_y enough, samples not; and a few samples, at one a_y as few are
        replace(one_ay, usable_s=1.5, usable_ay_mps2=(1.0, 3.0), usable_samples=150),
        replace(one_ay, usable_s=0.2, usable_samples=20),
    ):
        assert refusal.refusal(None, None, None, None, short).startswith(
            "no sideslip sign change and too little quasi-steady cornering: of 30 s"
        )


def test_replay_hint() -> None:
    said = refusal.replay_hint(10.0, 10_000)
    assert said is not None and said.startswith("optical frames arrive at 1000 Hz")
    assert refusal.replay_hint(10.0, 1_000) is None  # 100 Hz: a sensor's own
    assert refusal.replay_hint(1.0, 10_000) is None  # too soon to tell a rate


def test_resting_fit_and_standing_headline() -> None:
    quasi = replace(FIT, c2n=13.0, c2n_ci95=(12.7, 13.3))
    assert refusal.resting_fit(FIT, quasi, crossed=True) is FIT
    assert refusal.resting_fit(FIT, quasi, crossed=False) is quasi
    assert refusal.standing_headline("sign", None, None, FIT, FIT, None, None, None) is None
    assert refusal.standing_headline(None, "apart", None, quasi, FIT, quasi, None, None) is None
    head = refusal.standing_headline(None, None, None, FIT, FIT, None, None, None)
    assert head == Headline(14.0, (13.8, 14.2), Method.REGRESSION)


def test_one_frame_is_one_frame_in_the_warnings(config: Config) -> None:
    """A count of one reads in the singular (it said "1 frames' values dropped")."""
    from app.estimate.motion_model import FilterCounts

    frames = FrameCounts(bad_length=1, bad_time=1, rejected=Counter({"no sensor status yet (vx)": 1}))
    one = Findings(config=config, frames=frames, filter_counts=FilterCounts(time_jumps=1))
    assert advice.values_dropped(one) == ("1 frame's values dropped: no sensor status yet (vx)",)
    assert (advice.bad_length(one) or "").startswith("1 frame not decoded")
    assert (advice.bad_time(one) or "").startswith("1 frame without a usable timestamp")
    assert advice.time_jumps(one) == "timestamps went backwards once: the filter restarted"
    two = replace(one, frames=replace(frames, rejected=Counter({"no sensor status yet (vx)": 2})))
    assert advice.values_dropped(two) == ("2 frames' values dropped: no sensor status yet (vx)",)


def test_a_lost_filter_names_the_process_noise_of_each_sensor_it_lost(config: Config) -> None:
    from app.estimate.motion_model import FilterCounts

    assert advice.filter_lost(Findings(config=config, filter_counts=FilterCounts(outliers=40))) is None
    lost = FilterCounts(lost_yaw=1, lost_speed=2)
    elsewhere = Findings(config=config, filter_counts=lost)  # a hard stop: no sample touched
    assert advice.filter_lost(elsewhere) is None
    said = advice.filter_lost(replace(elsewhere, lost_in_samples=2)) or ""
    assert said.startswith("the filter lost the car 3 times (vehicle speed 2, yaw 1:")
    assert "then believed), and in 2 samples of the cornering C2n is measured on:" in said
    assert "raise [filter] q_r (0.5), q_u (0.05), or check" in said  # the defaults: no "default" said
    assert advice.filter_lost(replace(elsewhere, lost_in_samples=2, backwards=True)) is None  # vx's sign
    gated = replace(config, filter=replace(config.filter, innovation_gate=4.0, q_r=1e-4))
    one = Findings(config=gated, filter_counts=FilterCounts(lost_yaw=1), lost_in_samples=1)
    said = advice.filter_lost(one) or ""
    assert "the filter lost the car 1 time (yaw 1:" in said
    assert "raise [filter] innovation_gate (4; default 30), or check" in said  # not q_r: the gate first


def test_a_loss_in_the_samples_refuses_c2n_only_where_the_config_slowed_that_sensor_s_filter() -> None:
    """No C2n where the filter lost the car in the samples and the config lowered the process
    noise that follows that sensor (or narrowed the gate): its lag moved C2n by what the drive
    cannot tell. At the defaults a loss there (a sensor's glitch) leaves the C2n, said beside it."""
    from app.config import FilterSettings, lowered_filter
    from app.estimate.motion_model import FilterCounts
    from app.snapshot import FilterState
    from app.snapshot import lagged as snapshot_lagged

    def lagged(lost: FilterCounts, settings: FilterSettings, in_samples: int = 5) -> bool:
        return snapshot_lagged(FilterState(lost, 1.0, {}, in_samples), lowered_filter(settings))

    slow_u = FilterSettings(q_u=1e-6)
    assert lagged(FilterCounts(lost_vx=9), slow_u)
    assert lagged(FilterCounts(lost_speed=9), slow_u)  # q_u follows the vehicle speed too
    assert not lagged(FilterCounts(lost_vx=9), FilterSettings())  # the defaults: a glitch
    assert not lagged(FilterCounts(lost_yaw=9), slow_u)  # q_r follows the yaw rate: not lowered
    assert not lagged(FilterCounts(lost_vx=9), slow_u, in_samples=0)  # lost elsewhere
    assert lagged(FilterCounts(lost_yaw=9), FilterSettings(innovation_gate=4.0))  # a narrow gate: any
    assert lowered_filter(FilterSettings(q_v=1e6)) == {}


def test_a_vehicle_speed_reading_high_is_named_not_the_filter_s_q_u(config: Config) -> None:
    """A speedometer's reading (+10 % + 4 km/h, inside what the unit check allows) lost the car
    178 times and the warning said raise q_u; C2n moved 0.04 %. Now its ratio and scale."""
    from app.estimate.motion_model import FilterCounts

    lost = Findings(
        config=config, filter_counts=FilterCounts(lost_speed=178), lost_in_samples=178, speed_reads=1.14
    )
    said = advice.filter_lost(lost) or ""
    assert (
        "while the vehicle speed reads 1.14 × the optical vx (a speedometer's reading, or a scale off)"
        in said
    )
    assert f"set [roles] speed's scale = {1 / 1.14:.3g}, or leave the role out" in said and "q_u" not in said
    assert "q_u" in (advice.filter_lost(replace(lost, speed_reads=None)) or "")


def test_a_drive_backwards_more_than_it_cornered_forwards_is_a_sign_not_a_manoeuvre() -> None:
    said = refusal.refusal(None, None, None, None, Cornering(backwards_s=100.4))
    assert said.startswith("the optical speed reads backwards (100 s cornering backwards, 0 s forwards)")
    assert "set [roles] vx's scale = -1 (and vy's" in said
    flipped = refusal.refusal(None, None, None, None, Cornering(backwards_s=100.4), vx_scale=-1.0)
    assert "set [roles] vx's scale = 1 (and vy's" in flipped  # already -1: the fix turns it back
    reversed_to_park = Cornering(turning_s=60.0, usable_s=40.0, backwards_s=20.0)  # a test drive's own
    assert "backwards" not in refusal.refusal(None, None, None, None, reversed_to_park)
    assert refusal.reads_backwards(0.9, 0.0) is None  # under a second: a roll back at the start


def test_a_config_s_least_speed_above_all_the_cornering_is_blamed_not_the_driving() -> None:
    """`speed_min_mps = 100` (or 40, meant as km/h) on a drive at 8–17 m/s: `no cornering in the
    drive: drive steady circles …`, the driver told to drive again. Now the config is named; at
    the default least speed a drive too slow for the method is still the driving's."""
    slow = Cornering(below_speed_s=138.7)
    said = refusal.refusal(None, None, None, None, slow, speed_min_mps=100.0)
    assert said.startswith("no cornering above [detector] speed_min_mps = 100 m/s in the config, 139 s of")
    assert "lower speed_min_mps (default 4; in m/s, not km/h)" in said
    assert refusal.refusal(None, None, None, None, slow).startswith("no cornering in the drive: drive steady")
    partly = Cornering(turning_s=30.0, transient_s=30.0, below_speed_s=100.0)
    some = refusal.refusal(None, None, None, None, partly, speed_min_mps=12.0)
    assert "of 30 s cornering (100 s more under the config's speed_min_mps 12 m/s)," in some
    assert refusal.speed_min_problem(partly, 12.0) is None


def test_a_config_s_least_speed_above_the_drive_is_said_once_and_the_driving_not_blamed(
    drive_log: Path, write_config: Callable[..., Path]
) -> None:
    text = (REPO / "config" / "mondeo.toml").read_text().replace('"../dbc/', '"{dbc}/')
    config = write_config(text + "\n[detector]\nspeed_min_mps = 100\n")
    code, out, err = run_cli(["analyze", str(drive_log), "--config", str(config)])
    assert code == 0 and "C2n: no result (no cornering above [detector] speed_min_mps = 100 m/s" in out, out
    assert "sweep the speed" not in out + err and "drive steady" not in out + err
    code, out, err = run_cli(["gap", str(drive_log), "--config", str(config)])
    assert code == 1 and "no cornering above [detector] speed_min_mps = 100 m/s in the config" in err, err
    assert "no steady cornering near" not in err and "drive constant-radius" not in err
    # above u0 but under the fastest cornering: analyze names the seconds under it; gap named the driving
    config = write_config(text + "\n[detector]\nspeed_min_mps = 16.5\n")
    code, out, err = run_cli(["gap", str(drive_log), "--config", str(config)])
    assert code == 1 and "lies under [detector] speed_min_mps = 16.5 m/s in the config" in err, err
    assert "drive constant-radius" not in err


def test_a_filter_lost_in_the_samples_is_the_reason_before_any_sign_read_from_them() -> None:
    """q_u = 1e-6 on track laps read `the sideslip and the yaw rate disagree in sign … check
    scale of vy and beta`: the signs were the lagging filter's."""
    said = refusal.refusal(
        "the sideslip and the yaw rate disagree", None, None, None, Cornering(), lost_in_samples=760
    )
    assert said.startswith("the filter lost the car in 760 of the samples C2n is measured on:")
    assert refusal.refusal("sign", None, None, None, Cornering()) == "sign"
