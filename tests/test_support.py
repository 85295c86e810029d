"""Crossings whose sweeps disagree beyond any settled lag give no C2n (issue 39, the drive on ice)."""

import json
from pathlib import Path

from app.cli import main
from app.results.pairing import Paired
from app.results.support import unsteady_crossings

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
