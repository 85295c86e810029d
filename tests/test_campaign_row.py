"""A campaign's typed row: the data's error held apart from the sensors' scales from the fit on,
and the cache file that keeps the row between runs."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from app.campaign.meta_analysis import Estimate, Fits
from app.campaign.row import SessionResult, SessionRow
from app.campaign.work import _stored
from app.config import Priors
from app.pipeline import _with_scale
from app.results.combine import Combined
from app.results.headline import Method, headline
from app.results.regression import SampleRegression
from app.units import Z95
from tests.test_regression import G, sweep_samples


def _fits(scale_se: float, **kwargs: object) -> tuple:
    rng = np.random.default_rng(8)
    samples = [
        (t, u, r, v + rng.normal(0, 0.005))
        for t, u, r, v in sweep_samples(14.0, 1.1, 0.0, (70.0, -70.0, 140.0))
    ]
    out = []
    for scale in (0.0, scale_se):
        regression = SampleRegression(G, scale_se=scale, **kwargs)  # type: ignore[arg-type]
        for t, u, r, v in samples:
            regression.add(t, u, r, v)
        out.append(regression.fit())
    return tuple(out)


@pytest.mark.parametrize("priors", [None, Priors(estimator="marginal")], ids=["cascade", "marginal"])
def test_a_fit_holds_its_data_s_interval_apart_from_the_sensors_scales(priors: Priors | None) -> None:
    """The interval a campaign pools sessions on is the fit's without the scales: the same drive
    fitted with no scale tolerance gives exactly it, while the headline's interval is wider."""
    plain, counted = _fits(0.003, priors=priors)
    assert plain is not None and counted is not None
    assert counted.c2n_data_ci95 == pytest.approx(plain.c2n_ci95, rel=1e-12)
    assert counted.c2n_ci95[1] - counted.c2n_ci95[0] > 1.01 * (plain.c2n_ci95[1] - plain.c2n_ci95[0])
    assert counted.models.linear.data_ci95 == pytest.approx(plain.models.linear.ci95, rel=1e-12)
    head = headline(counted, None, None, None)
    assert head is not None and head.data_only_ci95 == counted.c2n_data_ci95 and head.ci95 == counted.c2n_ci95


def test_the_crossings_hold_their_data_s_error_apart_from_the_scales() -> None:
    """A scale of 1 % on C2n 15 (0.15) beside the crossings' own 0.1: the interval counts both,
    the data's interval is the crossings' alone (their se of 0.1, as a share of C2n:
    combine.ratio_ci95)."""
    combined = _with_scale(Combined(15.0, 0.1, 6, 1.0), 0.01)
    assert combined is not None and combined.se == pytest.approx(math.hypot(0.1, 0.15))
    head = headline(None, None, None, combined)
    assert head is not None and head.method is Method.CROSSINGS
    share, both = Z95 * 0.1 / 15.0, Z95 * math.hypot(0.1, 0.15) / 15.0
    assert head.data_only_ci95 == pytest.approx((15.0 / (1 + share), 15.0 / (1 - share)))
    assert head.ci95 == pytest.approx((15.0 / (1 + both), 15.0 / (1 - both)))
    assert Estimate.of(15.0, head.ci95, head.data_only_ci95).se == pytest.approx(0.1, rel=1e-3)


ROW = SessionRow(
    summary={"c2n": 14.1, "c2n_ci95": [13.9, 14.3], "warnings": ["d[1].log: a recording given twice"]},
    result=SessionResult(
        own=Estimate(14.1, (13.9, 14.3), 0.09),
        scale=0.002,
        softening_t=-2.4,
        fits=Fits(-2.4, Estimate(14.0, (13.8, 14.2), 0.1), Estimate(14.1, (13.9, 14.3), 0.09), "softening"),
    ),
    drive="141e8616:133443:296.520",
    frames=133443,
    seconds=2.9,
    worker_peak_mib=195.3,
    key="aa-bb",
)


def test_a_row_reads_back_from_its_cache_file_as_it_was(tmp_path: Path) -> None:
    (tmp_path / "aa-bb.json").write_text(json.dumps(ROW.to_json()), encoding="utf-8")
    assert _stored(tmp_path) == {"aa-bb": ROW}
    failed = SessionRow(error="x.blf: no C2n — no sweep crossed zero", key="cc-dd", frames=10)
    assert SessionRow.from_json(json.loads(json.dumps(failed.to_json()))) == failed


@pytest.mark.parametrize(
    "content",
    [
        {"key": "aa-bb", "c2n": 14.1, "c2n_ci95.low": 13.9, "error": None},  # an earlier c2n's flat row
        ROW.to_json() | {"format": 1},
        ROW.to_json() | {"result": {"own": [14.1, [13.9], 0.09]}},
        ROW.to_json() | {"error": 3},
        ROW.to_json() | {"result": ROW.to_json()["result"] | {"own": [14.1, [13.9, 14.3], float("nan")]}},
        ROW.to_json() | {"key": "another"},  # named for another drive
        [1, 2, 3],
    ],
)
def test_a_cache_file_that_holds_no_row_of_this_layout_is_no_row(tmp_path: Path, content: object) -> None:
    """Its drive is analysed again rather than read wrongly."""
    (tmp_path / "aa-bb.json").write_text(json.dumps(content), encoding="utf-8")
    assert _stored(tmp_path) == {}


def test_a_row_s_columns_are_the_summary_s_keys_joined_then_its_own() -> None:
    columns = ROW.columns()
    assert list(columns)[:3] == ["c2n", "c2n_ci95.low", "c2n_ci95.high"]
    assert columns["warnings"] == '["d[1].log: a recording given twice"]'
    assert columns["frames"] == 133443 and columns["key"] == "aa-bb" and columns["cached"] is None
    assert ROW.warnings_about(Path("/x/d[1].log")) == ["d[1].log: a recording given twice"]
    assert ROW.warnings_about(Path("/x/e.log")) == []


def test_a_row_seen_at_a_moved_log_names_it_there_in_its_warnings_and_error() -> None:
    summary = {"inputs": ["/old/a.blf"], "config": "/old/car.toml", "warnings": ["/old/a.blf: cut short", 3]}
    row = SessionRow(summary=summary, error="/old/a.blf: no C2n — too short", key="aa-bb")
    moved = row.seen_at(["/new/b.blf"], "/new/car.toml")
    assert moved.summary["inputs"] == ["/new/b.blf"] and moved.summary["config"] == "/new/car.toml"
    assert moved.summary["warnings"] == ["/new/b.blf: cut short", 3]
    assert moved.error == "/new/b.blf: no C2n — too short" and moved.key == "aa-bb"
    assert row.seen_at(["/old/a.blf"], "/old/car.toml") is row
    assert row.seen_at(["/new/b.blf", "/new/c.blf"], "/new/car.toml") is row  # not the same drive's parts
