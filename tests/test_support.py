"""Crossings whose sweeps disagree beyond any settled lag give no C2n (issue 39, the drive on ice)."""

import json
import math
from dataclasses import replace
from pathlib import Path

import can

from app.cli import main
from app.results.combine import Combined
from app.results.pairing import Paired
from app.results.refusal import unbounded_fit
from app.results.support import unbounded_crossings, unsteady_crossings
from tests.test_headline import FIT

CELLS = {"left up": 7.26, "left down": 12.08, "right up": 7.27, "right down": 12.09}


def paired(lag_s: float | None, lag_se: float | None) -> Paired:
    return Paired(9.07, 0.05, 0.0, 1e-5, lag_s, lag_se, CELLS, 4, 0.1)


def test_a_lag_beyond_the_settling_time_at_95_percent_is_no_steady_cornering() -> None:
    # |τ| − 1.96·σ against the gate's settling time: 1.5 − 1.96·0.2 = 1.108 > 1 refused,
    # 1.5 − 1.96·0.3 = 0.912 ≤ 1 kept; a sign does not matter, nor a lag the sensors can have
    why = unsteady_crossings(paired(-1.5, 0.2), settle_s=1.0)
    assert why is not None
    assert "-1.5 s ± 0.4" in why and "1 s" in why and "7.26–7.27 up against 12.08–12.09 down" in why
    assert unsteady_crossings(paired(1.5, 0.2), settle_s=1.0) is not None
    assert unsteady_crossings(paired(-1.5, 0.3), settle_s=1.0) is None
    assert unsteady_crossings(paired(-1.5, 0.2), settle_s=2.0) is None
    assert unsteady_crossings(paired(0.3, 0.02), settle_s=1.0) is None  # a late speed signal
    assert unsteady_crossings(paired(None, None), settle_s=1.0) is None  # one sweep direction
    assert unsteady_crossings(None, settle_s=1.0) is None


def test_a_drive_on_ice_gives_no_c2n_but_the_reason(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    log = tmp_path / "ice.log"
    assert main(["simulate", "--tyre", "magic", "--mu", "0.1", "--seed", "1", "--out", str(log)]) == 0
    out = tmp_path / "ice.json"
    assert main(["analyze", str(log), "--json", str(out)]) == 0
    summary = json.loads(out.read_text())
    assert summary["c2n"] is None and summary["c2n_ci95"] is None
    assert summary["paired"]["lag_ci95_s"][1] < -1.0  # what the pairing made of the sweeps' disagreement
    assert any("not in steady linear cornering" in w for w in summary["warnings"])
    printed = capsys.readouterr().out
    assert "C2n: no result (the crossings sweeping up and down disagree" in printed


def test_the_same_drive_on_dry_tyres_keeps_its_c2n(tmp_path: Path) -> None:
    log = tmp_path / "dry.log"
    assert main(["simulate", "--tyre", "magic", "--mu", "0.9", "--seed", "1", "--out", str(log)]) == 0
    out = tmp_path / "dry.json"
    assert main(["analyze", str(log), "--json", str(out)]) == 0
    summary = json.loads(out.read_text())
    truth = json.loads(log.with_name("dry.log.truth.json").read_text())["c2n"]
    assert abs(summary["c2n"] / truth - 1) < 0.03
    assert not any("steady linear cornering" in w for w in summary["warnings"])


def test_crossings_that_do_not_bound_c2n_say_what_held_it_open() -> None:
    one_way = Paired(15.05, 15.05 / 1.5, None, None, None, None, {"left up": 15.05}, 1, 1.0)  # Z95·se > C2n
    why = unbounded_crossings(one_way, None)
    assert why is not None and why.startswith("1 crossing reads C2n 15.05 but does not bound it: its 95 % ")
    assert "no upper end" in why and "head_yaw_deg" in why and "one sweep direction" in why
    assert "no upper end, where the crossing's own line counts its u0 alone (" in why  # printed narrower
    measured = replace(one_way, misalignment_rad=0.001, misalignment_se=0.01, lag_s=0.1, lag_se=2.0, n=4)
    why = unbounded_crossings(measured, None)
    assert why is not None and "4 crossings read" in why and "scatter as widely as C2n itself" in why
    assert "where each crossing's own line counts its u0 alone" in why
    assert unbounded_crossings(replace(one_way, se=1.0), None) is None  # bounded
    assert unbounded_crossings(replace(one_way, c2n=-3.0), None) is None  # no stiffness: a sign's matter
    assert unbounded_crossings(None, Combined(15.0, 10.0, 2, 3.0)) is not None
    assert unbounded_crossings(None, None) is None


def test_a_fit_that_does_not_bound_c2n_says_so() -> None:
    why = unbounded_fit(replace(FIT, c2n_ci95=(9.0, math.inf)))
    assert why == (
        "the regression over 5,000 samples reads C2n 14.00 but does not bound it: its 95 % interval runs "
        "from 9.00 with no upper end (a_y 1.0–4.0 m/s²) — drive longer: steady circles at 2–4 m/s² "
        "with the speed swept slowly through the sign change"
    )
    assert unbounded_fit(FIT) is None and unbounded_fit(None) is None


def _window(log: Path, out: Path, first_s: float, last_s: float) -> Path:
    """The frames of ``log`` from ``first_s`` to ``last_s`` after its first, as a log of their own."""
    frames = list(can.LogReader(str(log)))
    with can.Logger(str(out)) as writer:
        for frame in frames:
            if first_s <= frame.timestamp - frames[0].timestamp <= last_s:
                writer.on_message_received(frame)
    return out


def test_one_crossing_alone_is_no_result_and_beside_a_fit_shows_no_upper_end(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """Six seconds around a drive's first crossing (84 m, left, sweeping up): too few steady
    samples for a fit, and one crossing cannot tell a head's yaw from C2n. It read C2n 15.05
    [−4.4…] as a result; now none, and why. Twelve seconds hold a fit: the crossing beside it
    is shown without an upper end."""
    log = tmp_path / "circle.log"
    assert main(["simulate", "--scenario", "constant_radius", "--seed", "3", "--out", str(log)]) == 0
    out = tmp_path / "six.json"
    assert main(["analyze", str(_window(log, tmp_path / "six.log", 21, 27)), "--json", str(out)]) == 0
    summary = json.loads(out.read_text())
    assert summary["c2n"] is None and summary["c2n_ci95"] is None and len(summary["crossings"]) == 1
    assert summary["paired"]["c2n_ci95"][1] is None  # no upper end: null in the result file
    assert summary["no_result"].startswith("1 crossing reads C2n 15.05 but does not bound it")
    printed = capsys.readouterr().out
    assert "C2n: no result (1 crossing reads C2n 15.05 but does not bound it" in printed
    out = tmp_path / "twelve.json"
    assert main(["analyze", str(_window(log, tmp_path / "twelve.log", 18, 30)), "--json", str(out)]) == 0
    summary = json.loads(out.read_text())
    low, high = summary["c2n_ci95"]
    assert summary["c2n_method"] == "regression" and low < 14.87 < high and summary["no_result"] is None
    assert high - summary["c2n"] > summary["c2n"] - low  # the coefficient's interval, mapped
    assert "1 paired crossing: 15.011 [6.508, no upper bound]" in capsys.readouterr().out
