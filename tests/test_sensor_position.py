"""A sensor head mounted where the config does not say: the headline's u0 is where the drive's
sideslip changed sign, and the warnings say one thing of d."""

import statistics

import pytest

from app.config import load_config
from app.paper import crossing_speed
from app.sinks import summary
from tests.simulated import cached_drive, run_pipeline


def test_u0_is_where_the_sideslip_changed_sign_when_d_is_not_the_configs() -> None:
    """The head 1.5 m ahead of the axle, the config's 1.11 m: the regression places d and C2n
    itself; u0 is √(C2n·g·d) with that d — the crossings' speed — not with the config's (it read
    12.70 m/s where every crossing was at 14.7–14.8), and the drive is not said to rest on the
    config's d where another warning says the fit's lies apart from it."""
    config = load_config()
    drive = cached_drive("constant_radius", 4, None, d_m=1.5)
    snapshot = run_pipeline(config, drive).snapshot()
    truth = crossing_speed(drive.truth["c2n"], 1.5, config.vehicle.gravity_mps2)
    crossed = statistics.fmean(c.u0_mps for c in snapshot.crossings)
    assert snapshot.u0_mps == pytest.approx(truth, rel=0.01)
    assert snapshot.u0_mps == pytest.approx(crossed, rel=0.01)
    warnings = summary.build(snapshot, config, ["drive"]).warnings
    assert any("disagrees with the config's 1.11 m" in w for w in warnings)
    assert not any("rests on the config's" in w for w in warnings)
