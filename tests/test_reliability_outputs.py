"""Issue 39, third round: where c2n writes. An output is never an input (however spelt), never a
file c2n did not write unless --force, never standard output twice; outputs are swapped in whole."""

import errno
import json
import os
import shutil
import stat
import subprocess
import sys
from pathlib import Path

import pytest

from app.campaign.analysis import Job
from app.campaign.tables import write_tables
from app.campaign.work import HashMemo
from app.errors import OutputError
from app.output import files
from app.output.files import (
    files_together,
    folder_atomically,
    partial_path,
    write_atomically,
    write_text,
)
from app.output.paths import GENERATOR
from tests.simulated import REPO
from tests.test_reliability_inputs import MONDEO, run_cli


def _snapshot(folder: Path) -> dict[str, bytes]:
    """Every file under ``folder`` (links not followed) and its bytes."""
    return {
        str(p.relative_to(folder)): p.read_bytes()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and not p.is_symlink()
    }


@pytest.fixture
def day(drive_log: Path, tmp_path: Path) -> Path:
    """A folder with a drive, a config and the DBC it names, as a user has them."""
    shutil.copy(drive_log, tmp_path / "d.blf")
    shutil.copy(REPO / "dbc" / "kistler_smotion.dbc", tmp_path / "kistler.dbc")
    config = MONDEO.replace(f"{REPO}/dbc/kistler_smotion.dbc", str(tmp_path / "kistler.dbc"))
    (tmp_path / "car.toml").write_text(config)
    return tmp_path


def test_an_output_that_is_an_input_however_spelt_is_refused_and_nothing_changes(day: Path) -> None:
    os.symlink(day / "d.blf", day / "link.json")
    os.link(day / "d.blf", day / "hard.json")
    before = _snapshot(day)
    drive, car = str(day / "d.blf"), ["--config", str(day / "car.toml")]
    cases = {
        "analyze --json the log": ["analyze", drive, *car, "--json", drive],
        "a symlink to it": ["analyze", drive, *car, "--json", str(day / "link.json")],
        "a hard link to it": ["analyze", drive, *car, "--json", str(day / "hard.json")],
        "another spelling": ["analyze", drive, *car, "--json", f"{day}/sub/../d.blf"],
        "the config": ["analyze", drive, *car, "--json", str(day / "car.toml")],
        "a DBC": ["analyze", drive, *car, "--json", str(day / "kistler.dbc")],
        "gap --report the log": ["gap", drive, *car, "--report", drive],
        "gap --json the config": ["gap", drive, *car, "--json", str(day / "car.toml")],
        "export into the log's folder": ["export", drive, *car, "--out", str(day)],
        "export over the log": ["export", drive, *car, "--out", drive],
        "simulate over the config": ["simulate", *car, "--out", str(day / "car.toml")],
        "simulate a pack over the config": ["simulate", "--pack", "1", *car, "--out", str(day / "car.toml")],
        "live --json the DBC": ["live", "-i", "virtual", *car, "--json", str(day / "kistler.dbc")],
    }
    for name, argv in cases.items():
        code, _, err = run_cli(argv)
        assert code == 2 and err.count("\n") == 1 and "an input" in err, (name, err)
        assert _snapshot(day) == before, name


def test_two_outputs_in_one_file_or_both_on_stdout_are_usage_errors(day: Path) -> None:
    drive = str(day / "d.blf")
    code, _, err = run_cli(["gap", drive, "--json", str(day / "o.json"), "--report", f"{day}/./o.json"])
    assert code == 2 and "--json and --report: both name" in err
    code, out, err = run_cli(["gap", drive, "--json", "-", "--report", "-"])
    assert code == 2 and "only one output can go to standard output" in err and out == ""
    code, _, err = run_cli(["export", drive, "--out", "-"])
    assert code == 2 and "--out -: a folder cannot go to standard output" in err
    code, _, err = run_cli(["simulate", "--campaign", "1", "--out", "-"])
    assert code == 2 and "standard output" in err
    assert not (day / "o.json").exists() and not Path("-").exists()


def test_a_file_c2n_did_not_write_is_replaced_only_with_force(day: Path) -> None:
    drive = str(day / "d.blf")
    mine = day / "mine.json"
    mine.write_text('{"my": "notes"}\n')
    report = day / "report.html"
    report.write_text("<html><body>my page</body></html>\n")
    code, _, err = run_cli(["analyze", drive, "--json", str(mine)])
    assert code == 1 and "mine.json: exists and is not a file c2n wrote" in err and "--force" in err
    code, _, err = run_cli(["gap", drive, "--report", str(report)])
    assert code == 1 and "report.html: exists and is not a file c2n wrote" in err
    assert mine.read_text() == '{"my": "notes"}\n' and "my page" in report.read_text()
    # c2n's own summary is replaced without a word; a user's with --force
    assert run_cli(["analyze", drive, "--json", str(mine), "--force"])[0] == 0
    assert "c2n_ci95" in json.loads(mine.read_text())
    assert run_cli(["analyze", drive, "--json", str(mine)])[0] == 0
    (day / "empty.json").touch()  # nothing to lose
    assert run_cli(["analyze", drive, "--json", str(day / "empty.json")])[0] == 0


def test_another_drive_s_summary_is_replaced_only_with_force(
    day: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`analyze b.blf --json EXPORT/summary.json`, or into a `c2n live` session's folder: the
    export's (or the session's own) summary was replaced by another drive's, beside channels and
    events of the first — a folder that looks whole and is not. Now a summary naming other inputs
    is replaced only with --force; the same drive's, from here or from its own folder, as before."""
    drive = day / "d.blf"
    other = tmp_path / "other.blf"
    shutil.copy(drive, other)
    summary = day / "summary.json"
    assert run_cli(["analyze", str(drive), "--json", str(summary)])[0] == 0
    assert run_cli(["analyze", str(other), "--json", str(summary)])[0] == 0  # a file alone: as named
    assert run_cli(["analyze", str(drive), "--json", str(summary)])[0] == 0
    (day / "events.csv").write_text("t,event,\n")  # now one file of a folder's whole
    before = summary.read_bytes()
    code, _, err = run_cli(["analyze", str(other), "--json", str(summary)])
    assert code == 1, err
    assert f"summary.json: holds the summary of {drive}, not of {other}, beside that run's events.csv" in err
    assert summary.read_bytes() == before
    session = tmp_path / "session"
    session.mkdir()
    live = {
        "c2n": 14.8,
        "c2n_ci95": [14.6, 15.0],
        "c2n_method": "regression",
        "inputs": ["Virtual bus channel ch1"],
    }
    (session / "summary.json").write_text(json.dumps(live))
    (session / "frames.log").write_text("(0.000000) can0 123#0102\n")
    code, _, err = run_cli(["analyze", str(drive), "--json", str(session / "summary.json")])
    assert code == 1 and "holds the summary of Virtual bus channel ch1, not of" in err and "frames.log" in err
    assert json.loads((session / "summary.json").read_text()) == live
    assert run_cli(["analyze", str(drive), "--json", str(summary)])[0] == 0  # its own: replaced
    monkeypatch.chdir(day)
    assert run_cli(["analyze", "d.blf", "--json", "summary.json"])[0] == 0  # relative: its folder's
    monkeypatch.chdir(tmp_path)  # and read from elsewhere, the summary naming it relative
    assert run_cli(["analyze", str(drive), "--json", str(summary)])[0] == 0
    assert run_cli(["analyze", str(other), "--json", str(summary), "--force"])[0] == 0
    assert json.loads(summary.read_text())["inputs"] == [str(other)]


def test_simulate_never_replaces_a_log_or_a_truth_without_force(tmp_path: Path) -> None:
    real = tmp_path / "real.log"
    real.write_text("(0.000000) can0 123#0102\n")
    code, _, err = run_cli(["simulate", "--out", str(real)])
    assert code == 1 and "real.log: exists" in err and "--force" in err
    assert real.read_text() == "(0.000000) can0 123#0102\n"
    assert not (tmp_path / "real.log.truth.json").exists()
    (tmp_path / "new.log.truth.json").write_text("my truth")
    code, _, err = run_cli(["simulate", "--out", str(tmp_path / "new.log")])
    assert code == 1 and "new.log.truth.json: exists" in err and not (tmp_path / "new.log").exists()
    assert run_cli(["simulate", "--out", str(real), "--force"])[0] == 0
    assert json.loads((tmp_path / "real.log.truth.json").read_text())["c2n"] > 0
    assert real.read_text().count("\n") > 1000


def test_simulate_force_puts_a_log_and_its_truth_in_place_together_or_neither(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The log was put in place, then its truth written: a full disk at the truth left the new
    drive's log beside the older drive's truth (C2n 18 in the log, 14.87 in its truth), and a
    folder in the truth's place was found only after the log had been replaced."""
    log, truth = tmp_path / "a.log", tmp_path / "a.log.truth.json"
    assert run_cli(["simulate", "--seed", "1", "--out", str(log)])[0] == 0
    before = log.read_bytes(), truth.read_bytes()

    def full(tmp: Path) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    from app.sim import simulated_drive

    monkeypatch.setattr(simulated_drive, "text_file", lambda text: full)
    code, _, err = run_cli(["simulate", "--seed", "2", "--c2n", "18", "--out", str(log), "--force"])
    assert code == 1 and "a.log.truth.json: cannot write the truth (No space left on device)" in err
    assert (log.read_bytes(), truth.read_bytes()) == before and sorted(tmp_path.iterdir()) == [log, truth]
    monkeypatch.undo()
    truth.unlink()
    truth.mkdir()
    code, _, err = run_cli(["simulate", "--seed", "2", "--out", str(log), "--force"])
    assert code == 1 and "cannot write the truth (Is a directory)" in err
    assert log.read_bytes() == before[0] and sorted(tmp_path.iterdir()) == [log, truth]


def test_gap_s_diagnosis_and_report_are_put_in_place_together_or_neither(
    drive_log: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """--json was written, then the report: a report that failed (a full disk, a file-size limit)
    left the new diagnosis beside the older report's other verdict."""
    json_path, report = tmp_path / "g.json", tmp_path / "g.html"
    json_path.write_text("{}")  # an older run's, as far as the test goes
    report.write_text("<html>older</html>")
    from app.output import files as written

    real = written.text_file

    def failing_html(text: str):  # type: ignore[no-untyped-def]
        if text.startswith("<!DOCTYPE html>"):
            return lambda tmp: (_ for _ in ()).throw(OSError(errno.EFBIG, os.strerror(errno.EFBIG)))
        return real(text)

    from app.cli import gap

    monkeypatch.setattr(gap, "text_file", failing_html)
    argv = ["gap", str(drive_log), "--json", str(json_path), "--report", str(report), "--force"]
    code, _, err = run_cli(argv)
    assert code == 1 and "g.html: cannot write the report (File too large)" in err, err
    assert json_path.read_text() == "{}" and report.read_text() == "<html>older</html>"
    assert sorted(tmp_path.iterdir()) == sorted([json_path, report])


def test_a_name_too_long_for_its_temporary_is_refused_before_anything_is_written(tmp_path: Path) -> None:
    long = tmp_path / ("a" * 247 + ".log")  # the log fits in 255 bytes, its truth would not
    code, _, err = run_cli(["simulate", "--out", str(long)])
    assert code == 2 and err.count("\n") == 1 and "too long" in err and "choose a shorter name" in err
    assert list(tmp_path.iterdir()) == []


def test_a_campaign_s_results_are_swapped_in_together_or_not_at_all(tmp_path: Path) -> None:
    """Ctrl-C or a full disk while the new set is written: the old set, whole; no temporary."""
    names = ("results.csv", "comparison.json", "report.html")
    for name in names:
        (tmp_path / name).write_text("old")
    for stop in (KeyboardInterrupt(), OSError(28, "No space left on device")):
        with pytest.raises(type(stop)), files_together(tmp_path, names) as staging:
            (staging / "results.csv").write_text("new")
            raise stop
        assert {p.name: p.read_text() for p in tmp_path.iterdir()} == dict.fromkeys(names, "old")
    with files_together(tmp_path, names) as staging:
        for name in names:
            (staging / name).write_text("new")
    assert {p.name: p.read_text() for p in tmp_path.iterdir()} == dict.fromkeys(names, "new")


def test_an_output_folder_takes_the_umask_s_mode(tmp_path: Path) -> None:
    old = os.umask(0o022)
    try:
        with folder_atomically(tmp_path / "out", lambda name: True, "c2n export") as staging:
            (staging / "a").write_text("x")
    finally:
        os.umask(old)
    assert (tmp_path / "out").stat().st_mode & 0o777 == 0o755


def test_a_users_folder_filled_keeps_who_may_use_it(tmp_path: Path) -> None:
    """`export --out shared` where `shared` is a user's empty folder, private to a group (setgid,
    0770) and of that group: the folder an export puts in its place has its mode and group (it
    had the umask's 0755 and the user's own group: a group's folder opened to all, closed to the
    group)."""
    shared = tmp_path / "shared"
    shared.mkdir()
    group = next((g for g in os.getgroups() if g != os.getegid()), None) if os.geteuid() else 1
    if group is not None:
        os.chown(shared, -1, group)
    os.chmod(shared, 0o2770)
    with folder_atomically(shared, lambda name: True, "c2n export") as staging:
        (staging / "a").write_text("x")
    after = shared.stat()
    assert after.st_mode & 0o7777 == 0o2770 and (shared / "a").read_text() == "x"
    assert after.st_gid == (group if group is not None else os.getegid())


def test_live_never_replaces_an_export_s_or_a_session_s_summary_without_force(day: Path) -> None:
    """`live --json EXPORT/summary.json` (helper-32): the export's summary became the live run's
    (no C2n, 0 frames) beside the first drive's channels, and the export of that drive was then
    refused as another's. A live run is never the drive of a summary there; one alone is its to
    name again."""
    export = day / "d-export"
    assert run_cli(["export", str(day / "d.blf"), "--no-plots", "--format", "csv"])[0] == 0
    summary = export / "summary.json"
    before = summary.read_bytes()
    live = ["live", "-i", "virtual", "-c", "helper-32", "--no-record", "--duration", "0.3", "--json"]
    code, _, err = run_cli([*live, str(summary)])
    assert code == 1, err
    assert f"summary.json: holds the summary of {day / 'd.blf'}, not of this bus, beside that run's" in err
    assert summary.read_bytes() == before
    link = day / "s.json"  # through a link (helper-33: the files were looked for beside the link)
    link.symlink_to(summary)
    for argv in ([*live, str(link)], ["analyze", str(day / "other.blf"), "--json", str(link)]):
        if argv[0] == "analyze":
            shutil.copy(day / "d.blf", day / "other.blf")
        code, _, err = run_cli(argv)
        assert code == 1 and "beside that run's" in err, err
        assert summary.read_bytes() == before
    # a summary new to a session folder that has none (killed, or still recording) would say it ended
    session = day / "killed"
    (session / "config").mkdir(parents=True)  # a session: its frames beside its config's copy
    (session / "config" / "car.toml").write_text((day / "car.toml").read_text())
    (session / "frames.log").write_text("(0.000000) can0 123#0102\n")
    code, _, err = run_cli([*live, str(session / "summary.json")])
    assert code == 1 and "is the place of the summary of the session beside it (frames.log), which" in err, (
        err
    )
    assert not (session / "summary.json").exists()
    alone = day / "alone.json"
    alone.write_bytes(before)
    assert run_cli([*live, str(alone)])[0] == 0
    assert run_cli([*live, str(summary), "--force"])[0] == 0
    assert json.loads(summary.read_text())["inputs"] != json.loads(before)["inputs"]


def test_the_same_drive_s_summary_is_replaced_again_through_a_link_or_from_elsewhere(
    day: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """helper-34: `analyze d.blf --json latest.json` (a link to an export's summary) twice: the
    second refused as another drive's — analyze recorded `d.blf` as typed, read from the link's
    target's folder; and `analyze logs/d.blf --json logs/d-export/summary.json` from the folder
    above, twice. Its inputs are now recorded absolute. A folder of the user's holding a log named
    frames.log is not a session: its summary.json is written."""
    logs = day / "logs"
    logs.mkdir()
    shutil.copy(day / "d.blf", logs / "d.blf")
    assert run_cli(["export", str(logs / "d.blf"), "--no-plots", "--format", "csv"])[0] == 0
    monkeypatch.chdir(logs)
    (logs / "latest.json").symlink_to("d-export/summary.json")
    for _ in range(2):
        code, _, err = run_cli(["analyze", "d.blf", "--json", "latest.json"])
        assert code == 0, err
    assert json.loads((logs / "d-export" / "summary.json").read_text())["inputs"] == [str(logs / "d.blf")]
    monkeypatch.chdir(day)
    for _ in range(2):
        code, _, err = run_cli(["analyze", "logs/d.blf", "--json", "logs/d-export/summary.json"])
        assert code == 0, err
    plain = day / "plain"
    plain.mkdir()
    shutil.copy(day / "d.blf", plain / "frames.blf")
    code, _, err = run_cli(["analyze", str(plain / "frames.blf"), "--json", str(plain / "summary.json")])
    assert code == 0 and (plain / "summary.json").exists(), err


def test_a_read_only_export_is_not_replaced(day: Path) -> None:
    """`chmod -R a-w` on an export, then the same export again (helper-33, as root: replaced,
    its parquet gone, the read-only summary 644). A read-only result file was refused; a folder
    holding one is too: folders are never forced."""
    export = day / "d-export"
    assert run_cli(["export", str(day / "d.blf"), "--no-plots", "--format", "csv"])[0] == 0
    before = _snapshot(export)
    (export / "summary.json").chmod(0o444)
    code, _, err = run_cli(["export", str(day / "d.blf"), "--no-plots", "--format", "csv"])
    assert code == 1 and "d-export: holds read-only files (summary.json) — make it writable" in err, err
    assert _snapshot(export) == before
    (export / "summary.json").chmod(0o644)
    export.chmod(0o555)
    try:
        code, _, err = run_cli(["export", str(day / "d.blf"), "--no-plots", "--format", "csv"])
        assert code == 1 and "d-export: is read-only — make it writable" in err, err
    finally:
        export.chmod(0o755)
    assert _snapshot(export) == before
    assert run_cli(["export", str(day / "d.blf"), "--no-plots", "--format", "csv"])[0] == 0


def test_gap_s_report_never_replaces_another_command_s_page_without_force(day: Path) -> None:
    """`gap b.blf --report EXPORT/report.html` or a campaign's report.html (helper-32): replaced
    without a word, and the campaign then refused its own folder (`holds files c2n did not
    write`). A page's head names the command that wrote it; gap replaces its own, and a page of
    an older c2n only where it is alone."""
    from app.output.paths import page_of
    from app.sinks.html import page

    folder = day / "an-export"
    folder.mkdir()
    report = folder / "report.html"
    report.write_text(page("c2n export", [], "export"))
    (folder / "events.csv").write_text("t,event,\n")
    before = report.read_bytes()
    code, _, err = run_cli(["gap", str(day / "d.blf"), "--report", str(report)])
    assert code == 1, err
    assert "report.html: is c2n export's page, beside its summary" not in err  # no summary.json here
    assert "report.html: is c2n export's page, beside its events.csv — choose another name, or add" in err
    assert report.read_bytes() == before
    whose = page_of("gap")
    report.write_text(page("c2n gap", [], "gap"))
    assert whose(report) is None  # its own
    report.write_text(page("c2n", [], "campaign"))
    assert whose(report) == "is c2n campaign's page, beside its events.csv"
    older = "default-src 'none'; img-src data:"  # the policy of pages written before the marker
    report.write_text(f'<html><head><meta http-equiv="Content-Security-Policy" content="{older}">')
    assert whose(report) == "is a page of c2n's beside another run's events.csv"  # an older c2n's
    (folder / "events.csv").unlink()
    assert whose(report) is None  # alone: the user's to name again


def test_every_html_page_carries_c2n_s_marker(day: Path) -> None:
    from app.sinks.html import page

    assert GENERATOR in page("t", [], "export")


def test_events_csv_follows_the_csv_dialect(day: Path) -> None:
    out = day / "semi"
    argv = ["export", str(day / "d.blf"), "--no-plots", "--format", "csv", "--out", str(out)]
    assert run_cli([*argv, "--csv-dialect", "excel-semicolon"])[0] == 0
    lines = (out / "events.csv").read_text(encoding="utf-8").splitlines()
    assert lines[0].startswith("t;event;direction;")
    first = lines[1].split(";")
    assert len(first) == len(lines[0].split(";")) and "," in first[0] and "." not in first[0]


def test_an_export_folder_is_replaced_only_where_each_file_is_c2n_s_by_its_content(day: Path) -> None:
    """An older export (either CSV dialect) is replaced; a user's own events.csv or summary.json
    in it — named as c2n names its files — is not, and the folder stays as it was."""
    out = day / "export"
    argv = ["export", str(day / "d.blf"), "--no-plots", "--format", "csv", "--out", str(out)]
    assert run_cli(argv)[0] == 0
    assert run_cli([*argv, "--csv-dialect", "excel-semicolon"])[0] == 0
    assert run_cli(argv)[0] == 0
    for name, mine in (("events.csv", "my notes on the crossings\n"), ("summary.json", '{"mine": 1}\n')):
        (out / name).write_text(mine)
        before = _snapshot(out)
        code, _, err = run_cli(argv)
        assert code == 1 and f"holds files c2n did not write ({name})" in err
        assert _snapshot(out) == before
        shutil.rmtree(out)
        assert run_cli(argv)[0] == 0


OUTPUT_OPTIONS = ("--json", "--report", "--out", "--record")


def test_every_output_option_of_every_command_runs_the_guard(day: Path) -> None:
    """The class, not the cases: each command's every output option, pointed at an input (the
    config), is refused before any work — a new command or option must be added here."""
    import argparse

    from app.cli import build_parser

    pack = day / "pack"
    (pack / "sealed").mkdir(parents=True)
    seal = {"cases": {"case1": {"effect": {"name": "none", "size": 0.0}}}}  # a seal of its form
    (pack / "sealed" / "truth.json").write_text(json.dumps(seal))
    (pack / "case1").mkdir()
    shutil.copy(day / "d.blf", pack / "case1" / "drive.blf")
    (day / "manifest.csv").write_text("log,tyre_set\nd.blf,A\n")
    car = str(day / "car.toml")
    drive = str(day / "d.blf")
    before = {
        "analyze": [drive, "--config", car],
        "gap": [drive, "--config", car],
        "export": [drive, "--config", car],
        "simulate": ["--config", car],
        "live": ["-i", "virtual", "--config", car],
        "campaign": [str(day / "manifest.csv"), "--config", car],
        "gap-check": [str(pack)],
        "split": [drive, "--config", car],
    }
    inputs = {"gap-check": str(pack / "case1" / "drive.blf")}
    (subparsers,) = [a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)]
    found = 0
    for command, parser in subparsers.choices.items():
        options = [o for a in parser._actions for o in a.option_strings if o in OUTPUT_OPTIONS]
        if options:
            assert command in before, f"c2n {command} writes ({options}): add it to this test"
        for option in options:
            argv = [command, *before[command], option, inputs.get(command, car)]
            snapshot = _snapshot(day)
            code, _, err = run_cli(argv)
            assert code == 2 and "an input" in err and err.count("\n") == 1, (argv, err)
            assert _snapshot(day) == snapshot, argv
            found += 1
    assert found >= 10  # analyze, gap ×2, export, simulate, live ×2, campaign, gap-check, split


# -- round four (2026-11-28): outputs that are not plain files, or that change while c2n writes --


def test_a_device_a_pipe_or_standard_output_as_an_output_is_refused_and_left_as_it_is(day: Path) -> None:
    """A file output is renamed into place: over a pipe, a device or ``/dev/stdout`` that would
    replace the special file itself (as root, the system's); reading a pipe to see whose file it
    is would wait forever. Each is refused before any work, --force or not, in one line."""
    drive = str(day / "d.blf")
    os.mkfifo(day / "pipe.json")
    os.symlink(day / "pipe.json", day / "to_pipe.json")
    for path in ("pipe.json", "to_pipe.json"):
        for force in ([], ["--force"]):
            argv = [sys.executable, "-m", "app", "analyze", drive, "--json", str(day / path), *force]
            done = subprocess.run(argv, capture_output=True, text=True, timeout=120, cwd=REPO)
            assert done.returncode == 1 and "is a device or a pipe, not a file" in done.stderr, done.stderr
            assert done.stderr.count("\n") == 1 and "or - for standard output" in done.stderr
    assert stat.S_ISFIFO(os.lstat(day / "pipe.json").st_mode) and os.path.islink(day / "to_pipe.json")
    # the command's own standard output, named through a link (as /dev/stdout is)
    os.symlink("/proc/self/fd/1", day / "stdout.json")
    with (day / "captured.txt").open("w") as captured:
        argv = [sys.executable, "-m", "app", "analyze", drive, "--json", str(day / "stdout.json")]
        done = subprocess.run(argv, stdout=captured, stderr=subprocess.PIPE, text=True, timeout=120, cwd=REPO)
    assert done.returncode == 1 and "is this command's standard output — give - for it" in done.stderr
    assert os.readlink(day / "stdout.json") == "/proc/self/fd/1" and (day / "captured.txt").read_text() == ""
    assert not list(day.glob(".*partial*"))


def test_a_read_only_result_is_replaced_only_with_force_and_a_link_keeps_pointing(day: Path) -> None:
    drive = str(day / "d.blf")
    kept = day / "kept.json"
    assert run_cli(["analyze", drive, "--json", str(kept)])[0] == 0
    kept.chmod(0o444)
    before = kept.read_bytes()
    code, _, err = run_cli(["analyze", drive, "--json", str(kept)])
    assert code == 1 and "kept.json: is read-only" in err and "--force" in err and err.count("\n") == 1
    assert kept.read_bytes() == before
    assert run_cli(["analyze", drive, "--json", str(kept), "--force"])[0] == 0
    # a symlink is written where it points: the link stays a link
    (day / "results").mkdir()
    os.symlink(day / "results" / "summary.json", day / "latest.json")
    assert run_cli(["analyze", drive, "--json", str(day / "latest.json")])[0] == 0
    assert os.path.islink(day / "latest.json") and "c2n_ci95" in json.loads(
        (day / "results" / "summary.json").read_text()
    )
    assert run_cli(["analyze", drive, "--json", str(day / "latest.json")])[0] == 0
    assert os.path.islink(day / "latest.json")


@pytest.mark.parametrize("one_step", [True, False], ids=["traded-in-one-step", "two-renames"])
def test_files_put_in_an_output_folder_while_c2n_writes_are_kept(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, one_step: bool
) -> None:
    """An export's folder is swapped in whole and the older one removed: a log another command
    wrote there meanwhile (or a user's notes) was removed with it, exit 0. Now the older folder
    stays as it was, with them, and the run says so — also where the file system cannot trade
    the two folders in one step (renameat2's exchange)."""
    if not one_step:
        monkeypatch.setattr(files, "exchange", lambda a, b: False)
    out = tmp_path / "exp"
    out.mkdir()
    (out / "summary.json").write_text('{"c2n": 1, "c2n_ci95": [0, 2], "c2n_method": "regression"}')

    def ours(path: Path) -> bool:
        return path.name == "summary.json"

    put_in = r"notes.txt was put in it while c2n wrote — left as it is"
    with pytest.raises(OutputError, match=put_in), folder_atomically(out, ours, "c2n export") as staging:
        (staging / "summary.json").write_text("{}")
        (out / "notes.txt").write_text("my notes")  # another terminal, meanwhile
    assert sorted(p.name for p in out.iterdir()) == ["notes.txt", "summary.json"]
    assert (out / "notes.txt").read_text() == "my notes" and "c2n_method" in (
        out / "summary.json"
    ).read_text()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["exp"]  # no staging, no older folder left
    with folder_atomically(out / "new", ours, "c2n export") as staging:  # undisturbed: as before
        (staging / "summary.json").write_text("{}")
    assert [p.name for p in (out / "new").iterdir()] == ["summary.json"]


def test_an_output_folder_is_where_the_system_resolves_it(tmp_path: Path) -> None:
    """``LINK/../exp`` is ``exp`` beside the link's target, as the system opens it — where the
    guard looked — not the ``exp`` the text names, whose files were removed unasked."""
    (tmp_path / "real" / "deep").mkdir(parents=True)
    (tmp_path / "exp").mkdir()
    (tmp_path / "exp" / "sheet.xlsx").write_text("a user's")
    os.symlink(tmp_path / "real" / "deep", tmp_path / "lnk")
    with folder_atomically(tmp_path / "lnk" / ".." / "exp", lambda path: False, "c2n export") as staging:
        (staging / "summary.json").write_text("{}")
    assert [p.name for p in (tmp_path / "real" / "exp").iterdir()] == ["summary.json"]
    assert [p.name for p in (tmp_path / "exp").iterdir()] == ["sheet.xlsx"]


def test_a_mount_point_as_an_output_folder_asks_for_a_folder_inside_it(
    day: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A USB stick's mount point cannot be renamed away (EBUSY): a traceback after the whole
    analysis. Refused before any work, naming a folder inside it."""
    stick = day / "usb"
    stick.mkdir()
    real_ismount = os.path.ismount
    monkeypatch.setattr(os.path, "ismount", lambda p: os.path.realpath(p) == str(stick) or real_ismount(p))
    code, _, err = run_cli(["export", str(day / "d.blf"), "--out", str(stick), "--format", "csv"])
    assert code == 1 and err.count("\n") == 1
    assert "is a mount point, which c2n cannot put a folder in place of" in err
    assert f"give a folder inside it (e.g. {stick / 'c2n'})" in err
    assert list(stick.iterdir()) == []


def test_a_log_copied_over_another_of_the_same_size_and_date_is_hashed_again(tmp_path: Path) -> None:
    """The hash memo knew a log by its size and mtime: a logger without a clock (every file the
    same date), or one that cuts files at a size, writes another drive with both the same, and
    the campaign gave the earlier drive's C2n for it ("1 known from an earlier run"). The change
    time and inode are remembered too."""
    log = tmp_path / "LOG0001.log"
    log.write_bytes(b"(1.000000) can0 123#00\n" * 100)
    os.utime(log, ns=(315532800 * 10**9, 315532800 * 10**9))  # 1980-01-01, a clock never set
    memo = HashMemo(tmp_path / "hashes.json")
    first = memo.key(Job(log, None))
    memo.save()
    assert HashMemo(tmp_path / "hashes.json").key(Job(log, None)) == first  # remembered
    log.write_bytes(b"(1.000000) can0 123#01\n" * 100)  # another drive, the same size
    os.utime(log, ns=(315532800 * 10**9, 315532800 * 10**9))
    assert HashMemo(tmp_path / "hashes.json").key(Job(log, None)) != first


def test_a_folder_named_cache_is_a_campaign_s_only_by_its_content(tmp_path: Path) -> None:
    """A campaign's --out may hold its own cache; a user's folder that is merely named ``cache``
    (its hashes.json was written over) is not c2n's; a damaged hash memo is no memo."""
    manifest = tmp_path / "manifest.csv"
    manifest.write_text("log,tyre_set\na.blf,A\n")
    mine = tmp_path / "mine"
    (mine / "cache").mkdir(parents=True)
    (mine / "cache" / "hashes.json").write_text("my own list\n")
    code, _, err = run_cli(["campaign", str(manifest), "--out", str(mine), "--workers", "1"])
    assert code == 1 and "holds files c2n did not write (cache)" in err
    assert (mine / "cache" / "hashes.json").read_text() == "my own list\n"
    assert [p.name for p in mine.iterdir()] == ["cache"]
    out = tmp_path / "out"
    assert run_cli(["campaign", str(manifest), "--out", str(out), "--workers", "1"])[0] == 0
    assert run_cli(["campaign", str(manifest), "--out", str(out), "--workers", "1"])[0] == 0  # its own
    (out / "cache" / "hashes.json").write_text("[]")
    assert HashMemo(out / "cache" / "hashes.json").key(Job(manifest, None)) is not None


def test_an_interrupted_or_killed_write_leaves_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "x.blf"
    with pytest.raises(KeyboardInterrupt):
        write_atomically(target, lambda tmp: (tmp.write_text("half"), _interrupt()), "the log")
    assert list(tmp_path.iterdir()) == []
    dead = partial_path(target).name.replace(str(os.getpid()), "999999999")
    (tmp_path / dead).write_text("a killed run's")
    alive = partial_path(target).name.replace(str(os.getpid()), str(os.getppid()))
    (tmp_path / alive).write_text("a running one's")
    write_atomically(target, lambda tmp: tmp.write_text("whole"), "the log")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted([alive, "x.blf"])


def _interrupt() -> None:
    raise KeyboardInterrupt


def test_an_undecodable_folder_name_is_written_as_text(tmp_path: Path) -> None:
    """A folder named in Latin-1 on a UTF-8 system (``p\\xff``): its name reaches the results'
    text as surrogate escapes, which UTF-8 and Parquet refused (a traceback after all the work)."""
    folder = Path(os.fsdecode(bytes(tmp_path) + b"/p\xff"))
    folder.mkdir()
    name = os.fsdecode(b"logs/\xfe.blf")
    write_tables(folder, ["log", "c2n"], [{"log": name, "c2n": 15.0}])
    text = (folder / "results.csv").read_text(encoding="utf-8-sig")
    assert text.splitlines()[1] == "logs/\ufffd.blf,15"
    import pyarrow.parquet as pq

    with (folder / "results.parquet").open("rb") as file:
        assert pq.read_table(file).to_pylist() == [{"log": "logs/\ufffd.blf", "c2n": 15.0}]
    write_text(folder / "page.html", f"<title>{name}</title>", "the report")
    assert (folder / "page.html").read_text(encoding="utf-8") == "<title>logs/\ufffd.blf</title>"


def _a_dead_pid() -> int:
    child = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True)
    return int(child.stdout)


def _summary_ours(path: Path) -> bool:
    return path.name == "summary.json"


def test_an_output_folder_is_never_missing_while_the_new_one_is_swapped_in(tmp_path: Path) -> None:
    """The older folder was renamed away, then the new one renamed in: a kill between the two
    (or a power cut) left no ``--out`` at all and the user's previous output hidden, which no
    later run put back. The two now trade places in one step; here the run dies at the moment
    the older folder is looked at after the swap."""
    out = tmp_path / "exp"
    out.mkdir()
    (out / "summary.json").write_text("older")
    swapped = False

    def ours(path: Path) -> bool:
        if swapped:
            raise SystemExit("killed")
        return _summary_ours(path)

    with pytest.raises(SystemExit), folder_atomically(out, ours, "c2n export") as staging:
        (staging / "summary.json").write_text("newer")
        swapped = True
    assert (out / "summary.json").read_text() == "newer"


def test_an_older_folder_a_killed_run_left_swapped_away_is_put_back(tmp_path: Path) -> None:
    """Where the folders cannot trade places in one step (a file system without it), a run
    killed between its two renames leaves ``.exp.old-PID-…`` and no ``exp``: the next run puts
    it back; one left beside a new ``exp`` goes, unless it holds a user's file."""
    out = tmp_path / "exp"
    orphan = tmp_path / f".exp.old-{_a_dead_pid()}-0123abcd"
    orphan.mkdir()
    (orphan / "summary.json").write_text("the previous export")
    full = "channels.csv: cannot write the CSV channels (No space left on device)"

    def no_space(tmp: Path) -> None:
        raise OSError(errno.ENOSPC, "No space left on device")

    with (
        pytest.raises(OutputError) as refused,
        folder_atomically(out, _summary_ours, "c2n export") as staging,
    ):
        write_atomically(staging / "channels.csv", no_space, "the CSV channels")
    assert str(refused.value) == f"{out / full} — {out} is left as it was"  # not the hidden staging
    assert [p.name for p in tmp_path.iterdir()] == ["exp"]
    assert (out / "summary.json").read_text() == "the previous export"

    orphan.mkdir()
    (orphan / "summary.json").write_text("an older export")
    running = tmp_path / f".exp.old-{os.getpid()}-4567cdef"  # a run between its renames now
    running.mkdir()
    with folder_atomically(out, _summary_ours, "c2n export") as staging:
        (staging / "summary.json").write_text("newer")
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["exp", running.name])
    running.rmdir()

    orphan.mkdir()
    (orphan / "notes.txt").write_text("a user's")
    with folder_atomically(out, _summary_ours, "c2n export") as staging:
        (staging / "summary.json").write_text("newest")
    assert (orphan / "notes.txt").read_text() == "a user's" and (out / "summary.json").read_text() == "newest"


def test_a_folder_c2n_cannot_write_in_is_said_before_the_analysis(
    day: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A read-only mount (or a folder without write permission) as where the output goes was
    found only after the whole analysis. Root writes through permissions, so the system's
    refusal is stood in for here as a read-only mount gives it (EROFS)."""
    import tempfile

    shelf = day / "shelf"
    shelf.mkdir()
    real = tempfile.TemporaryFile

    def read_only(*args: object, dir: object = None, **kwargs: object) -> object:
        if dir is not None and Path(str(dir)) == shelf:
            raise OSError(errno.EROFS, "Read-only file system")
        return real(*args, dir=dir, **kwargs)  # type: ignore[call-overload]

    monkeypatch.setattr(tempfile, "TemporaryFile", read_only)
    drive, car = str(day / "d.blf"), ["--config", str(day / "car.toml")]
    code, out, err = run_cli(["export", drive, *car, "--out", str(shelf / "sub" / "exp"), "--no-plots"])
    said = f"--out {shelf / 'sub' / 'exp'}: cannot write in {shelf} (Read-only file system)"
    assert code == 1 and err.strip().endswith(f"{said} — choose another place")
    assert "C2n" not in out and list(shelf.iterdir()) == []  # said before the drive was read
    code, _, err = run_cli(["analyze", drive, *car, "--json", str(shelf / "r.json")])
    assert code == 1 and f"cannot write in {shelf} (Read-only file system)" in err


@pytest.mark.parametrize("option", ["--json", "--out"])
def test_an_output_under_a_file_is_said_before_the_analysis(day: Path, option: str) -> None:
    """`--json notes.txt/r.json`: the whole analysis ran, then `cannot write the summary (File
    exists)`, which names neither the file nor the cause."""
    notes = day / "notes.txt"
    notes.write_text("a user's")
    command = ["analyze", "--json"] if option == "--json" else ["export", "--no-plots", "--out"]
    code, out, err = run_cli(
        [
            command[0],
            str(day / "d.blf"),
            "--config",
            str(day / "car.toml"),
            *command[1:],
            str(notes / "sub" / "r"),
        ]
    )
    assert code == 1 and err.count("\n") == 1
    assert f"{option} {notes / 'sub' / 'r'}: {notes} is a file, not a folder — choose another place" in err
    assert "C2n" not in out and notes.read_text() == "a user's"


def test_a_campaign_cache_whose_hash_memo_is_damaged_is_hashed_again(day: Path) -> None:
    """A hash memo that does not read beside the cache's rows was taken for a user's file, and
    the campaign's own folder refused as not c2n's."""
    manifest = day / "manifest.csv"
    manifest.write_text("log,tyre_set\nd.blf,A\n")
    out = day / "campaign"
    args = ["campaign", str(manifest), "--config", str(day / "car.toml"), "--out", str(out), "--workers", "1"]
    assert run_cli(args)[0] == 0
    (out / "cache" / "hashes.json").write_text('{"truncated": [1')
    code, _, err = run_cli(args)
    assert code == 0, err
    assert json.loads((out / "cache" / "hashes.json").read_text())  # a memo again


def test_a_file_given_as_live_s_record_folder_is_named_a_file_and_kept(tmp_path: Path) -> None:
    """``--record`` is a folder c2n makes a session in, never replaces: a file there was told
    ``add --force to replace it``, which did not (and must not) replace it."""
    notes = tmp_path / "notes"
    notes.write_text("a user's")
    for force in ([], ["--force"]):
        argv = ["live", "-i", "virtual", "-c", "c2n-record-file", "--record", str(notes), "--duration", "0.1"]
        code, _, err = run_cli([*argv, *force])
        assert code == 1 and "is a file, not a folder" in err and "--force" not in err, err
        assert notes.read_text() == "a user's"


def test_a_pack_written_again_into_its_own_folder_is_told_the_folder_is_not_empty(tmp_path: Path) -> None:
    """A pack is never written over; refusing c2n's own earlier pack as "files c2n did not write"
    was untrue."""
    pack = tmp_path / "pack"
    (pack / "case_001").mkdir(parents=True)
    (pack / "sealed").mkdir()
    code, _, err = run_cli(["simulate", "--pack", "1", "--quick", "--out", str(pack)])
    assert code == 1 and err.strip() == (
        f"c2n: error: --out {pack}: is not empty (case_001, sealed) — choose a new or empty folder"
    )


def test_a_result_s_inputs_are_the_same_files_not_the_same_names(tmp_path: Path) -> None:
    """helper-31: a summary recording `day.blf` (as typed) was taken for any log of that name —
    `analyze day.blf` from another folder replaced an export's summary with another drive's; an
    export through a link, re-pointed, was replaced by the new target's; `d1 d1` matched `d3 d1`.
    And the same file was refused from another folder, through a hard link. Now the inputs are
    the same files (a relative record read from the result's folder and its parent, never from
    here), each once; a default export folder's log of the same name is the log moved with it."""
    from app.output.paths import same_inputs

    (tmp_path / "B").mkdir()
    day, other = tmp_path / "day.blf", tmp_path / "B" / "day.blf"
    day.write_bytes(b"1")
    other.write_bytes(b"2")
    export = tmp_path / "day-export"
    export.mkdir()
    assert same_inputs(["day.blf"], [day], export)  # analyze's record, typed beside the log
    assert not same_inputs(["day.blf"], [other], export)  # a log of that name elsewhere
    os.link(day, tmp_path / "hard.blf")
    assert same_inputs([str(day)], [tmp_path / "hard.blf"], export)
    (tmp_path / "link.blf").symlink_to(day)
    assert same_inputs([str(day)], [tmp_path / "link.blf"], export)
    assert not same_inputs([str(tmp_path / "link.blf")], [other], export)
    assert same_inputs([str(other), str(day)], [day, other], export)  # any order
    assert not same_inputs([str(other), str(day)], [day, day], export)  # each once
    moved = "/gone/day.blf"  # the log and its export moved together
    assert not same_inputs([moved], [day], export) and same_inputs([moved], [day], export, by_name=True)
    assert not same_inputs(["Virtual bus channel ch1"], [day], export)
