"""The headline is the estimate the drive held, never the one that reads best."""

import json
import math
from dataclasses import replace
from typing import Any

import pytest

from app.results.combine import Combined
from app.results.fit_groups import DResult, FitSamples, ModelChoice, ModelFit, Psi0Result
from app.results.headline import Headline, Method, headline
from app.results.pairing import Paired
from app.results.regression import RegressionFit

FIT = RegressionFit(
    c2n=14.0,
    c2n_se=0.1,
    c2n_ci95=(13.8, 14.2),
    samples=FitSamples(count=5000, blocks=200, ay_range_mps2=(1.0, 4.0), curvature_range_per_m=(0.01, 0.02)),
    d=DResult(m=1.2, ci95_m=(1.19, 1.21)),
    psi0=Psi0Result(rad=0.0, ci95_rad=(-0.001, 0.001)),
    models=ModelChoice(
        chosen="linear", softening_t=0.3, linear=ModelFit(14.0, None), softening=ModelFit(14.0, None)
    ),
)
PAIRED = Paired(15.0, 0.2, None, None, None, None, {}, 4, 1.0)  # read far from the fit: not chosen for it
COMBINED = Combined(16.0, 0.3, 4, 1.0)
QUASI = replace(FIT, c2n=13.0, c2n_ci95=(12.7, 13.3))


def _all(**held: Any) -> dict[str, Any]:
    return {"regression": None, "quasi": None, "paired": None, "combined": None} | held


@pytest.mark.parametrize(
    ("held", "expected"),
    [
        (
            _all(regression=FIT, paired=PAIRED, combined=COMBINED),
            Headline(14.0, (13.8, 14.2), Method.REGRESSION),
        ),
        (
            _all(quasi=replace(FIT, c2n=13.0, c2n_ci95=(12.7, 13.3))),
            Headline(13.0, (12.7, 13.3), Method.QUASI_STEADY),
        ),
        (_all(paired=PAIRED, combined=COMBINED), Headline(15.0, PAIRED.ci95, Method.PAIRED)),
        (_all(combined=COMBINED), Headline(16.0, COMBINED.ci95, Method.CROSSINGS)),
        (_all(), None),
    ],
)
def test_the_headline_is_what_the_drive_held(held: dict[str, Any], expected: Headline | None) -> None:
    """A regression where the steady samples support one, whatever the crossings read (they are
    its samples, not a second measurement); the quasi-steady fit where no sweep crossed zero; the
    crossings only where no fit could be made."""
    assert headline(**held) == expected


@pytest.mark.parametrize("c2n", [0.0, -14.0, math.nan])
def test_a_fit_that_is_no_stiffness_is_no_headline_and_not_replaced_by_the_crossings(c2n: float) -> None:
    """A regression whose C2n is not positive is no result — the crossings of the same samples do
    not stand in for it (the caller says why: a role's sign, ``Snapshot.sign_problem``)."""
    held = _all(regression=replace(FIT, c2n=c2n), paired=PAIRED, combined=COMBINED)
    assert headline(**held) is None
    assert headline(**_all(paired=replace(PAIRED, c2n=c2n), combined=COMBINED)) == Headline(
        16.0, COMBINED.ci95, Method.CROSSINGS
    )


def test_the_method_is_written_as_its_name() -> None:
    assert json.dumps({"c2n_method": Method.PAIRED}) == '{"c2n_method": "paired crossings"}'
    assert f"{Method.QUASI_STEADY}" == "quasi-steady" and Method.REGRESSION == "regression"
    assert [m.is_fit for m in Method] == [True, True, False, False]


def test_an_interval_without_an_upper_end_is_no_headline() -> None:
    """A C2n that a fit or the crossings cannot bound above is no result (refusal.unbounded_fit,
    support.unbounded_crossings say why), and the crossings' mean does not stand in for the
    paired crossings that counted the head's yaw."""
    open_fit = replace(FIT, c2n_ci95=(9.0, math.inf))
    assert headline(**_all(regression=open_fit, paired=PAIRED, combined=COMBINED)) is None
    assert headline(**_all(quasi=open_fit, combined=COMBINED)) is None
    wide = replace(PAIRED, se=15.0 / 1.9)  # Z95·se > C2n
    assert not wide.bounded
    assert headline(**_all(paired=wide, combined=COMBINED)) is None
    assert headline(**_all(combined=replace(COMBINED, se=16.0 / 1.9))) is None
