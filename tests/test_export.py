"""`c2n export`: channel files (CSV, Parquet, MF4) that agree with each other, the events table,
session folders, and the log formats c2n reads."""

import csv
import io
import json
import math
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import can
import numpy as np
import pyarrow.parquet as pq
import pytest
from asammdf import MDF

from app.cli import main
from app.config import load_config
from app.sim.simulated_drive import write_drive
from app.sinks.channels import csv_header
from app.sinks.trace import DECODED, TraceRecorder
from app.sources.logs import LogSource
from tests.simulated import cached_drive, run_pipeline

TRUE_C2N = 15.1


def drive():  # type: ignore[no-untyped-def]
    return cached_drive("constant_radius", 41, TRUE_C2N)


@pytest.fixture(scope="module")
def exported(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("export")
    log = folder / "drive.blf"
    write_drive(drive(), log)
    assert run_cli(["export", str(log), "--no-plots"]) == 0
    return folder / "drive-export"


DECIMALS = {c.name: c.decimals for c in TraceRecorder(DECODED).channels}


def run_cli(argv: list[str]) -> int:
    with redirect_stdout(io.StringIO()), redirect_stderr(io.StringIO()):
        return main(argv)


def read_csv(path: Path) -> tuple[list[str], np.ndarray]:
    with path.open(newline="", encoding="utf-8-sig") as file:
        rows = list(csv.reader(file))
    values = np.array([[float(v) if v else math.nan for v in row] for row in rows[1:]])
    return rows[0], values


def test_export_writes_every_file_into_the_default_folder(exported: Path) -> None:
    names = {p.name for p in exported.iterdir()}
    assert names == {"channels.csv", "channels.parquet", "channels.mf4", "events.csv", "summary.json"}


def test_mf4_has_the_channels_units_and_values_of_the_csv(exported: Path) -> None:
    header, values = read_csv(exported / "channels.csv")
    assert header[0] == "time [s]" and "sideslip [deg]" in header and "steady" in header
    with MDF(exported / "channels.mf4") as mdf:
        for column, name_unit in enumerate(header[1:], start=1):
            name = name_unit.split(" [")[0]
            signal = mdf.get(name, raw=True)  # the flags' values, not their words
            assert csv_header(name, str(signal.unit)) == name_unit
            # the CSV keeps 6 decimals of time and 4 of most values; the MF4 every bit (its time
            # base spreads frames of one microsecond by 1 ns)
            np.testing.assert_allclose(signal.timestamps, values[:, 0], rtol=0, atol=1e-6)
            atol = 0.5 * 10.0 ** -DECIMALS[name]
            np.testing.assert_allclose(signal.samples, values[:, column], rtol=0, atol=atol, equal_nan=True)
            assert signal.comment  # the description travels with the channel


def test_parquet_has_the_values_and_units_of_the_csv(exported: Path) -> None:
    header, values = read_csv(exported / "channels.csv")
    table = pq.read_table(exported / "channels.parquet")
    assert len(table.column_names) == len(header)
    for column, field in enumerate(table.schema):
        unit = field.metadata[b"unit"].decode()
        assert csv_header(field.name, unit) == header[column]
        got = table.column(field.name).to_numpy(zero_copy_only=False).astype(float)
        atol = 0.5 * 10.0 ** -DECIMALS[field.name]  # the CSV keeps each channel's decimals
        np.testing.assert_allclose(got, values[:, column], rtol=0, atol=atol, equal_nan=True)


def test_channels_hold_the_filtered_and_decoded_drive(exported: Path) -> None:
    header, values = read_csv(exported / "channels.csv")
    col = {name.split(" [")[0]: values[:, i] for i, name in enumerate(header)}
    assert np.all(np.diff(col["time"]) >= 0)
    truth = drive().trace
    steady = col["steady"] == 1
    assert steady.mean() > 0.5
    # the filtered speed follows the simulated one within a few cm/s
    true_u = np.interp(col["time"], truth.t, truth.u)
    assert np.nanmedian(np.abs(col["speed"][steady] - true_u[steady])) < 0.03
    # sideslip changes sign in left turns where the summary says it does
    summary = json.loads((exported / "summary.json").read_text())
    for crossing in summary["crossings"]:
        near = steady & (np.abs(col["time"] - crossing["t"]) < 3.0)
        assert np.nanmin(col["sideslip"][near]) < 0 < np.nanmax(col["sideslip"][near])
    # decoded values are the optical sensor's, in its units
    assert np.nanmax(np.abs(col["vx"] - col["speed"])[steady]) < 0.5


def test_events_table_matches_the_summary(exported: Path) -> None:
    summary = json.loads((exported / "summary.json").read_text())
    with (exported / "events.csv").open(newline="") as file:
        rows = list(csv.DictReader(file))
    crossings = [r for r in rows if r["event"] == "crossing"]
    assert len(crossings) == len(summary["crossings"]) == 4
    for row, crossing in zip(crossings, summary["crossings"], strict=True):
        assert row["direction"] == crossing["direction"] and row["sweep"] == crossing["sweep"]
        assert float(row["c2n"]) == pytest.approx(crossing["c2n"], abs=1e-4)
        assert float(row["t"]) == pytest.approx(crossing["t"], abs=1e-3)
    assert abs(summary["c2n"] / TRUE_C2N - 1) < 0.01


def test_export_of_a_live_session_uses_its_own_config_copy(tmp_path: Path) -> None:
    """A session folder carries the config and DBCs it was recorded with: export needs nothing else."""
    session = tmp_path / "session"
    (session / "config").mkdir(parents=True)
    config = load_config()
    for path in (config.path, *(dbc.path for dbc in config.dbcs)):
        (session / "config" / path.name).write_bytes(path.read_bytes())
    write_drive(drive(), session / "frames.log")
    assert run_cli(["export", str(session), "--format", "csv", "--no-plots"]) == 0
    summary = json.loads((session / "export" / "summary.json").read_text())
    expected = run_pipeline(load_config(), drive())
    assert summary["c2n"] == pytest.approx(expected.snapshot().headline.c2n, abs=1e-4)  # type: ignore[union-attr]
    assert {p.name for p in (session / "export").iterdir()} == {"channels.csv", "events.csv", "summary.json"}


def test_a_folder_that_is_not_a_session_is_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["export", str(tmp_path)]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith(f"c2n: error: {tmp_path}: not a c2n session folder") and "\n" not in err


def test_trace_rows_are_one_per_decoded_frame() -> None:
    from app.pipeline import Pipeline

    config = load_config()
    pipeline, recorder = Pipeline(config), TraceRecorder(config.roles)
    decoded = 0
    for message in drive().messages[:5000]:
        record = pipeline.process(message)
        if record is not None:
            recorder.on_record(record)
            decoded += bool(record.signals)
    trace = recorder.trace(pipeline.state.t_first or 0.0)
    assert len(trace) == decoded > 0
    assert all(len(trace[c.name]) == decoded for c in trace.channels)
    assert trace["time"][0] >= 0


# -- formats in ----------------------------------------------------------------------------------

WRITABLE = (".asc", ".blf", ".csv", ".log", ".mf4", ".trc")


@pytest.fixture(scope="module")
def reference(tmp_path_factory: pytest.TempPathFactory) -> dict[str, object]:
    log = tmp_path_factory.mktemp("ref") / "drive.blf"
    write_drive(drive(), log)
    out = log.with_suffix(".json")
    assert run_cli(["analyze", str(log), "--json", str(out)]) == 0
    return dict(json.loads(out.read_text()))


@pytest.mark.parametrize("suffix", WRITABLE)
def test_every_format_gives_the_same_result(
    suffix: str, tmp_path: Path, reference: dict[str, object]
) -> None:
    """The same frames written by python-can's writer for each format analyse alike."""
    log = tmp_path / f"drive{suffix}"
    with can.Logger(log) as writer:
        for message in drive().messages:
            writer.on_message_received(message)
    assert sum(1 for _ in can.LogReader(log)) == len(drive().messages)
    out = tmp_path / "summary.json"
    assert run_cli(["analyze", str(log), "--json", str(out)]) == 0
    summary = json.loads(out.read_text())
    assert summary["frames"] == reference["frames"]
    assert len(summary["crossings"]) == len(reference["crossings"])  # type: ignore[arg-type]
    assert summary["c2n"] == pytest.approx(reference["c2n"], rel=2e-4)


def test_progress_follows_the_file(tmp_path: Path) -> None:
    log = tmp_path / "drive.log"
    write_drive(drive(), log)
    source = LogSource([log])
    assert source.bytes_read() == 0
    positions = []
    for i, _ in enumerate(source):
        if i % 5000 == 0:
            positions.append(source.bytes_read())
    assert positions == sorted(positions) and 0 < positions[-1] < source.total_bytes  # type: ignore[operator]
    assert source.bytes_read() == source.total_bytes == log.stat().st_size


def test_files_open_in_their_tools_without_loss(exported: Path, tmp_path: Path) -> None:
    """The CSV: a byte-order mark (a spreadsheet then reads m/s² right), values rounded to their
    resolution; the semicolon dialect with decimal commas for a spreadsheet set so. The MF4: the
    flags with their words, and a time base asammdf turns into a table without losing a row."""
    raw = (exported / "channels.csv").read_bytes()
    assert raw.startswith("\ufeff".encode()) and "m/s²".encode() in raw
    header, values = read_csv(exported / "channels.csv")
    text = raw.decode("utf-8-sig")
    assert "0000000" not in text and "9999999" not in text  # no 28.40000000000009
    with MDF(exported / "channels.mf4") as mdf:
        frame = mdf.to_dataframe(raw=True)
        assert len(frame) == len(values)  # every row, though frames share microseconds
        words = set(mdf.get("steady").samples.tolist()) | set(mdf.get("direction").samples.tolist())
        known = {b"steady", b"not steady", b"left", b"right", b"straight", b"no estimate"}
        assert words <= known and {b"steady", b"left", b"right"} <= words
    out = tmp_path / "semicolon"
    assert (
        run_cli(
            [
                "export",
                str(exported.parent / "drive.blf"),
                "--format",
                "csv",
                "--no-plots",
                "--csv-dialect",
                "excel-semicolon",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    with (out / "channels.csv").open(newline="", encoding="utf-8-sig") as file:
        rows = list(csv.reader(file, delimiter=";"))
    assert rows[0] == header
    again = np.array([[float(v.replace(",", ".")) if v else math.nan for v in row] for row in rows[1:]])
    np.testing.assert_array_equal(again, values)


def test_a_csv_longer_than_a_spreadsheet_s_sheet_says_so(
    exported: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A long session's channels.csv opened in Excel or LibreOffice shows its first 1,048,575
    rows: the export says so, where it is longer (the sheet's size lowered to this drive's)."""
    import app.cli.export

    assert app.cli.export.SPREADSHEET_ROWS == 1_048_575  # a 1,048,576-row sheet, its header one
    rows = len((exported / "channels.csv").read_bytes().splitlines()) - 1
    log = exported.parent / "drive.blf"

    def warned(sheet: int, fmt: str) -> str:
        monkeypatch.setattr(app.cli.export, "SPREADSHEET_ROWS", sheet)
        err = io.StringIO()
        out = tmp_path / f"{sheet}-{fmt}"
        with redirect_stdout(io.StringIO()), redirect_stderr(err):
            assert main(["export", str(log), "--out", str(out), "--no-plots", "--format", fmt]) == 0
        return err.getvalue()

    said = warned(rows - 1, "csv")
    assert f"channels.csv holds {rows:,} rows: a spreadsheet opens the first {rows - 1:,}" in said
    assert "use channels.parquet or channels.mf4" in said
    assert "spreadsheet" not in warned(rows, "csv")
    assert "spreadsheet" not in warned(rows - 1, "parquet")
