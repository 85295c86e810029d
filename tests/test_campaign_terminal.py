"""What `c2n campaign` says in the terminal: every group of --by, a group none of whose sessions
gave a C2n too, with why; and nothing of Dask's own bookkeeping."""

import json
import logging
import socket
import subprocess
import sys
from pathlib import Path

import pytest
from rich.console import Console

from app.campaign.comparison import compare, write_comparison
from app.campaign.manifest import read_manifest
from app.campaign.meta_analysis import Estimate, no_trend
from app.campaign.report import write_report
from app.campaign.row import SessionResult, SessionRow
from app.cli.campaign import print_comparison, quiet_dask
from tests.test_campaign import run_cli
from tests.test_campaign_inputs import C2N, _manifest, _rows

# -- a group none of whose sessions gave a C2n ------------------------------------------------


def test_a_group_whose_sessions_all_failed_is_shown_with_its_reasons_counted(tmp_path: Path) -> None:
    """Tyre set B's three drives give no C2n (two unreadable, one a session folder's damaged
    frames): its line says so, the reasons counted without each log's name, in the terminal,
    comparison.json and the report — it was left out of all three without a word."""
    text = "log,tyres\na1.blf,A\nb1.blf,B\na2.blf,A\nb2.blf,B\nS,B\na3.blf,A\n"
    manifest = read_manifest(_manifest(tmp_path, text))
    good = iter(_rows(C2N[:3]))
    logs = [e.log for e in manifest.entries]  # as the workers name them in their errors: resolved
    folder = logs[0].parent
    errors = {
        "b1.blf": f"{folder / 'b1.blf'}: no CAN frames in the file",
        "b2.blf": f"{folder / 'b2.blf'}: no CAN frames in the file",
        "S": f"{folder / 'S'}/frames.blf: not a readable log, damaged from the start",
    }
    rows = [SessionRow(error=errors[e.name]) if e.name in errors else next(good) for e in logs]
    comparison = compare(manifest, rows, "tyres")
    console = Console(record=True, width=300)
    print_comparison(console, comparison, "tyres")
    lines = console.export_text().splitlines()
    assert lines[0].startswith("  tyres A: C2n = 15.033 1/rad")
    assert lines[1] == (
        "  tyres B: 3 sessions, none gave a C2n: 2× no CAN frames in the file; "
        "1× not a readable log, damaged from the start"
    )
    assert len(lines) == 2  # one group with a C2n: no difference
    said = comparison.to_json()["no_c2n"]
    assert said == {
        "B": {
            "n_sessions": 3,
            "reasons": {"no CAN frames in the file": 2, "not a readable log, damaged from the start": 1},
        }
    }
    write_comparison(tmp_path, comparison)
    assert json.loads((tmp_path / "comparison.json").read_text())["no_c2n"] == said
    write_report(tmp_path, comparison, "campaign")
    assert "tyres B: 3 sessions, none gave a C2n: 2× no CAN frames" in (tmp_path / "report.html").read_text()


def test_the_terminal_names_every_group_of_by_even_where_no_log_could_be_read(tmp_path: Path) -> None:
    """The command itself: logs that are missing or damaged, in two tyre sets and with no --by."""
    (tmp_path / "damaged.blf").write_bytes(b"LOGG" + bytes(300))
    path = _manifest(tmp_path, "log,tyres\ngone1.blf,A\ngone2.blf,B\ndamaged.blf,B\ngone3.blf,B\n")
    code, text, err = run_cli(["campaign", str(path), "--by", "tyres", "--workers", "1"])
    assert code == 0 and "c2n: 4 of 4 sessions failed" in err
    assert "  tyres A: 1 session, none gave a C2n: 1× No such file or directory\n" in text
    unreadable = "1× not a readable .blf log"
    assert f"  tyres B: 3 sessions, none gave a C2n: 2× No such file or directory; {unreadable}" in text
    code, text, _ = run_cli(["campaign", str(path), "--workers", "1", "--out", str(tmp_path / "one")])
    assert code == 0
    assert f"  all sessions: 4 sessions, none gave a C2n: 3× No such file or directory; {unreadable}" in text


# -- Dask's own log lines ----------------------------------------------------------------------


def test_a_local_dask_cluster_keeps_its_bookkeeping_out_of_the_terminal(tmp_path: Path) -> None:
    """`--scheduler local` printed ~40 of Dask's INFO lines ('Start Nanny at', 'Register worker',
    'Scheduler closing all comms' …) and, with port 8787 taken (a Jupyter's Dask, another
    campaign), a four-line UserWarning about a dashboard it does not start: the terminal holds
    the campaign's own words alone."""
    pytest.importorskip("distributed")
    path = _manifest(tmp_path, "log\ngone.blf\n")
    with socket.socket() as taken:
        try:
            taken.bind(("", 8787))
            taken.listen()
        except OSError:  # taken already: as the test wants it
            pass
        done = subprocess.run(
            [sys.executable, "-m", "app", "campaign", str(path), "--scheduler", "local"],
            capture_output=True,
            text=True,
            timeout=300,
            cwd=Path(__file__).parent.parent,
        )
    assert done.returncode == 0, done.stderr
    assert f"c2n: warning: {tmp_path / 'gone.blf'}: No such file or directory\n" in done.stderr
    assert "c2n: 1 of 1 session failed (see report.html)\n" in done.stderr
    assert "c2n: info:" not in done.stderr and "Warning" not in done.stderr, done.stderr
    assert "1 session in " in done.stdout and "all sessions: 1 session, none gave a C2n" in done.stdout


def test_dask_s_warnings_and_errors_still_reach_the_terminal() -> None:
    distributed = logging.getLogger("distributed")
    before = distributed.level
    try:
        distributed.setLevel(logging.INFO)  # as importing distributed leaves it
        quiet_dask(debug=False)
        scheduler = logging.getLogger("distributed.scheduler")
        assert not scheduler.isEnabledFor(logging.INFO)
        assert scheduler.isEnabledFor(logging.WARNING) and scheduler.isEnabledFor(logging.ERROR)
        distributed.setLevel(logging.INFO)
        quiet_dask(debug=True)  # --debug shows it all
        assert scheduler.isEnabledFor(logging.INFO)
    finally:
        distributed.setLevel(before)


# -- a group of one session; a group named "all" --------------------------------------------------


def test_a_group_of_one_session_keeps_that_sessions_own_interval(tmp_path: Path) -> None:
    """A 7-second drive's C2n of 16.132 [9.851, 44.410] (a regression's interval, the reciprocal of
    its a_y coefficient's) alone in its group: the group's interval is it, in the terminal, the
    JSON and the trend plot's bar. Made again as wide about C2n, it read [-1.148, 33.411]."""
    text = "log,tyres,p\nshort.blf,S,250\na1.blf,A,230\na2.blf,A,240\n"
    manifest = read_manifest(_manifest(tmp_path, text))
    short = SessionRow(
        result=SessionResult(Estimate(16.132, (9.851, 44.410), 8.79), 0.0, None, None), key="s"
    )
    comparison = compare(manifest, [short, *_rows([15.0, 15.2])], "tyres")
    assert comparison.groups["S"].ci95 == (9.851, 44.410)
    assert comparison.to_json()["groups"]["S"]["ci95"] == [9.851, 44.410]
    assert comparison.groups["A"].ci95[0] < 15.0 < comparison.groups["A"].ci95[1]  # pooled as before
    console = Console(record=True, width=300)
    print_comparison(console, comparison, "tyres")
    assert "  tyres S: C2n = 16.132 1/rad [9.851, 44.410] (95 %, 1 session" in console.export_text()
    [short_point] = comparison.tag_values["p"]["S"]
    assert short_point[3:] == (9.851, 44.410)  # the plot's bar: the session's own ends


def test_a_by_group_named_all_is_refused_before_any_work(tmp_path: Path) -> None:
    """'all' keys the trend over every session: a group of that name overwrote it, and the
    report said of a tag with five sessions 'the fit overflows: no trend'."""
    path = _manifest(tmp_path, "log,tyres\na.blf,A\nb.blf,all\n")
    code, _, err = run_cli(["campaign", str(path), "--by", "tyres", "--workers", "1"])
    assert code == 2
    assert "line 3: the --by tyres group 'all' has the name of the trend over all sessions" in err
    assert not (tmp_path / "manifest-campaign").exists()


def test_one_session_with_a_value_is_said_to_be_one() -> None:
    """Not 'takes one value': one session's value is no spread of values to fit."""
    said = no_trend([2.0], 4)
    assert said.startswith("1 session with a C2n and a value: a trend needs three")
    assert said.endswith("(4 sessions with a C2n have no value: left out)")
