"""Every command driven with random options, numbers and config files (hypothesis, seeded): the
exit code is 0, 1 or 2, there is never a traceback, and nothing half-written is left looking
complete (every output is written aside and renamed into place)."""

import io
import json
import uuid
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import can
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rich.console import Console

from app.campaign.meta_analysis import Z95, Estimate
from app.campaign.row import SessionResult, SessionRow
from app.cli import main
from tests.simulated import REPO, cached_drive

NUMBERS = ["0", "-1", "-5", "nan", "inf", "-inf", "1e308", "abc", "", "0.5", "3", "20000"]
TOML_VALUES = ["nan", "inf", "-inf", "0", "-5", "1e9", '"x"', "true", "[]", "{}", "3"]
MONDEO = (REPO / "config" / "mondeo.toml").read_text().replace('"../dbc/', f'"{REPO}/dbc/')
KEYS = {
    "vehicle": ["sensor_ahead_of_rear_axle_m", "gravity_mps2", "wheelbase_m", "steering_ratio", "track_m"],
    "tyres": ["c1n_per_rad", "c2n_per_rad"],
    "detector": ["ay_max_mps2", "settle_s", "speed_min_mps", "min_fit_samples", "radius_max_m"],
    "filter": ["sigma_velocity_mps", "q_r", "gap_reset_s", "innovation_gate", "sideslip_source"],
}


@pytest.fixture(scope="module")
def files(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("property")
    log = root / "tiny.log"
    with can.Logger(log) as writer:
        for m in cached_drive("constant_radius", 41, 15.1).messages[:3000]:
            writer.on_message_received(m)
    garbage = root / "garbage.blf"
    garbage.write_bytes(b"LOGG" + bytes(range(256)) * 8)
    (root / "empty_pack").mkdir()
    return {"log": log, "garbage": garbage, "pack": root / "empty_pack", "root": root}


@st.composite
def a_config(draw: st.DrawFn, root: Path) -> Path:
    text = MONDEO
    for _ in range(draw(st.integers(0, 3))):
        section = draw(st.sampled_from(sorted(KEYS)))
        key, value = draw(st.sampled_from(KEYS[section])), draw(st.sampled_from(TOML_VALUES))
        text = text.replace(f"[{section}]\n", f"[{section}]\n{key} = {value}\n", 1)
        if f"[{section}]\n" not in MONDEO:
            text += f"\n[{section}]\n{key} = {value}\n"
    if draw(st.booleans()):
        text = text.encode("utf-8")[: draw(st.integers(0, len(text)))].decode("utf-8", "ignore")
    path = root / f"{uuid.uuid4().hex}.toml"
    path.write_text(text)
    return path


@st.composite
def a_command(draw: st.DrawFn, files: dict[str, Path]) -> list[str]:
    root = files["root"]
    out = root / uuid.uuid4().hex
    log = str(draw(st.sampled_from([files["log"], files["garbage"], root / "missing.blf"])))
    number = st.sampled_from(NUMBERS)
    config = ["--config", str(draw(a_config(root)))] if draw(st.booleans()) else []
    command = draw(
        st.sampled_from(["analyze", "export", "simulate", "gap", "gap-check", "replay", "live", "demo"])
    )
    if command == "analyze":
        return ["analyze", log, "--json", str(out / "s.json"), *config]
    if command == "export":
        fmt = draw(st.sampled_from(["csv", "parquet", "mf4", "xlsx"]))
        return ["export", log, "--out", str(out), "--format", fmt, "--no-plots", *config]
    if command == "simulate":
        option = draw(
            st.sampled_from(["--c2n", "--noise", "--sweep-rate", "--optical-hz", "--mu", "--ay-max"])
        )
        return ["simulate", "--out", str(out / "sim.blf"), option, draw(number), *config]
    if command == "gap":
        return ["gap", log, "--json", str(out / "g.json"), *config]
    if command == "gap-check":
        return [
            "gap-check",
            str(draw(st.sampled_from([files["pack"], files["log"]]))),
            "--workers",
            draw(number),
        ]
    if command == "replay":
        rate = draw(st.sampled_from([*NUMBERS[:9], "1e5"]))
        return ["replay", log, "-i", "virtual", "-c", uuid.uuid4().hex, "--rate", rate]
    if command == "live":
        duration = draw(st.sampled_from([*NUMBERS[:9], "0.2"]))
        return [
            "live",
            "-i",
            "virtual",
            "-c",
            uuid.uuid4().hex,
            "--no-record",
            "--duration",
            duration,
            *config,
        ]
    return ["demo", "--speedup", draw(st.sampled_from(NUMBERS[:9]))]


@settings(
    max_examples=60,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(data=st.data())
def test_every_command_with_random_options_and_configs_ends_cleanly(
    files: dict[str, Path], data: st.DataObject
) -> None:
    argv = data.draw(a_command(files))
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main(argv, Console(file=out, width=100))
    assert code in (0, 1, 2), (argv, code, err.getvalue())
    assert "Traceback" not in err.getvalue() + out.getvalue(), (argv, err.getvalue())
    leftovers = [p for p in files["root"].rglob("*") if ".partial" in p.name]
    assert not leftovers, (argv, leftovers)


# -- where the commands write (issue 39) --------------------------------------------------------


@pytest.fixture(scope="module")
def desk(files: dict[str, Path]) -> dict[str, Path]:
    """A user's folder: a drive, a config with its DBC, a manifest, and files of their own — a
    JSON, a page, a log, a folder holding a results.csv, a name with [brackets]."""
    import shutil

    root = files["root"] / "desk"
    root.mkdir()
    shutil.copy(files["log"], root / "drive.log")
    shutil.copy(REPO / "dbc" / "kistler_smotion.dbc", root / "kistler.dbc")
    (root / "car.toml").write_text(
        MONDEO.replace(f"{REPO}/dbc/kistler_smotion.dbc", str(root / "kistler.dbc"))
    )
    (root / "manifest.csv").write_text("log,tyre_set\ndrive.log,A\n")
    (root / "notes.json").write_text('{"mine": true}\n')
    (root / "page.html").write_text("<html>mine</html>\n")
    (root / "old.log").write_text("(0.000000) can0 123#0102\n")
    (root / "[mine].json").write_text("[1, 2]\n")
    (root / "folder").mkdir()
    (root / "folder" / "results.csv").write_text("precious\n")
    return {name: root / name for name in ("drive.log", "car.toml", "kistler.dbc", "manifest.csv")} | {
        "root": root
    }


def _user_files(root: Path) -> dict[Path, bytes]:
    return {p: p.read_bytes() for p in root.rglob("*") if p.is_file()}


@st.composite
def an_output_command(draw: st.DrawFn, desk: dict[str, Path]) -> tuple[list[str], bool]:
    """A command whose output path is drawn: an input (the log, config, DBC, manifest, each
    also through a symlink or as ./x), the folder holding them, a user's file or folder, '-',
    a name with brackets, or a new path."""
    root = desk["root"]
    fresh = root / "new" / uuid.uuid4().hex
    spelt = st.sampled_from(["as is", "dotted", "symlink"])

    def spell(path: Path) -> Path:
        how = draw(spelt)
        if how == "dotted":
            return path.parent / "." / path.name
        if how == "symlink":
            link = root / "new" / f"link-{uuid.uuid4().hex}{path.suffix}"
            link.parent.mkdir(exist_ok=True)
            link.symlink_to(path)
            return link
        return path

    inputs = [desk["drive.log"], desk["car.toml"], desk["kistler.dbc"], desk["manifest.csv"]]
    mine = [root / "notes.json", root / "page.html", root / "old.log", root / "[mine].json"]
    target = draw(
        st.sampled_from(
            ["input", "input", "folder", "mine", "mine", "dash", "brackets", "fresh", "mine_folder"]
        )
    )
    path = {
        "input": lambda: spell(draw(st.sampled_from(inputs))),
        "folder": lambda: root,
        "mine": lambda: draw(st.sampled_from(mine)),
        "dash": lambda: Path("-"),
        "brackets": lambda: fresh.with_name(f"[{fresh.name}]"),
        "fresh": lambda: fresh,
        "mine_folder": lambda: root / "folder",
    }[target]()
    force = draw(st.booleans())
    config = ["--config", str(desk["car.toml"])]
    log = str(desk["drive.log"])
    command = draw(st.sampled_from(["analyze", "gap-json", "gap-report", "export", "simulate", "campaign"]))
    if command == "analyze":
        argv = ["analyze", log, *config, "--json", str(path)]
    elif command == "gap-json":
        argv = ["gap", log, *config, "--json", str(path), "--report", str(fresh) + ".html"]
    elif command == "gap-report":
        argv = ["gap", log, *config, "--report", str(path)]
    elif command == "export":
        argv = ["export", log, *config, "--out", str(path), "--no-plots", "--format", "csv"]
        force = False
    elif command == "simulate":
        suffix = "" if path.suffix in (".log", ".blf") else ".log"
        argv = ["simulate", *config, "--out", str(path) + (suffix if target in ("fresh", "brackets") else "")]
    else:
        argv = ["campaign", str(desk["manifest.csv"]), "--workers", "1", "--out", str(path)]
        force = False
    return argv + (["--force"] if force else []), force


@settings(
    max_examples=30,
    derandomize=True,
    deadline=None,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
@given(data=st.data())
def test_no_output_path_changes_a_file_c2n_did_not_write(desk: dict[str, Path], data: st.DataObject) -> None:
    """Whatever the output path, an input never changes, and a user's file changes only with
    --force; the run ends with 0, 1 or 2 and no traceback."""
    root = desk["root"]
    before = {p: b for p, b in _user_files(root).items() if "new" not in p.relative_to(root).parts}
    argv, force = data.draw(an_output_command(desk))
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main(argv, Console(file=out, width=100))
    assert code in (0, 1, 2), (argv, code, err.getvalue())
    assert "Traceback" not in err.getvalue() + out.getvalue(), (argv, err.getvalue())
    kept = {p for p in before if not force or p in desk.values()}  # --force: inputs still never
    after = _user_files(root)
    changed = [p.name for p in kept if after.get(p) != before[p]]
    assert not changed, (argv, changed, err.getvalue())
    assert not Path("-").exists(), argv


# -- tags and manifests: what a user types into a spreadsheet ---------------------------------------

TAGS = st.one_of(
    st.sampled_from(["Pirelli [old]", "Pirelli [new]", "[/]", "[bold]", "\x1b[2J", "", "a\\", "1e308", "-0"]),
    st.sampled_from(["20261124", "20261125", "1e200", "2e200", "nan", "inf", "220", "240"]),
    st.text(st.characters(blacklist_categories=["Cs"], blacklist_characters='\r\n\x00,;\t"'), max_size=8),
)


def _row(log: str, c2n: float) -> SessionRow:
    own = Estimate(c2n, (c2n - 0.2, c2n + 0.2), 0.2 / Z95)
    return SessionRow(summary={"c2n": c2n}, result=SessionResult(own, 0.0, None, None))


@st.composite
def a_manifest(draw: st.DrawFn, root: Path) -> tuple[Path, list[SessionRow], str]:
    """A manifest of 1–6 drives (some listed twice under other names), two tag columns, written
    with ',' or ';', and the rows the workers would return."""
    n = draw(st.integers(1, 6))
    delimiter = draw(st.sampled_from([",", ";"]))
    folder = root / uuid.uuid4().hex
    folder.mkdir()
    lines = [delimiter.join(["log", "tyre_set", "pressure"])]
    rows = []
    for k in range(n):
        name = f"d{k}.log"
        (folder / name).write_text("")
        tags = [draw(TAGS), draw(TAGS)]
        lines.append(delimiter.join([name, *(f'"{t}"' for t in tags)]))
        rows.append(_row(name, draw(st.floats(5.0, 40.0))))
    path = folder / "manifest.csv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path, rows, draw(st.sampled_from(["tyre_set", "pressure"]))


@settings(max_examples=60, derandomize=True, deadline=None, database=None)
@given(data=st.data())
def test_any_tags_in_a_manifest_are_compared_printed_literally_and_written_as_valid_json(
    tmp_path_factory: pytest.TempPathFactory, data: st.DataObject
) -> None:
    from app.campaign.comparison import compare
    from app.campaign.manifest import read_manifest
    from app.cli.campaign import print_comparison
    from app.errors import printable

    path, rows, by = data.draw(a_manifest(tmp_path_factory.getbasetemp()))
    manifest = read_manifest(path)
    assert manifest.tag_names == ("tyre_set", "pressure")
    comparison = compare(manifest, rows, by)
    console = Console(record=True, width=300)
    print_comparison(console, comparison, by)  # no MarkupError
    printed = console.export_text()
    assert "\x1b" not in printed
    for name in comparison.groups:  # every group under its own name, brackets and all
        shown = {"": "(empty)", "(empty)": "'(empty)'"}.get(printable(name), printable(name))
        assert f"{by} {shown}: C2n" in printed
    text = json.dumps(comparison.to_json(), allow_nan=False)  # raises on NaN or Infinity
    assert json.loads(text)["sessions"] == len(rows)
