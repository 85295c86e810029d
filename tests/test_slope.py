"""A test pad with a drainage slope: the regression fits it and takes it out of C2n, and out of
the crossings found once it is known."""

import json
from pathlib import Path
from typing import Any

import can
import pytest
from rich.console import Console

from app.cli import main


@pytest.mark.parametrize(("grade", "side"), [(2.0, "right"), (-3.0, "left")])
def test_a_sloping_pad_reads_within_one_percent_with_the_truth_inside(
    grade: float, side: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The standard session on the two-track model, its pad falling to one side of the start
    heading (left out of the fit, a 2 % slope read C2n 2.5 % low with the truth outside)."""
    log = tmp_path / "slope.blf"
    argv = ["simulate", "--session", "standard", "--effect", "road_cross_slope", "--effect-size", str(grade)]
    assert main([*argv, "--seed", "11", "--out", str(log)], Console(record=True)) == 0
    truth = json.loads(log.with_name("slope.blf.truth.json").read_text())["c2n"]
    capsys.readouterr()
    assert main(["analyze", str(log), "--json", str(tmp_path / "out.json")], Console(record=True)) == 0
    result = json.loads((tmp_path / "out.json").read_text())
    low, high = result["c2n_ci95"]
    assert result["c2n_method"] == "regression" and low <= truth <= high
    assert abs(result["c2n"] / truth - 1) < 0.01
    fit = result["regression"]
    assert fit["slope_pct"] == pytest.approx(abs(grade), rel=0.1)
    assert fit["slope_downhill_deg"] == pytest.approx(-90.0 if side == "right" else 90.0, abs=10.0)
    assert f"the test pad slopes {fit['slope_pct']:.1f} %" in capsys.readouterr().err
    # each crossing happens at one heading: once the slope is known it is taken out of them as
    # they are fitted; the first circles' come before it, and the pairing moves every crossing to
    # the last slope found
    crossings = result["crossings"]
    corrected = [c for c in crossings if c["slope_corrected"]]
    before = [c for c in crossings if not c["slope_corrected"]]
    assert len(corrected) >= 8 and before and all(c["t"] < corrected[0]["t"] for c in before)
    errors = [abs(c["c2n"] / truth - 1) for c in corrected]
    assert max(errors) < 0.06 and sum(errors) / len(errors) < 0.03  # the sweeps' lag is still in each
    assert abs(result["paired"]["c2n"] / truth - 1) < 0.005
    assert result["paired"]["n"] == len(crossings)


def test_the_slope_is_taken_out_alike_frame_by_frame_and_in_blocks(tmp_path: Path) -> None:
    """`c2n live` takes frames one by one, `c2n analyze` of an MF4 in blocks: the crossings the
    slope is taken out of, and every number, are the same."""
    from app.config import load_config
    from app.pipeline import Pipeline
    from app.sinks import summary
    from app.sources.logs import LogSource

    log = tmp_path / "slope.mf4"
    argv = ["simulate", "--session", "standard", "--effect", "road_cross_slope", "--effect-size", "2"]
    assert main([*argv, "--seed", "5", "--out", str(log)], Console(record=True)) == 0

    def analysed(blocks: bool) -> dict[str, Any]:
        pipeline = Pipeline(load_config())
        source = LogSource([log], triage=pipeline.decoder if blocks else None)
        for item in source.items(blocks=blocks):
            if isinstance(item, can.Message):
                pipeline.process(item)
            else:
                pipeline.process_block(item)
        pipeline.finish()
        result = summary.build(pipeline.snapshot(), pipeline.config, [str(log)]).to_json()
        result.pop("duration_s")
        return result

    by_frame, in_blocks = analysed(False), analysed(True)
    corrected = [c for c in by_frame["crossings"] if c["slope_corrected"]]
    assert len(corrected) >= 8
    assert json.dumps(in_blocks, sort_keys=True) == json.dumps(by_frame, sort_keys=True)
