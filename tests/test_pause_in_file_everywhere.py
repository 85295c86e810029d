"""A log file whose optical sensor paused between two tyre sets has no one C2n in `c2n export`,
no one diagnosis in `c2n gap`, and no C2n in a campaign's row, as in `c2n analyze`
(``app.results.within_file``); parts that agree keep their C2n, and a file that did not pause is
not read again."""

import csv
import json
from pathlib import Path

import can
import pytest

from app.config import load_config
from app.results.log_clock import sensor_messages
from app.results.within_file import Part, parts_disagree
from app.sources.logs import LogReport
from app.sources.spacing import FrameSpacing
from tests.test_reliability_inputs import run_cli
from tests.test_separate_recordings import _drive, _one_file

PARTS = ("day.log 0–150 s 14.9", "day.log 750–900 s 15.9")  # each part's result, as analyze names it


@pytest.fixture(scope="module")
def logs(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """day.log: a logger left recording through a tyre change (14.89, ten minutes' pause, 15.91),
    read 15.43 [15.20, 15.67] as one drive, outside both; plain.log: one drive of 15.1."""
    folder = tmp_path_factory.mktemp("logs")
    before, after = _drive(14.89, 5).messages, _drive(15.91, 6).messages
    shift = before[-1].timestamp + 600.0 - after[0].timestamp
    _one_file(folder / "day.log", (before, 0.0), (after, shift))
    _one_file(folder / "plain.log", (_drive(15.1, 1).messages, 0.0))
    return folder


def test_export_of_two_tyre_sets_in_one_file_is_refused_and_writes_nothing(
    logs: Path, tmp_path: Path
) -> None:
    """Each part's result named and the fix, exit 1, no export folder (it wrote channels, events
    and a summary.json of 15.43 without a word)."""
    out = tmp_path / "day-export"
    code, _, err = run_cli(
        ["export", str(logs / "day.log"), "--format", "csv", "--no-plots", "--out", str(out)]
    )
    assert code == 1
    assert f"the drives disagree, each alone: {PARTS[0]}" in err and PARTS[1] in err
    fix = f"split the log at its pauses (c2n split {logs / 'day.log'}) and export each part alone"
    assert f"{fix} (nothing written to {out})" in err
    assert not out.exists()


def test_gap_of_two_tyre_sets_in_one_file_is_refused_and_writes_nothing(logs: Path, tmp_path: Path) -> None:
    """Each part's result named and the fix, exit 1, no diagnosis file (it diagnosed the two
    drives as one drive's gap, its C2n lines between them, without a word)."""
    out = tmp_path / "gap.json"
    code, _, err = run_cli(["gap", str(logs / "day.log"), "--json", str(out)])
    assert code == 1
    assert f"the drives disagree, each alone: {PARTS[0]}" in err and PARTS[1] in err
    assert f"split the log at its pauses (c2n split {logs / 'day.log'}) and diagnose each part alone" in err
    assert not out.exists()


def test_a_campaign_row_of_two_tyre_sets_in_one_file_has_no_c2n_and_the_campaign_goes_on(
    logs: Path, tmp_path: Path
) -> None:
    """The row of the file that paused: no C2n, its reason naming each part; the plain drive's
    row its C2n (day.log's row read 15.43 with no error)."""
    manifest = tmp_path / "manifest.csv"
    manifest.write_text(f"log,tyre_set\n{logs / 'day.log'},AB\n{logs / 'plain.log'},A\n")
    out = tmp_path / "campaign"
    code, _, err = run_cli(
        ["campaign", str(manifest), "--workers", "1", "--by", "tyre_set", "--out", str(out)]
    )
    assert code == 0, err
    with (out / "results.csv").open(encoding="utf-8-sig", newline="") as file:
        day, plain = csv.DictReader(file)
    assert day["c2n"] == "" and day["compared.c2n"] == ""
    assert f"{logs / 'day.log'}: no C2n — the drives disagree, each alone: {PARTS[0]}" in day["error"]
    assert PARTS[1] in day["error"] and "list each part in the manifest" in day["error"]
    assert f"split the log at its pauses (c2n split {logs / 'day.log'})" in day["error"]
    assert plain["error"] == "" and 14.6 < float(plain["c2n"]) < 15.6
    assert f"{PARTS[0]}" in err and "1 of 2 sessions failed" in err


def test_a_sensor_dropout_in_one_drive_still_exports_its_c2n(tmp_path: Path) -> None:
    """Two seconds without the optical sensor in one drive: parts that agree, exported as one
    drive with its C2n and no word of parts (it was so before: what the check must not break)."""
    drive = _drive(14.89, 5)
    start = drive.messages[0].timestamp
    optical = set(sensor_messages(load_config()))
    kept = [
        m for m in drive.messages if not (m.arbitration_id in optical and 70.0 <= m.timestamp - start < 72.0)
    ]
    log = _one_file(tmp_path / "dropout.log", (kept, 0.0))
    out = tmp_path / "dropout-export"
    code, _, err = run_cli(["export", str(log), "--format", "csv", "--no-plots", "--out", str(out)])
    assert code == 0, err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["c2n_ci95"][0] <= 14.89 <= summary["c2n_ci95"][1]
    assert "disagree" not in err and "pause" not in err


def _no_part(config: object) -> Part:
    raise AssertionError("no part is run")


def test_a_file_without_a_pause_is_not_read_again(tmp_path: Path) -> None:
    """No pause: no part and no read (the file is not even there)."""
    assert parts_disagree(LogReport(tmp_path / "gone.log"), load_config(), _no_part) is None


def test_a_log_timed_in_milliseconds_is_left_to_the_clock_check(tmp_path: Path) -> None:
    """Frames 20 "s" apart pause at every frame: no part for each (thousands of pipelines at
    once in a real log), the clock's own refusal says why."""
    config = load_config()
    sensor = frozenset(sensor_messages(config))
    spacing = FrameSpacing(sensor, config.filter.gap_reset_s)
    for k in range(50):
        spacing.add(can.Message(timestamp=20.0 * k, arbitration_id=min(sensor)))
    report = LogReport(tmp_path / "ms.log", spacing=spacing, span_s=(0.0, 980.0))
    assert len(spacing.pauses) == 49
    assert parts_disagree(report, config, _no_part) is None
