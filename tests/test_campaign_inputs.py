"""A campaign's inputs as users and spreadsheets write them: a manifest saved where the decimal
mark is a comma, a tag a spreadsheet rounded, tags near the ends of a float, a session folder
whose frames are a pipe; and the counts said in words."""

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from rich.console import Console

from app.campaign.comparison import compare, write_comparison
from app.campaign.manifest import read_manifest
from app.campaign.meta_analysis import Estimate, trend
from app.campaign.report import write_report
from app.campaign.row import SessionResult, SessionRow
from app.cli.campaign import print_comparison
from app.errors import C2nError
from tests.test_campaign import run_cli

C2N = [15.0, 15.2, 14.9, 15.1]  # the sessions' C2n [1/rad], each ±0.2 (95 %)


def _rows(c2n: list[float]) -> list[SessionRow]:
    """Campaign rows as workers return them, each with its headline C2n."""
    return [
        SessionRow(result=SessionResult(Estimate(c, (c - 0.2, c + 0.2), 0.1), 0.0, None, None), key=str(i))
        for i, c in enumerate(c2n)
    ]


def _manifest(folder: Path, text: str, name: str = "manifest.csv") -> Path:
    path = folder / name
    path.write_text(text, encoding="utf-8")
    return path


# -- decimal commas ---------------------------------------------------------------------------

SEMICOLON = """log;tyre_set;pressure_bar;temp_C
s001.blf;A;2,0;20,5
s002.blf;B;2,3;21,5
s003.blf;C;2,6;19
s004.blf;A;2,1;22,5
"""
COMMA = SEMICOLON.replace(",", ".").replace(";", ",")


def test_a_semicolon_manifest_reads_decimal_commas_as_numbers(tmp_path: Path) -> None:
    """Excel where the decimal mark is a comma writes ';' between fields and '2,0' for 2.0: the
    same trends as the manifest written with ',' and '.', and the same tags in the results."""
    semicolon = read_manifest(_manifest(tmp_path, SEMICOLON, "semicolon.csv"))
    comma = read_manifest(_manifest(tmp_path, COMMA, "comma.csv"))
    assert semicolon.numeric_tags() == comma.numeric_tags() == ["pressure_bar", "temp_C"]
    assert [e.tags for e in semicolon.entries] == [e.tags for e in comma.entries]
    assert semicolon.warnings == ()
    trends = compare(semicolon, _rows(C2N), "tyre_set").trends
    assert trends == compare(comma, _rows(C2N), "tyre_set").trends
    assert set(trends) == {"pressure_bar", "temp_C"} and "all" in trends["pressure_bar"]


def test_a_point_in_a_semicolon_manifest_is_no_decimal_mark_it_could_be_sure_of(tmp_path: Path) -> None:
    """Where the decimal mark is a comma a point groups thousands: '1.200' N is 1200 there, and it
    was read as 1.2 — a trend of C2n over 1.2, 950 and 1.5 N, no word. A column with a point in
    a ';' manifest is kept as text, said; its commas' column is read as before. '1_000' and '2_3'
    (Python's float reads 23) are a code's spelling, not numbers."""
    text = (
        "log;load_N;pressure_bar;fw;code\n"
        "a.blf;1.200;2,0;1.5;1_000\nb.blf;950;2,3;1.10;2_3\nc.blf;1.500;2,6;2.0;7\n"
    )
    manifest = read_manifest(_manifest(tmp_path, text))
    assert manifest.numeric_tags() == ["pressure_bar"]
    assert [e.tags["load_N"] for e in manifest.entries] == ["1.200", "950", "1.500"]  # as written
    [load, fw] = manifest.warnings
    assert "line 2, column 'load_N': '1.200' has a point, in a manifest separated by ';'" in load
    assert "'1.200' is 1200, not 1.2) — the column is kept as text, with no trend against it" in load
    assert "line 2, column 'fw': '1.5' has a point" in fw
    trends = compare(manifest, _rows(C2N[:3]), None).trends
    assert set(trends) == {"pressure_bar"}


def test_a_column_mixing_decimal_commas_with_other_values_says_which_it_could_not_read(
    tmp_path: Path,
) -> None:
    """A value with a decimal point among decimal commas, or no number, is not guessed at: the
    column stays text, and the terminal names the file, the line, the column and the value."""
    text = "log;pressure_bar;driver\ngone1.blf;2,0;Smith, J\ngone2.blf;2,3;Jones\ngone3.blf;2.6;Lee\n"
    manifest = read_manifest(_manifest(tmp_path, text))
    assert manifest.numeric_tags() == []
    assert [e.tags["pressure_bar"] for e in manifest.entries] == ["2,0", "2,3", "2.6"]
    assert len(manifest.warnings) == 1  # 'Smith, J' is no number written with a decimal comma
    warning = manifest.warnings[0]
    assert f"{tmp_path / 'manifest.csv'}: line 4, column 'pressure_bar': '2.6'" in warning
    assert "no trend" in warning and "'2,0'" in warning
    code, _, err = run_cli(["campaign", str(tmp_path / "manifest.csv"), "--workers", "1"])
    assert code == 0 and f"c2n: warning: {warning}\n" in err and "Traceback" not in err


# -- tags a spreadsheet rounded, tags near a float's ends ----------------------------------------


def test_a_tag_constant_to_a_spreadsheet_s_precision_takes_one_value(tmp_path: Path) -> None:
    """2.3 and 2.3000000000000003 are one value to a spreadsheet (15 significant digits): no
    trend (a line through them had a slope of 1e14 1/rad per bar), and the report says why."""
    assert trend([2.3, 2.3, 2.3, 2.3000000000000003], C2N, [0.1] * 4) is None
    fitted = trend([2.3, 2.3, 2.4, 2.4000000000000004], C2N, [0.1] * 4)
    assert fitted is not None and abs(fitted.slope) < 10  # 2.4 is another value
    text = "log,pressure_bar\na.blf,2.3\nb.blf,2.3\nc.blf,2.3\nd.blf,2.3000000000000003\n"
    comparison = compare(read_manifest(_manifest(tmp_path, text)), _rows(C2N), None)
    assert comparison.trends == {"pressure_bar": {}}
    assert comparison.no_trend == {"pressure_bar": "takes one value: no trend"}
    write_comparison(tmp_path, comparison)
    said = json.loads((tmp_path / "comparison.json").read_text())
    assert said["no_trend"] == {"pressure_bar": "takes one value: no trend"}
    write_report(tmp_path, comparison, "campaign")
    assert "pressure_bar takes one value: no trend" in (tmp_path / "report.html").read_text()


def test_a_word_in_a_column_of_numbers_is_said_where_it_drops_the_trend(tmp_path: Path) -> None:
    """'n/a' among pressures made the column text: its trend went, without a word."""
    text = "log,pressure_bar,driver\na.blf,2.3\nb.blf,n/a,x\nc.blf,2.5,y\nd.blf,2.6,z\n".replace(
        "2.3\n", "2.3,w\n"
    )
    manifest = read_manifest(_manifest(tmp_path, text))
    assert manifest.numeric_tags() == []
    [said] = manifest.warnings
    assert said.endswith(
        "line 3, column 'pressure_bar': 'n/a' is not a number, where 3 of the column's 4 values are — "
        "the column is kept as text, with no trend against it; write a number (no unit), or leave the "
        "cell empty"
    )
    words = read_manifest(_manifest(tmp_path, "log,day\na.blf,mon\nb.blf,tue\nc.blf,1\n"))
    assert words.warnings == ()  # mostly words: a text column, nothing lost


def test_one_value_of_a_numeric_group_tag_is_one_group_however_spelt(tmp_path: Path) -> None:
    """`--by pressure_kPa` grouped 230 and 230.0 apart: two groups of one pressure."""
    text = "log,pressure_kPa\na.blf,230\nb.blf,230.0\nc.blf,250\nd.blf,2.5e2\n"
    comparison = compare(read_manifest(_manifest(tmp_path, text)), _rows(C2N), "pressure_kPa")
    assert sorted(comparison.groups) == ["230", "250"]
    assert comparison.groups["230"].n_sessions == comparison.groups["250"].n_sessions == 2
    text = "log,tyre\na.blf,A\nb.blf,A \nc.blf,a\nd.blf,B\n"  # text: as written (its cells stripped)
    assert sorted(compare(read_manifest(_manifest(tmp_path, text)), _rows(C2N), "tyre").groups) == [
        "A",
        "B",
        "a",
    ]


def test_a_numeric_tag_with_an_empty_cell_is_fitted_on_the_rows_with_a_value_and_says_so(
    tmp_path: Path,
) -> None:
    """A pressure not noted on one line: the column is still numeric (it was taken for text, with
    no trend and no word why), the trend is fitted on the other rows and the row left out is
    named — one line in the terminal before the work, ``no_value`` in comparison.json, the report.
    Too few rows left with a value: ``no_trend`` says so, and why."""
    path = _manifest(tmp_path, "log,pressure_bar\na.blf,2.0\nb.blf,\nc.blf,2.4\nd.blf,2.6\n")
    manifest = read_manifest(path)
    assert manifest.numeric_tags() == ["pressure_bar"] and manifest.empty_cells() == {"pressure_bar": [3]}
    comparison = compare(manifest, _rows(C2N), None)
    fitted = comparison.trends["pressure_bar"]["all"]
    assert fitted == trend([2.0, 2.4, 2.6], [C2N[0], C2N[2], C2N[3]], [0.1] * 3) and fitted.n_sessions == 3
    assert comparison.no_value == {"pressure_bar": ["b.blf"]} and comparison.no_trend == {}
    write_comparison(tmp_path, comparison)
    said = json.loads((tmp_path / "comparison.json").read_text())
    assert said["no_value"] == {"pressure_bar": ["b.blf"]} and said["trends"]["pressure_bar"]["all"]
    write_report(tmp_path, comparison, "campaign")
    assert "pressure_bar: left out, no value in the manifest: b.blf" in (tmp_path / "report.html").read_text()
    code, _, err = run_cli(["campaign", str(path), "--workers", "1"])
    assert code == 0 and "Traceback" not in err
    assert (
        f"c2n: warning: {path}: column 'pressure_bar' has 1 empty cell of 4 (line 3) — the trends "
        "against it leave that row out\n"
    ) in err
    _, _, err = run_cli(["campaign", str(path), "--workers", "1", "--by", "pressure_bar"])
    assert "empty cell" not in err  # a group of its own, "(empty)": no trend against it to leave it out of

    two = read_manifest(_manifest(tmp_path, "log,p\na.blf,2.0\nb.blf,\nc.blf,\nd.blf,2.6\n", "two.csv"))
    assert two.empty_cells_warning("p") == (
        f"{tmp_path / 'two.csv'}: column 'p' has 2 empty cells of 4 (lines 3, 4) — the trends against it "
        "leave those rows out"
    )
    comparison = compare(two, _rows(C2N), None)
    assert comparison.trends == {"p": {}} and comparison.no_value == {"p": ["b.blf", "c.blf"]}
    assert comparison.no_trend == {
        "p": "2 sessions with a C2n and a value: a trend needs three "
        "(2 sessions with a C2n have no value: left out)"
    }


@pytest.mark.parametrize(
    "values", [(1e308, -1e308, 0.0, 1.0), (1.7e308, 1e308, 1.5e308, 1.6e308), (-8e307, 8e307, 0.0, 1.0)]
)
def test_a_tag_near_the_ends_of_a_float_is_fitted_and_plotted(
    tmp_path: Path, values: tuple[float, ...]
) -> None:
    """The trend is fitted on the tag centred and scaled (docs/campaigns.md); its plot, too, is
    drawn on the tag scaled, where matplotlib's ticks would overflow past ~1e307."""
    text = "log,load\n" + "".join(f"{i}.blf,{v!r}\n" for i, v in enumerate(values))
    comparison = compare(read_manifest(_manifest(tmp_path, text)), _rows(C2N), None)
    assert comparison.trends["load"]["all"].n_sessions == 4
    write_report(tmp_path, comparison, "campaign")
    report = (tmp_path / "report.html").read_text()
    assert "C2n against load" in report and "<img" in report


# -- a session folder whose frames are a pipe --------------------------------------------------


def test_a_session_folder_whose_frames_are_a_pipe_is_refused_before_any_work(tmp_path: Path) -> None:
    """Opening a pipe for reading waits for a writer that never comes: the campaign hung in its
    hash memo. The manifest refuses it, as it refuses a pipe it names itself."""
    session = tmp_path / "S"
    (session / "config").mkdir(parents=True)
    os.mkfifo(session / "frames.log")
    manifest = _manifest(tmp_path, "log\nS\n")
    done = subprocess.run(
        [sys.executable, "-m", "app", "campaign", str(manifest), "--workers", "1"],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=Path(__file__).parent.parent,
    )
    assert done.returncode == 1 and done.stderr.count("\n") == 1, done.stderr
    assert "line 2 names S, whose frames.log is no file (a device or a pipe)" in done.stderr
    assert not (tmp_path / "manifest-campaign").exists()


def test_a_pipe_is_never_opened_for_its_hash(tmp_path: Path) -> None:
    """A pipe swapped in after the manifest was read: hashing it fails at once, never waits."""
    pipe = tmp_path / "frames.log"
    os.mkfifo(pipe)
    hashing = (
        "import sys\nfrom pathlib import Path\nfrom app.campaign.analysis import content_hash\n"
        "from app.errors import C2nError\ntry:\n    content_hash([Path(sys.argv[1])])\n"
        "except C2nError as error:\n    print(error)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", hashing, str(pipe)],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=Path(__file__).parent.parent,
    )
    assert done.stdout == f"{pipe}: not a regular file (a device or a pipe) — name a log file\n", done.stderr


# -- counts in words ---------------------------------------------------------------------------


def test_one_session_is_one_session(tmp_path: Path) -> None:
    manifest = read_manifest(_manifest(tmp_path, "log,tyre_set\na.blf,A\nb.blf,B\nc.blf,B\n"))
    comparison = compare(manifest, _rows(C2N[:3]), "tyre_set")
    console = Console(record=True, width=200)
    print_comparison(console, comparison, "tyre_set")
    shown = console.export_text()
    assert "(95 %, 1 session, τ" in shown and "(95 %, 2 sessions, τ" in shown
    _manifest(tmp_path, "log\ngone.blf\n", "one.csv")
    code, text, err = run_cli(["campaign", str(tmp_path / "one.csv"), "--workers", "1"])
    assert code == 0 and "\n1 session in " in text and "c2n: 1 of 1 session failed" in err


def test_a_log_name_no_file_system_holds_is_one_line(tmp_path: Path) -> None:
    """A manifest line naming a file of 300 bytes' name (a pasted name run on): one line naming
    the manifest's line, before any work (it was `OSError: [Errno 36]`'s traceback)."""
    manifest = _manifest(tmp_path, "log,tyre_set\n" + "a" * 300 + ".log,A\n")
    with pytest.raises(
        C2nError, match=r"line 2 names a{40}…, which cannot be looked up \(File name too long\)"
    ):
        read_manifest(manifest)
    manifest = _manifest(tmp_path, "log,tyre_set\nday1\0.blf,A\n", "nul.csv")  # was ValueError's traceback
    with pytest.raises(C2nError, match=r"line 2 names a log whose name holds a NUL byte — check the name"):
        read_manifest(manifest)


def test_results_csv_answers_a_semicolon_manifest_in_its_own_dialect(tmp_path: Path) -> None:
    """A manifest saved where the decimal mark is a comma gets results.csv the same way: ';'
    between fields, its numbers (C2n, the pressures it gave) with a decimal comma, text as it
    is (it was always ',' and '.': one column per row in that spreadsheet); ``--csv-dialect
    excel`` asks for ',' and '.'; a second run replaces the campaign's own results.csv either
    way."""
    import csv

    from app.sim.simulated_drive import write_drive
    from tests.simulated import cached_drive

    write_drive(cached_drive("constant_radius", 41, 15.1), tmp_path / "s 1.blf")
    path = _manifest(tmp_path, "log;tyre_set;pressure_bar\ns 1.blf;A;2,5\ngone.blf;B;2,3\n")
    out = tmp_path / "manifest-campaign"
    for dialect, (delimiter, mark) in ((None, (";", ",")), ("excel", (",", "."))):
        argv = ["campaign", str(path), "--workers", "1", *(["--csv-dialect", dialect] if dialect else [])]
        code, _, err = run_cli(argv)
        assert code == 0, err
        text = (out / "results.csv").read_text(encoding="utf-8-sig")
        assert text.startswith(f"log{delimiter}tyre_set{delimiter}pressure_bar{delimiter}")
        drive, gone = csv.DictReader(text.splitlines(), delimiter=delimiter)
        assert (drive["log"], drive["pressure_bar"], gone["pressure_bar"]) == (
            "s 1.blf",
            f"2{mark}5",
            f"2{mark}3",
        )
        assert 14.6 < float(drive["c2n"].replace(mark, ".")) < 15.6 and mark in drive["c2n"]
        assert gone["c2n"] == "" and "gone.blf" in gone["error"]


def test_a_results_csv_edited_since_or_a_users_own_is_not_replaced(tmp_path: Path) -> None:
    """A results.csv was c2n's if it began with a BOM and `log,` — what Excel's "CSV UTF-8"
    writes of a user's sheet whose first column is `log`, as the manifest's is — and a later run
    replaced it, unread: a column of notes added by hand, or a user's own file, gone. Now the
    campaign knows its files by the digests it recorded: an edited one is refused, untouched;
    its own, unedited, is replaced as before."""
    from app.sim.simulated_drive import write_drive
    from tests.simulated import cached_drive

    write_drive(cached_drive("constant_radius", 41, 15.1), tmp_path / "s 1.blf")
    path = _manifest(tmp_path, "log,tyre_set\ns 1.blf,A\n")
    out = tmp_path / "manifest-campaign"
    argv = ["campaign", str(path), "--workers", "1"]
    for _ in range(2):  # its own results, replaced
        code, _, err = run_cli(argv)
        assert code == 0, err
    results = out / "results.csv"
    edited = results.read_text(encoding="utf-8-sig").replace("\n", ",felt cold\n", 1)
    results.write_text(edited, encoding="utf-8-sig")
    code, _, err = run_cli(argv)
    assert code == 1 and "holds files c2n did not write (results.csv)" in err
    assert results.read_text(encoding="utf-8-sig") == edited
    theirs = tmp_path / "mine"
    theirs.mkdir()
    (theirs / "results.csv").write_bytes(b"\xef\xbb\xbflog,my own analysis\r\nweek 1,very important\r\n")
    code, _, err = run_cli([*argv, "--out", str(theirs)])
    assert code == 1 and "holds files c2n did not write (results.csv)" in err
    assert (theirs / "results.csv").read_bytes().endswith(b"very important\r\n")


def test_another_manifests_results_on_the_same_out_are_not_replaced(tmp_path: Path) -> None:
    """Two manifests run with one --out: the second replaced the first's results.csv, comparison
    and report, exit 0, no word. Now it is refused before any work, the first's results as they
    were; with them removed, the second runs and reuses the analyses in the cache."""
    from app.sim.simulated_drive import write_drive
    from tests.simulated import cached_drive

    write_drive(cached_drive("constant_radius", 41, 15.1), tmp_path / "s1.blf")
    first = _manifest(tmp_path, "log,tyre_set\ns1.blf,A\n", "first.csv")
    second = _manifest(tmp_path, "log,pressure_bar\ns1.blf,2.1\n", "second.csv")
    out = tmp_path / "shared"
    code, _, err = run_cli(["campaign", str(first), "--out", str(out), "--workers", "1"])
    assert code == 0, err
    code, _, err = run_cli(["campaign", str(first), "--out", str(out), "--workers", "1"])
    assert code == 0, err  # the same manifest again: its own results, replaced
    kept = {name: (out / name).read_bytes() for name in ("results.csv", "comparison.json", "report.html")}
    code, _, err = run_cli(["campaign", str(second), "--out", str(out), "--workers", "1"])
    assert code == 1 and f"holds the results of the campaign {first.resolve()}, not of {second}" in err
    assert "Traceback" not in err
    assert {name: (out / name).read_bytes() for name in kept} == kept
    assert b"tyre_set" in kept["results.csv"]
    for name in ("results.csv", "results.parquet", "comparison.json", "report.html"):
        (out / name).unlink()
    code, printed, err = run_cli(["campaign", str(second), "--out", str(out), "--workers", "1"])
    assert code == 0, err
    assert "1 known from an earlier run" in printed
    assert b"pressure_bar" in (out / "results.csv").read_bytes()


def test_a_link_to_a_manifest_or_an_older_c2n_s_results_are_not_replaced(tmp_path: Path) -> None:
    """A link to a manifest from another folder reads its logs beside the link: its run failed
    every session and replaced the manifest's results, as a link is the same file. An older c2n's
    results, without the record of their manifest, were replaced by any manifest's. Now a link
    is another manifest, and older results are known by the logs their results.csv lists."""
    from app.campaign.work import CACHE, WRITTEN
    from app.sim.simulated_drive import write_drive
    from tests.simulated import cached_drive

    (tmp_path / "camp").mkdir()
    write_drive(cached_drive("constant_radius", 41, 15.1), tmp_path / "camp" / "s1.blf")
    first = _manifest(tmp_path / "camp", "log,tyre_set\ns1.blf,A\n", "first.csv")
    out = tmp_path / "camp" / "out"
    code, _, err = run_cli(["campaign", str(first), "--out", str(out), "--workers", "1"])
    assert code == 0, err
    kept = (out / "results.csv").read_bytes()
    link = tmp_path / "link.csv"
    link.symlink_to(first)
    code, _, err = run_cli(["campaign", str(link), "--out", str(out), "--workers", "1"])
    assert code == 1 and f"holds the results of the campaign {first}, not of {link}" in err, err
    assert (out / "results.csv").read_bytes() == kept
    record = out / CACHE / WRITTEN  # as an older c2n kept it: no manifest named
    record.write_text(
        json.dumps({k: v for k, v in json.loads(record.read_text()).items() if k != "manifest"})
    )
    other = _manifest(tmp_path / "camp", "log,tyre_set\ns1.blf,A\ns2.blf,B\n", "other.csv")
    write_drive(cached_drive("constant_radius", 42, 15.1), tmp_path / "camp" / "s2.blf")
    code, _, err = run_cli(["campaign", str(other), "--out", str(out), "--workers", "1"])
    assert code == 1 and "holds the results of a campaign of other logs than" in err, err
    assert (out / "results.csv").read_bytes() == kept
    code, _, err = run_cli(["campaign", str(first), "--out", str(out), "--workers", "1"])
    assert code == 0, err  # its own logs: its own results, replaced


def test_a_drive_moved_since_its_analysis_is_named_where_it_is_now(tmp_path: Path) -> None:
    """A log renamed (or moved) and its manifest line with it: its row came from the cache (the
    same content), and results.csv's inputs named the old file, gone. Now the row names the log
    where it is."""
    import csv

    from app.sim.simulated_drive import write_drive
    from tests.simulated import cached_drive

    write_drive(cached_drive("constant_radius", 41, 15.1), tmp_path / "s1.blf")
    path = _manifest(tmp_path, "log,tyre_set\ns1.blf,A\n")
    argv = ["campaign", str(path), "--workers", "1"]
    assert run_cli(argv)[0] == 0
    (tmp_path / "s1.blf").rename(tmp_path / "day 2.blf")
    _manifest(tmp_path, "log,tyre_set\nday 2.blf,A\n")
    code, _, err = run_cli(argv)
    assert code == 0, err
    text = (tmp_path / "manifest-campaign" / "results.csv").read_text(encoding="utf-8-sig")
    (row,) = csv.DictReader(text.splitlines())
    assert row["cached"] == "True" and row["log"] == "day 2.blf"
    assert json.loads(row["inputs"]) == [str(tmp_path / "day 2.blf")], row["inputs"]
    assert "s1.blf" not in text


def test_numeric_tags_are_numbers_in_the_parquet(tmp_path: Path) -> None:
    """results.parquet held every tag as text: `pressure_kPa` came back as strings, a trend or a
    plot in pandas first had to convert them. A numeric tag is now a column of numbers (whole
    where every value is), an empty cell null; a text tag stays text."""
    import pyarrow.parquet as pq

    from app.campaign.tables import write_tables

    rows = [
        {"log": "a.blf", "pressure_kPa": "230", "load_kg": "80.5", "tyre_set": "A", "c2n": 15.0},
        {"log": "b.blf", "pressure_kPa": "", "load_kg": "1e2", "tyre_set": "7", "c2n": None},
    ]
    for row, big, lead in zip(rows, ("9007199254740993", "-5"), ("007", "12"), strict=True):
        row |= {"big": big, "lead": lead}  # 2⁵³ + 1 read through a float is 2⁵³; an id's zeros
    columns = ["log", "pressure_kPa", "load_kg", "tyre_set", "c2n", "big", "lead"]
    write_tables(tmp_path, columns, rows, numeric=["pressure_kPa", "load_kg", "big", "lead"])
    table = pq.read_table(tmp_path / "results.parquet")
    assert table.column("big").to_pylist() == [9007199254740993, -5]
    assert table.column("lead").to_pylist() == ["007", "12"]
    assert str(table.schema.field("pressure_kPa").type) == "int64"
    assert str(table.schema.field("load_kg").type) == "double"
    assert str(table.schema.field("tyre_set").type) == "string"
    assert table.column("pressure_kPa").to_pylist() == [230, None]
    assert table.column("load_kg").to_pylist() == [80.5, 100.0]
    text = (tmp_path / "results.csv").read_text(encoding="utf-8-sig")
    assert (
        "a.blf,230,80.5,A,15,9007199254740993,007" in text and "b.blf,,1e2,7,,-5,12" in text
    )  # the CSV as the manifest wrote them
