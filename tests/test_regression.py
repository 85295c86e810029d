"""The every-sample regression against eq. 6 (with offset and softening) in closed form."""

import dataclasses
import math
from typing import Any

import numpy as np
import pytest

from app import paper
from app.results.regression import SampleRegression
from app.units import Z95

G = 9.81


def sweep_samples(
    c2n: float, d: float, psi0: float, radii: tuple[float, ...], softening: float = 0.0, hz: float = 50.0
):
    """(t, u, r, v) for speed sweeps up and down on each signed radius, with the sideslip at the
    sensor β = ψ0 + d·κ − α2, α2 = a_y/(g·C2n)·(1 + s·a_y²) (eq. 6 with offset and softening)."""
    u0 = paper.crossing_speed(c2n, d, G)
    t = 0.0
    for radius in radii:
        speeds = np.concatenate(
            [np.linspace(0.6 * u0, 1.4 * u0, int(40 * hz)), np.linspace(1.4 * u0, 0.6 * u0, int(40 * hz))]
        )
        for u in speeds:
            r = u / radius
            ay = u * r
            beta = psi0 + d * r / u - ay / (G * c2n) * (1 + softening * ay * ay)
            yield t, float(u), float(r), float(u * beta)
            t += 1.0 / hz
        t += 5.0


def fitted(samples, **kwargs):
    regression = SampleRegression(G, **kwargs)
    for t, u, r, v in samples:
        regression.add(t, u, r, v)
    return regression.fit()


def test_recovers_c2n_d_and_offset_exactly() -> None:
    fit = fitted(sweep_samples(14.99, 1.11, math.radians(-0.3), (80.0, -80.0)))
    assert fit is not None and fit.models.chosen == "linear"
    assert fit.c2n == pytest.approx(14.99, rel=1e-9)
    assert fit.d.m == pytest.approx(1.11, rel=1e-9)
    assert fit.psi0 is not None and fit.psi0.rad == pytest.approx(math.radians(-0.3), abs=1e-12)
    assert fit.samples.ay_range_mps2[1] == pytest.approx(
        (1.4 * paper.crossing_speed(14.99, 1.11)) ** 2 / 80.0, rel=1e-6
    )


def test_softening_is_found_and_c2n_is_the_slope_at_zero() -> None:
    """A tyre that softens with slip: the straight line reads low, the fit extrapolates to a_y = 0."""
    rng = np.random.default_rng(5)
    samples = [
        (t, u, r, v + rng.normal(0, 0.005))
        for t, u, r, v in sweep_samples(12.0, 1.2, 0.0, (60.0, -60.0, 120.0, -120.0), softening=0.002)
    ]
    fit = fitted(samples)
    assert fit is not None and fit.models.chosen == "softening" and fit.models.softening_t < -5
    assert fit.c2n == pytest.approx(12.0, rel=0.005)
    assert fit.softening is not None and fit.softening.per_mps2_2 == pytest.approx(0.002, rel=0.1)
    assert fit.models.linear.c2n < 0.98 * 12.0  # what ignoring it would have said


def test_each_model_has_its_own_interval_whichever_is_chosen() -> None:
    """A campaign may compare a session on the model its own fit did not choose (its tyre set's
    sessions together decide): both models' intervals are there, the chosen one's the headline's."""
    rng = np.random.default_rng(5)
    for softening, chosen in ((0.002, "softening"), (0.0, "linear")):
        samples = [
            (t, u, r, v + rng.normal(0, 0.005))
            for t, u, r, v in sweep_samples(12.0, 1.2, 0.0, (60.0, -60.0, 120.0, -120.0), softening=softening)
        ]
        fit = fitted(samples)
        assert fit is not None and fit.models.chosen == chosen
        assert fit.models.softening is not None
        assert fit.models.linear.ci95 is not None and fit.models.softening.ci95 is not None
        own, other = (
            (fit.models.softening.ci95, fit.models.linear.ci95)
            if chosen == "softening"
            else (fit.models.linear.ci95, fit.models.softening.ci95)
        )
        assert own == pytest.approx(fit.c2n_ci95, rel=1e-12)
        # each interval is about its own model's C2n
        assert sum(fit.models.linear.ci95) / 2 == pytest.approx(fit.models.linear.c2n, rel=1e-12)
        assert sum(fit.models.softening.ci95) / 2 == pytest.approx(fit.models.softening.c2n, rel=1e-12)
        assert other != own
        if chosen == "softening":  # the straight line misses the truth, the softening model holds it
            assert (
                fit.models.linear.ci95[1] < 12.0
                and fit.models.softening.ci95[0] <= 12.0 <= fit.models.softening.ci95[1]
            )
        else:  # on linear tyres both hold it, the softening model's (a term more) the wider
            width = fit.models.softening.ci95[1] - fit.models.softening.ci95[0]
            assert width > fit.models.linear.ci95[1] - fit.models.linear.ci95[0]
            assert all(
                low <= 12.0 <= high for low, high in (fit.models.linear.ci95, fit.models.softening.ci95)
            )


def test_the_sensors_scale_tolerance_widens_the_interval_by_its_share() -> None:
    """A relative error σ from the sensors' scales is in C2n's interval beside the data's:
    half-width q·√(se² + (σ·C2n)²), the estimate itself unchanged."""
    rng = np.random.default_rng(8)
    samples = [
        (t, u, r, v + rng.normal(0, 0.005))
        for t, u, r, v in sweep_samples(14.0, 1.1, 0.0, (70.0, -70.0, 140.0))
    ]
    plain, counted = fitted(samples), fitted(samples, scale_se=0.003)
    assert plain is not None and counted is not None and counted.c2n == plain.c2n
    q = (plain.c2n_ci95[1] - plain.c2n) / plain.c2n_se
    assert counted.c2n_se == pytest.approx(math.hypot(plain.c2n_se, 0.003 * plain.c2n), rel=1e-9)
    assert counted.c2n_ci95[1] - counted.c2n == pytest.approx(q * counted.c2n_se, rel=1e-9)
    assert counted.scale_se == 0.003 and plain.scale_se == 0.0
    assert counted.models.linear.ci95 is not None and plain.models.linear.ci95 is not None
    assert (
        counted.models.linear.ci95[1] - counted.models.linear.ci95[0]
        > plain.models.linear.ci95[1] - plain.models.linear.ci95[0]
    )


def test_stiffening_is_not_taken_for_softening() -> None:
    fit = fitted(sweep_samples(12.0, 1.2, 0.0, (60.0, -60.0), softening=-0.002))
    assert fit is not None and fit.models.chosen == "linear"


def test_one_direction_one_radius_cannot_tell_offset_from_d() -> None:
    fit = fitted(sweep_samples(14.0, 1.0, 0.0, (70.0,)))
    assert fit is not None and fit.psi0 is None
    assert fit.c2n == pytest.approx(14.0, rel=1e-9) and fit.d.m == pytest.approx(1.0, rel=1e-9)


def test_two_radii_one_direction_do_tell_them_apart() -> None:
    fit = fitted(sweep_samples(14.0, 1.0, math.radians(0.2), (70.0, 140.0)))
    assert (
        fit is not None
        and fit.psi0 is not None
        and fit.psi0.rad == pytest.approx(math.radians(0.2), abs=1e-12)
    )


def test_too_little_data_gives_no_fit() -> None:
    assert fitted(list(sweep_samples(14.0, 1.0, 0.0, (70.0,)))[:100]) is None


def test_merging_old_blocks_keeps_the_estimate() -> None:
    """Memory is bounded by merging the oldest blocks; the sums, so the fit, do not change."""
    rng = np.random.default_rng(2)
    samples = [
        (t, u, r, v + rng.normal(0, 0.01)) for t, u, r, v in sweep_samples(13.0, 1.1, 0.0, (80.0, -80.0))
    ]
    full = fitted(samples, max_blocks=4096)
    merged = fitted(samples, max_blocks=64)
    assert full is not None and merged is not None
    assert merged.samples.blocks <= 64 < full.samples.blocks
    assert merged.c2n == pytest.approx(full.c2n, rel=1e-12)
    assert merged.c2n_se == pytest.approx(full.c2n_se, rel=0.5)  # coarser blocks, similar honesty


def test_interval_covers_the_truth_with_autocorrelated_noise() -> None:
    covered = 0
    trials = 60
    for seed in range(trials):
        rng = np.random.default_rng(seed)
        samples = list(sweep_samples(13.0, 1.1, 0.0, (80.0, -80.0)))
        noise = np.zeros(len(samples))
        white = rng.normal(0, 0.02, len(samples))
        for i in range(1, len(noise)):
            noise[i] = 0.7 * noise[i - 1] + white[i]
        fit = fitted([(t, u, r, v + e) for (t, u, r, v), e in zip(samples, noise, strict=True)])
        assert fit is not None
        covered += fit.c2n_ci95[0] <= 13.0 <= fit.c2n_ci95[1]
    assert 0.88 <= covered / trials <= 1.0


def test_a_narrow_ay_band_that_cannot_see_softening_widens_the_interval_to_both_models() -> None:
    """Samples on one circle at 3–4 m/s² only, tyres softening 4 % at 4 m/s² (eq. 6 with
    softening, closed form): the a_y³ term is not resolved, the straight line reads low, and the
    interval must span both models; the same tyres swept from 1 m/s² resolve it."""
    rng = np.random.default_rng(0)
    c2n, d, softening = 14.0, 1.1, 0.0025

    def circle(radius: float, ay_low: float, ay_high: float, hz: float = 100.0):
        t = 0.0
        for ay in np.concatenate(
            [np.linspace(ay_low, ay_high, int(60 * hz)), np.linspace(ay_high, ay_low, int(60 * hz))]
        ):
            u = math.sqrt(ay * radius)
            beta = d / radius - ay / (G * c2n) * (1 + softening * ay * ay)
            yield t, u, u / radius, u * beta + rng.normal(0, 0.02)
            t += 1.0 / hz

    narrow = fitted(circle(30.0, 3.0, 4.0))
    assert narrow is not None and narrow.models.chosen == "linear" and not narrow.models.resolved
    assert narrow.models.hidden_pct > 3.0
    assert narrow.models.linear.c2n < 0.97 * c2n  # a confident straight line would be wrong ...
    assert narrow.c2n_ci95[0] <= c2n <= narrow.c2n_ci95[1]  # ... the widened interval holds the truth
    wide = fitted(circle(30.0, 0.5, 4.0))
    assert wide is not None and wide.models.resolved and wide.models.hidden_pct < 3.0


def circle_samples(
    c2n: float,
    d: float,
    slope: float,
    downhill_deg: float,
    radii: tuple[float, ...],
    sweep_s: float = 20.0,
    transfer: float = 0.0,
):
    """(t, u, r, v, ψ) for sweeps up and down (``sweep_s`` each) on full circles of a pad that
    slopes ``slope`` (a fraction) falling towards ``downhill_deg`` from the start heading: the
    tyres make up the slope's pull g·s·sin(D − ψ), so β = d·κ − (a_y − g_y)/(g·C2n); and the
    slope's gravity along the heading g_x = g·s·cos(D − ψ) changes the rear's give per m/s² of
    a_y by the factor 1 + ``transfer``·g_x/g (load moved between the axles)."""
    u0, hz = paper.crossing_speed(c2n, d, G), 50.0
    t, heading, downhill = 0.0, 0.0, math.radians(downhill_deg)
    for radius in radii:
        up = np.linspace(0.6 * u0, 1.4 * u0, int(sweep_s * hz))
        for u in np.concatenate([up, up[::-1]]):
            r = u / radius
            g_y = G * slope * math.sin(downhill - heading)
            softer = 1.0 + transfer * slope * math.cos(downhill - heading)
            beta = d * r / u - (u * r * softer - g_y) / (G * c2n)
            yield t, float(u), float(r), float(u * beta), heading
            t += 1.0 / hz
            heading += r / hz
        t += 5.0


def test_a_sloping_pad_is_fitted_and_taken_out_of_c2n() -> None:
    regression = SampleRegression(G)
    for t, u, r, v, heading in circle_samples(14.0, 1.2, 0.02, -90.0, (60.0, -60.0, 90.0, -90.0)):
        regression.add(t, u, r, v, heading)
    fit = regression.fit()
    assert fit is not None and fit.slope is not None
    assert fit.c2n == pytest.approx(14.0, rel=1e-9)
    assert fit.d.m == pytest.approx(1.2, rel=1e-9)
    assert fit.slope.pct == pytest.approx(2.0, rel=1e-9)
    assert fit.slope.downhill_deg == pytest.approx(-90.0, abs=1e-6)
    falling_left = SampleRegression(G)
    for t, u, r, v, heading in circle_samples(14.0, 1.2, 0.03, 45.0, (60.0, -60.0, 90.0, -90.0), 60.0):
        falling_left.add(t, u, r, v, heading)
    fit = falling_left.fit()
    assert fit is not None and fit.slope is not None and fit.slope.pct == pytest.approx(3.0, rel=1e-9)
    assert fit.slope.downhill_deg == pytest.approx(45.0, abs=1e-6)
    assert fit.c2n == pytest.approx(14.0, rel=1e-9)


def test_a_slope_s_load_transfer_is_fitted_and_leaves_c2n_as_on_the_level() -> None:
    """The slope's pull along the heading makes the rear give more going downhill than up: C2n
    is the level pad's, where leaving the a_y·sin ψ, a_y·cos ψ terms out would move it."""
    samples = list(circle_samples(14.0, 1.2, 0.03, 130.0, (60.0, -60.0, 90.0, -90.0), transfer=3.0))
    regression = SampleRegression(G)
    for t, u, r, v, heading in samples:
        regression.add(t, u, r, v, heading)
    fit = regression.fit()
    assert fit is not None and fit.slope is not None and fit.slope.pct == pytest.approx(3.0, rel=1e-9)
    assert fit.slope.downhill_deg == pytest.approx(130.0, abs=1e-6)
    assert fit.c2n == pytest.approx(14.0, rel=1e-9) and fit.d.m == pytest.approx(1.2, rel=1e-9)
    level = SampleRegression(G)
    for t, u, r, v, heading in circle_samples(14.0, 1.2, 0.0, 0.0, (60.0, -60.0, 90.0, -90.0)):
        level.add(t, u, r, v, heading)
    flat = level.fit()
    assert flat is not None and flat.c2n == pytest.approx(14.0, rel=1e-9)
    assert flat.slope is not None and flat.slope.pct == pytest.approx(
        0.0, abs=1e-6
    )  # no slope: its transfer terms stay out


def test_a_quarter_turn_of_headings_fits_no_slope() -> None:
    """Samples on one short arc: sin ψ and cos ψ barely move, the offset and d take them."""
    regression = SampleRegression(G)
    for t, u, r, v, heading in circle_samples(14.0, 1.2, 0.0, 0.0, (60.0, -60.0)):
        regression.add(t, u, r, v, heading % (math.pi / 4))
    fit = regression.fit()
    assert fit is not None and fit.slope is None


def test_the_heading_is_the_same_frame_by_frame_and_in_blocks() -> None:
    from app.results.heading import Heading

    rng = np.random.default_rng(4)
    t = np.cumsum(rng.uniform(0.004, 0.02, 500))
    r = rng.normal(0.2, 0.05, 500)
    r[rng.random(500) < 0.2] = np.nan  # frames without a yaw rate hold the heading
    one = Heading()
    expected = [one.step(float(a), None if math.isnan(b) else float(b)) for a, b in zip(t, r, strict=True)]
    blocks = Heading()
    got = np.concatenate([blocks.steps(t[k : k + 37], r[k : k + 37]) for k in range(0, 500, 37)])
    assert got.tolist() == expected  # exactly: the same additions in the same order
    steady = Heading()
    assert steady.steps(t, np.full(500, 0.3))[-1] == pytest.approx(0.3 * (t[-1] - t[0]), rel=1e-12)


def one_speed_samples(c2n: float, d: float, psi0: float, speed: float, rng: np.random.Generator):
    """(t, u, r, v) on circles of four radii, both ways, all at about one speed (±1 %): a_y = u²·κ
    then moves with κ alone, so d·κ and a_y/(g·C2n) cannot be told apart."""
    t, hz = 0.0, 50.0
    for radius in (60.0, -60.0, 90.0, -90.0, 120.0, -120.0):
        for k in range(int(30 * hz)):
            u = speed * (1.0 + 0.01 * math.sin(k / hz))
            r = u / radius
            beta = psi0 + d * r / u - u * r / (G * c2n)
            yield t, u, r, u * beta + rng.normal(0.0, 0.01)
            t += 1.0 / hz
        t += 5.0


@pytest.mark.parametrize("tolerance_mm", [10.0, 2.0])
def test_samples_at_one_speed_hold_d_at_the_tape_s_value_and_say_so(tolerance_mm: float) -> None:
    """One speed cannot place d beside C2n: the fit holds d where the config says (counting the
    tape's tolerance, ±1 cm at 95 % by default, in the interval), and the intervals hold the truth
    at about their rate — neither narrower nor wider — when the tape is as good as stated."""
    rng = np.random.default_rng(8)
    free = fitted(one_speed_samples(14.0, 1.2, math.radians(0.2), 11.0, rng))
    assert free is not None and not free.d.held  # no tape value: d fitted, and C2n barely placed
    assert free.c2n_ci95[1] - free.c2n_ci95[0] > 0.1 * 14.0
    tape_se = {} if tolerance_mm == 10.0 else {"d_tape_se_m": tolerance_mm / 1000.0 / Z95}
    covered, errors, z = 0, [], []
    for seed in range(40):
        rng = np.random.default_rng(100 + seed)
        tape = 1.2 + rng.normal(0.0, tolerance_mm / 1000.0 / Z95)  # 95 % within the tolerance
        samples = one_speed_samples(14.0, 1.2, math.radians(0.2), 11.0, rng)
        fit = fitted(samples, d_tape_m=tape, **tape_se)
        assert fit is not None and fit.d.held and fit.d.m == tape and fit.d.ci95_m == (tape, tape)
        assert fit.samples.speed_range_mps[0] == pytest.approx(11.0 * 0.99, rel=1e-3)
        covered += fit.c2n_ci95[0] <= 14.0 <= fit.c2n_ci95[1]
        errors.append(abs(fit.c2n / 14.0 - 1.0))
        z.append((fit.c2n - 14.0) / fit.c2n_se)
    assert covered >= 34  # 95 % of 40, less what chance takes
    assert 0.7 < math.sqrt(float(np.mean(np.square(z)))) < 1.3  # errors as large as the intervals say
    assert float(np.median(errors)) < 0.01 * tolerance_mm / 10.0
    assert fit.c2n_ci95[1] - fit.c2n_ci95[0] < 0.5 * (free.c2n_ci95[1] - free.c2n_ci95[0])


def test_a_speed_sweep_fits_d_even_with_a_tape_value() -> None:
    fit = fitted(sweep_samples(14.99, 1.11, math.radians(-0.3), (80.0, -80.0)), d_tape_m=1.5)
    assert fit is not None and not fit.d.held
    assert fit.d.m == pytest.approx(1.11, rel=1e-9) and fit.c2n == pytest.approx(14.99, rel=1e-9)


def _one_speed_summary(estimator: str) -> tuple[Any, dict[str, Any]]:
    """Circles at 11 m/s through the pipeline's regression (d from the config) to the summary."""
    from app.config import load_config
    from app.pipeline import Pipeline
    from app.sinks import summary

    config = load_config()
    config = dataclasses.replace(config, priors=dataclasses.replace(config.priors, estimator=estimator))
    pipeline = Pipeline(config)
    rng = np.random.default_rng(3)
    for t, u, r, v in one_speed_samples(14.0, config.d_m, 0.0, 11.0, rng):
        pipeline.regression.add(t, u, r, v)
    pipeline.finish()
    return config, summary.build(pipeline.snapshot(), config, ["one speed"]).to_json()


def test_the_summary_says_d_was_held_and_what_to_drive() -> None:
    """Through the pipeline's regression (d from the config) to the summary: the key, the speeds
    and a warning naming the config's d and the sweep that would measure it (the cascade's, which
    holds d; the marginal fit's: the next test)."""
    config, result = _one_speed_summary("cascade")
    fit = result["regression"]
    assert fit["d_fixed"] is True and fit["d_m"] == config.d_m
    assert fit["speed_range_mps"][0] == pytest.approx(10.89, abs=0.01)
    assert fit["c2n_ci95"][0] <= 14.0 <= fit["c2n_ci95"][1]
    said = [w for w in result["warnings"] if "too narrow to fit the sensor's d" in w]
    assert len(said) == 1 and f"the config's {config.d_m:g} m" in said[0] and "sweep the speed" in said[0]


def test_the_summary_says_when_the_tape_places_d_better_than_the_drive() -> None:
    """The marginal fit at one speed: d keeps the tape's prior (the drive adds nothing to it), C2n's
    interval is held open by d and counts the tape, and a warning says what C2n rests on and what
    to drive. Sweeps through u0 on two radii tell more of d than a ±10 mm tape: no warning."""
    from app.pipeline import Pipeline
    from app.sinks import summary

    config, result = _one_speed_summary("marginal")
    rng = np.random.default_rng(3)
    fit = result["regression"]
    assert fit["estimator"] == "marginal" and fit["held_open_by"] is not None and fit["d_information"] < 0.1
    assert fit["c2n_ci95"][0] <= 14.0 <= fit["c2n_ci95"][1]
    said = [w for w in result["warnings"] if "less well than the tape" in w]
    assert len(said) == 1 and f"the config's {config.d_m:g} m" in said[0] and "sweep the speed" in said[0]
    swept = Pipeline(config)
    for t, u, r, v in sweep_samples(14.0, config.d_m, 0.0, (80.0, -80.0, 40.0, -40.0)):
        swept.regression.add(t, u, r, v + u * rng.normal(scale=0.001))
    swept.finish()
    result = summary.build(swept.snapshot(), config, ["sweeps"]).to_json()
    assert result["regression"]["d_information"] > 1.0
    assert not any("less well than the tape" in w for w in result["warnings"])


def test_a_force_that_follows_the_turn_is_fitted_and_taken_out_of_c2n() -> None:
    """A rear force of 2.5 % of the axle's weight towards each turn's inside (a tyre model's
    camber step: CommonRoad's car): a sideslip step δ·sign(κ) with δ = 0.025/C2n. Left in, d·κ
    and the a_y³ term take it on three radii and C2n reads high; fitted, it comes out exactly."""
    c2n, step = 14.0, 0.025 / 14.0
    radii = (60.0, -60.0, 90.0, -90.0, 130.0, -130.0)
    samples = [
        (t, u, r, v + u * step * math.copysign(1.0, r))
        for t, u, r, v in sweep_samples(c2n, 1.1, math.radians(0.2), radii)
    ]
    fit = fitted(samples)
    assert (
        fit is not None and fit.turn_force is not None and fit.turn_force.pct == pytest.approx(2.5, rel=1e-6)
    )
    assert fit.turn_force.step_rad == pytest.approx(step, rel=1e-6)
    assert fit.c2n == pytest.approx(c2n, rel=1e-8) and fit.d.m == pytest.approx(1.1, rel=1e-8)
    assert fit.turn_force.ci95_pct[0] > 2.0


def test_no_turn_force_is_fitted_where_there_is_none() -> None:
    rng = np.random.default_rng(11)
    radii = (60.0, -60.0, 90.0, -90.0, 130.0, -130.0)
    samples = [(t, u, r, v + rng.normal(0, 0.01)) for t, u, r, v in sweep_samples(14.0, 1.1, 0.0, radii)]
    fit = fitted(samples)
    assert fit is not None and fit.turn_force is None
    assert fit.c2n == pytest.approx(14.0, rel=0.003)


def test_one_radius_each_way_cannot_tell_a_turn_force_from_d() -> None:
    """sign(κ) is d·κ's double when |κ| is one: the term is not tried, d takes the step."""
    samples = [
        (t, u, r, v + u * 0.002 * math.copysign(1.0, r))
        for t, u, r, v in sweep_samples(14.0, 1.1, 0.0, (80.0, -80.0))
    ]
    fit = fitted(samples)
    assert fit is not None and fit.turn_force is None
    assert fit.d.m == pytest.approx(1.1 + 0.002 * 80.0, rel=1e-6)


def tight_samples(
    c2n: float, d: float, psi0: float, radii: tuple[float, ...], split: float = 0.0, step: float = 0.0
):
    """(t, u, r, v) for sweeps on a small pad's radii, from 7.7 m/s up to 4 m/s² (the steady gate)
    and down: a_y never below 1.6 m/s². ``split`` mimics the two wheels of an axle on a tight turn,
    α2 = a_y/(g·C2n)·(1 + split·κ·a_y); ``step`` a sideslip step δ·sign(κ) (a turn force)."""
    t, hz = 0.0, 50.0
    for radius in radii:
        top = math.sqrt(4.0 * abs(radius))
        for u in np.concatenate([np.linspace(7.7, top, 1000), np.linspace(top, 7.7, 1000)]):
            r = u / radius
            ay, kappa = u * r, r / u
            beta = psi0 + d * kappa - ay / (G * c2n) * (1 + split * kappa * ay) + step * math.copysign(1, r)
            yield t, float(u), float(r), float(u * beta)
            t += 1.0 / hz
        t += 5.0


SMALL_PAD = (25.0, -25.0, 30.0, -30.0, 36.0, -36.0)


def test_on_radii_under_twenty_wheelbases_d_is_held_at_the_tape_s_value() -> None:
    """A tight turn's two wheels misread by a share that d·κ takes: fitted, d lands 7 mm short and
    C2n 1 % high; held at the tape's value, C2n is within 0.5 %, and the fit says how much a
    centimetre of tape moves it (its interval counts one)."""
    samples = list(tight_samples(14.0, 1.11, math.radians(0.2), SMALL_PAD, split=0.1))
    free = fitted(samples)
    assert free is not None and not free.d.held and abs(free.c2n / 14.0 - 1.0) > 0.01
    held = fitted(samples, d_tape_m=1.11, wheelbase_m=2.7)
    assert held is not None and held.d.held and held.d.held_tight and held.d.m == 1.11
    assert held.c2n == pytest.approx(14.0, rel=0.005)
    assert held.d.per_tape_cm_pct is not None and held.d.per_tape_cm_pct > 1.0
    assert held.c2n_ci95[0] <= 14.0 <= held.c2n_ci95[1]
    # a wheelbase of 1 m puts the same radii at 25–36 wheelbases: d fitted
    assert not fitted(samples, d_tape_m=1.11, wheelbase_m=1.0).d.held  # type: ignore[union-attr]
    # and wide circles keep d free where the tape is 2 cm out
    wide = fitted(
        sweep_samples(14.0, 1.11, 0.0, (70.0, -70.0, 140.0, -140.0)), d_tape_m=1.13, wheelbase_m=2.7
    )
    assert wide is not None and not wide.d.held and wide.d.m == pytest.approx(1.11, rel=1e-9)
    assert wide.samples.tight_terms == ()


def swept_pad_samples(c2n: float, d: float, psi0: float, wheels: float, transfer: float):
    """(t, u, r, v, u̇) on the small pad: each radius swept up slowly from 7.7 m/s to 4 m/s² and
    down fast, the circle left at 8.7 m/s (so the sweeps' load transfer does not cancel), with
    α2 = a_y/(g·C2n)·(1 + wheels·κ² + transfer·u̇): the axle's two wheels and the sweep's load."""
    t, hz = 0.0, 50.0
    for radius in SMALL_PAD:
        top = math.sqrt(4.0 * abs(radius))
        for speeds in (np.linspace(7.7, top, 1500), np.linspace(top, 8.7, 300)):
            u_dot = (speeds[-1] - speeds[0]) * hz / len(speeds)
            for u in speeds:
                r = u / radius
                ay, kappa = u * r, r / u
                beta = psi0 + d * kappa - ay / (G * c2n) * (1 + wheels * kappa**2 + transfer * u_dot)
                yield t, float(u), float(r), float(u * beta), float(u_dot)
                t += 1.0 / hz
        t += 5.0


def test_a_small_pad_s_two_wheels_and_its_sweeps_load_transfer_are_fitted() -> None:
    """Where d is held on a small pad the fit has the axle's two wheels (κ²·a_y) and the sweeps'
    load transfer (a_y·u̇) too: C2n exact with both in the sideslip. Without u̇ (a caller that
    never gives it) that term is not tried and its share goes into C2n; with d fitted, the two
    wheels go into d."""
    samples = list(swept_pad_samples(14.0, 1.11, math.radians(0.2), wheels=3.0, transfer=-0.07))

    def fit(with_u_dot: bool = True, **kwargs):
        regression = SampleRegression(G, **kwargs)
        for t, u, r, v, u_dot in samples:
            regression.add(t, u, r, v, u_dot=u_dot if with_u_dot else 0.0)
        return regression.fit()

    held = fit(d_tape_m=1.11, wheelbase_m=2.7)
    assert held is not None and held.d.held_tight and held.samples.tight_terms == ("ay_u_dot", "k2_ay")
    assert held.c2n == pytest.approx(14.0, rel=1e-9)
    assert held.c2n_ci95[0] <= 14.0 <= held.c2n_ci95[1]
    quasi = SampleRegression(G, d_tape_m=1.11, wheelbase_m=2.7, transient=True)  # ordinary driving's
    for t, u, r, v, u_dot in samples:  # fit: its ṙ and a_y·u̇ beside the pad's terms, none twice
        quasi.add(t, u, r, v, r_dot=u_dot * r / u, u_dot=u_dot)
    beside = quasi.fit()
    assert (
        beside is not None
        and beside.samples.transient_terms
        and beside.samples.tight_terms == ("ay_u_dot", "k2_ay")
    )
    assert beside.c2n == pytest.approx(14.0, rel=1e-9)
    blind = fit(with_u_dot=False, d_tape_m=1.11, wheelbase_m=2.7)
    assert (
        blind is not None and blind.samples.tight_terms == ("k2_ay",) and abs(blind.c2n / 14.0 - 1.0) > 0.003
    )
    free = fit()
    assert free is not None and not free.d.held and free.samples.tight_terms == ()
    assert abs(free.c2n / 14.0 - 1.0) > 0.005 and abs(free.d.m - 1.11) > 0.002
    # circles at one speed on the same radii: no sweep, so neither term (u̇ would be noise)
    regression = SampleRegression(G, d_tape_m=1.11, wheelbase_m=2.7)
    for i, radius in enumerate(np.repeat(SMALL_PAD, 1000)):
        u = 8.0 * (1.0 + 0.01 * math.sin(0.02 * i))  # ±1 %
        ay, kappa = u * u / radius, 1.0 / radius
        beta = kappa * 1.11 - ay / (G * 14.0) * (1.0 + 3.0 * kappa**2)
        regression.add(i / 50.0, u, u / radius, u * beta, u_dot=0.08 * math.cos(0.02 * i))
    circles = regression.fit()
    assert circles is not None and circles.d.held and circles.samples.tight_terms == ()


@pytest.mark.parametrize("bad", [math.nan, -1e9])
def test_a_broken_u_dot_leaves_the_sweeps_term_out_not_the_fit(bad: float) -> None:
    """One sample in a hundred with a u̇ that is not a number or absurd: the sweeps' term is left
    out and the fit still stands, C2n within 1 % and the truth in its interval."""
    regression = SampleRegression(G, d_tape_m=1.11, wheelbase_m=2.7)
    for i, (t, u, r, v, u_dot) in enumerate(swept_pad_samples(14.0, 1.11, 0.0, 3.0, -0.07)):
        regression.add(t, u, r, v, u_dot=bad if i % 97 == 0 else u_dot)
    fit = regression.fit()
    assert fit is not None and "ay_u_dot" not in fit.samples.tight_terms and math.isfinite(fit.c2n)
    assert fit.c2n == pytest.approx(14.0, rel=0.01) and fit.c2n_ci95[0] <= 14.0 <= fit.c2n_ci95[1]


def test_a_turn_force_is_found_where_no_sample_is_near_zero_a_y() -> None:
    """On a small pad every steady sample has a_y ≥ 1.6 m/s², so sign(κ) is nearly a_y's double;
    a 2.5 % turn force (CommonRoad's camber step) still shows and comes out exactly."""
    fit = fitted(tight_samples(14.0, 1.11, 0.0, SMALL_PAD, step=0.025 / 14.0), d_tape_m=1.11, wheelbase_m=2.7)
    assert (
        fit is not None and fit.turn_force is not None and fit.turn_force.pct == pytest.approx(2.5, rel=1e-6)
    )
    assert fit.c2n == pytest.approx(14.0, rel=1e-8)


def test_the_summary_says_why_d_was_held_on_a_small_pad() -> None:
    """Through the pipeline's regression (the config's d, wheelbase and tape tolerance) to the
    summary: the keys and a warning naming the radii, the share of a centimetre, the tolerance
    counted and what to do (the cascade's, which holds d there)."""
    from app.config import Calibration, load_config
    from app.pipeline import Pipeline
    from app.sinks import summary

    config = load_config()
    config = dataclasses.replace(config, priors=dataclasses.replace(config.priors, estimator="cascade"))
    pipeline = Pipeline(config)
    for t, u, r, v in tight_samples(14.0, config.d_m, 0.0, SMALL_PAD):
        pipeline.regression.add(t, u, r, v)
    pipeline.finish()
    result = summary.build(pipeline.snapshot(), config, ["small pad"]).to_json()
    fit = result["regression"]
    assert fit["d_fixed"] is True and fit["d_held_tight"] is True and fit["d_m"] == config.d_m
    assert fit["tight_terms"] == ["k2_ay"]  # u̇ not given here: the sweeps' term is not tried
    assert fit["c2n"] == pytest.approx(14.0, rel=1e-6) and fit["c2n_per_tape_cm_pct"] > 1.0
    said = [w for w in result["warnings"] if "wheelbases" in w]
    assert len(said) == 1 and "radii under 54 m (20 wheelbases)" in said[0]
    assert f"each cm of d moves C2n by {fit['c2n_per_tape_cm_pct']:.1f} %" in said[0]
    assert "its interval counts the tape's ±10 mm" in said[0]  # the config's default tolerance
    assert not any("too narrow to fit the sensor's d" in w for w in result["warnings"])
    # a tape stated five times finer: the same C2n, an interval five times narrower (the samples
    # are exact, so the tape is all of it), and the warning names it
    careful = dataclasses.replace(config, calibration=Calibration(d_tolerance_mm=2.0))
    pipeline = Pipeline(careful)
    for t, u, r, v in tight_samples(14.0, config.d_m, 0.0, SMALL_PAD):
        pipeline.regression.add(t, u, r, v)
    pipeline.finish()
    narrower = summary.build(pipeline.snapshot(), careful, ["small pad"]).to_json()
    assert narrower["regression"]["c2n"] == fit["c2n"]
    width, fine = (np.diff(r["regression"]["c2n_ci95"])[0] for r in (result, narrower))
    assert width / fine == pytest.approx(5.0, rel=0.02)
    assert any("its interval counts the tape's ±2 mm" in w for w in narrower["warnings"])
