"""Real third-party logs through ``c2n analyze`` (data/real/, see each folder's README.md).

None of these cars carries an optical sensor, so every run ends with exit code 1 and one error
line naming role 'vx'; what these tests protect is that real files in every log format open,
that every frame is counted by what it was, and that the summary is still written. Expected
counts come from the READMEs or are counted here from the files themselves.
"""

import io
import json
import re
import string
from collections import Counter
from collections.abc import Iterable
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import can
import cantools
import pytest

from app.cli import main
from tests.real_data import REPO_ROOT, needs_real_data, real_path

pytestmark = needs_real_data

TEMPLATES = Path(__file__).resolve().parent / "data" / "real_configs"
OUR_KISTLER = REPO_ROOT / "dbc" / "kistler_smotion.dbc"

RAV4_LOG = ("comma2k19-rav4-segment", "raw_can_bus0.candump.log")
TOYOTA_DBC = ("opendbc-dbc", "_toyota_2017.dbc")
CAR_MF4 = ("css-electronics-mf4", "3BA199E2_00000165_00000002-60FEB8E3.MF4")
CAR_MF4_DBC = ("css-electronics-mf4", "canmod-gps.dbc")
J1939_MF4 = ("css-electronics-mf4", "asammdf-basics_00000001_J1939.MF4")
J1939_DBC = ("css-electronics-mf4", "CSS-Electronics-SAE-J1939-DEMO.dbc")
LOGAN_LOG = ("nemodrive-logan-candump", "commands_1544451790.73.can")
LOGAN_DBC = ("nemodrive-logan-candump", "logan.dbc")

# Facts from the READMEs.
CAR_MF4_FRAMES = 73_812
J1939_FRAMES = 150_411
LOGAN_FRAMES = 8_988
OBD_RESPONSE_ID = 0x7E8  # also the id of Kistler 'Coordinates'
J1939_LOG_IDS = (0x0CF00400, 0x18FEF100)  # EEC1 and CCVS1 from source address 0x00

# The vehicle roles each config maps: role -> message name in the third-party DBC.
RAV4_ROLES = {
    "speed": "SPEED",
    "yaw_rate": "KINEMATICS",
    "ay": "KINEMATICS",
    "steer": "STEER_ANGLE_SENSOR",
}
CAR_MF4_ROLES = {"speed": "gnss_speed", "yaw_rate": "gnss_imu", "ay": "gnss_imu"}
LOGAN_ROLES = {"speed": "SPEED_SENSOR", "steer": "STEERING_SENSORS"}

_CANDUMP_LINE = re.compile(r"^\(\d+(?:\.\d+)?\)\s+\S+\s+([0-9A-Fa-f]+)#")


@dataclass(frozen=True)
class Analysis:
    """What one ``c2n analyze`` run showed: exit code, stderr lines and the JSON summary."""

    code: int
    stderr: str
    summary: dict[str, Any] | None

    @property
    def lines(self) -> list[str]:
        return [line for line in self.stderr.splitlines() if line.strip()]

    @property
    def errors(self) -> list[str]:
        return [line for line in self.lines if line.startswith("c2n: error:")]

    @property
    def frames(self) -> dict[str, int]:
        assert self.summary is not None
        return dict(self.summary["frames"])

    @property
    def warnings(self) -> list[str]:
        assert self.summary is not None
        return list(self.summary["warnings"])

    def frames_per_id(self) -> Counter[int]:
        """Frames per CAN id over all channels (channel names differ between log formats)."""
        assert self.summary is not None
        counts: Counter[int] = Counter()
        for row in self.summary["frames_by_id"]:
            counts[int(row["id"], 16)] += row["frames"]
        return counts


def analyze(log: Path, config: Path, out: Path) -> Analysis:
    """Run ``c2n analyze LOG --config F --json OUT`` in-process, capturing its output."""
    stdout, stderr = io.StringIO(), io.StringIO()
    with redirect_stdout(stdout), redirect_stderr(stderr):
        code = main(["analyze", str(log), "--config", str(config), "--json", str(out)])
    summary = json.loads(out.read_text()) if out.exists() else None
    return Analysis(code, stderr.getvalue(), summary)


def _toml_path(path: Path) -> str:
    return path.resolve().as_posix().replace("\\", "\\\\").replace('"', '\\"')


def config_from_template(template: str, folder: Path, **paths: Path) -> Path:
    """The template from tests/data/real_configs with its paths filled in, written to ``folder``."""
    text = string.Template((TEMPLATES / template).read_text())
    values = {"C2N_DBC": OUR_KISTLER.parent, **paths}
    if "${REAL_DATA}" in text.template:
        values["REAL_DATA"] = real_path()
    config = folder / template
    config.write_text(text.substitute({key: _toml_path(value) for key, value in values.items()}))
    return config


def candump_ids(path: Path) -> Counter[int]:
    """Frames per id in a candump -l file, counted from its text."""
    counts: Counter[int] = Counter()
    with path.open() as file:
        for line in file:
            if line.strip():
                match = _CANDUMP_LINE.match(line)
                assert match, f"{path}: not a candump line: {line!r}"
                counts[int(match.group(1), 16)] += 1
    return counts


def role_ids(dbc: Path, roles: dict[str, str], strict: bool = True) -> dict[str, int]:
    """role -> frame id of the message the config maps it to, read from the DBC with cantools."""
    database = cantools.database.load_file(dbc, strict=strict)
    return {role: database.get_message_by_name(name).frame_id for role, name in roles.items()}


def dbc_ids(*dbcs: tuple[Path, bool]) -> set[int]:
    ids: set[int] = set()
    for path, strict in dbcs:
        ids |= {m.frame_id for m in cantools.database.load_file(path, strict=strict).messages}
    return ids


def assert_no_optical_sensor(run: Analysis, because: tuple[str, ...] = ("no frames for role 'vx'",)) -> None:
    """Exit 1, one error line saying role 'vx' had no frames (or ``because``), and a summary."""
    assert run.code == 1, run.stderr
    assert "Traceback" not in run.stderr
    assert len(run.errors) == 1, run.stderr
    assert all(words in run.errors[0] for words in because), run.errors[0]
    assert run.summary is not None, "the JSON summary is written even when there is no result"
    assert run.summary["c2n"] is None
    frames = run.frames
    assert frames["total"] == sum(n for kind, n in frames.items() if kind != "total")
    assert sum(run.frames_per_id().values()) == frames["total"]


def assert_roles_had_frames(run: Analysis, roles: Iterable[str]) -> None:
    silent = [
        role for role in roles if any(w.startswith(f"no frames for role '{role}'") for w in run.warnings)
    ]
    assert not silent, f"roles reported without frames: {silent}"
    assert any(w.startswith("no frames for role 'vx'") for w in run.warnings)


def split(counts: Counter[int], role_ids: Iterable[int], known_ids: set[int]) -> dict[str, int]:
    """Expected used / unused / unknown_id counts when every frame of a known id decodes."""
    used_ids = set(role_ids)
    return {
        "used": sum(n for i, n in counts.items() if i in used_ids),
        "unused": sum(n for i, n in counts.items() if i in known_ids and i not in used_ids),
        "unknown_id": sum(n for i, n in counts.items() if i not in known_ids),
    }


# -- comma2k19 RAV4: candump, and the same frames as ASC and BLF ---------------------------------


@pytest.fixture(scope="module")
def rav4(tmp_path_factory: pytest.TempPathFactory) -> Analysis:
    folder = tmp_path_factory.mktemp("rav4")
    return analyze(
        real_path(*RAV4_LOG),
        config_from_template("comma2k19_rav4.toml", folder),
        folder / "out.json",
    )


def test_rav4_candump(rav4: Analysis) -> None:
    """A real Toyota candump, relaxed opendbc DBC: every frame counted, vehicle roles found."""
    assert_no_optical_sensor(rav4)
    counts = candump_ids(real_path(*RAV4_LOG))
    assert rav4.frames["total"] == counts.total()
    assert rav4.frames_per_id() == counts
    toyota = real_path(*TOYOTA_DBC)
    ids = role_ids(toyota, RAV4_ROLES, strict=False)
    assert all(counts[i] > 0 for i in ids.values()), ids
    assert_roles_had_frames(rav4, RAV4_ROLES)
    known = dbc_ids((OUR_KISTLER, True), (toyota, False))
    assert {k: rav4.frames[k] for k in ("used", "unused", "unknown_id")} == split(counts, ids.values(), known)
    # The README: frames of DBC ids were zero-padded to the DBC length.
    assert rav4.frames["bad_length"] == 0
    relaxed = [line for line in rav4.lines if line.startswith("c2n: warning:") and "strict=False" in line]
    assert relaxed and "_toyota_2017.dbc" in relaxed[0], rav4.stderr
    assert any("_toyota_2017.dbc" in w and "strict=False" in w for w in rav4.warnings)


def test_rav4_real_values_not_dropped_by_placeholder_range(rav4: Analysis) -> None:
    """Values a signal can carry are not dropped because a DBC's [min|max] is a placeholder."""
    dropped = [w for w in rav4.warnings if "out of range" in w]
    assert not dropped, dropped


def test_rav4_roles_turn_together(tmp_path: Path) -> None:
    """The signs the config gives the RAV4's roles, checked on the drive itself (highway bends,
    |u·r| to 0.8 m/s²): YAW_RATE turns with the GNSS heading (global_pose) and with STEER_ANGLE;
    KINEMATICS.ACCEL_Y turned against both until the config said `scale = -1` — what
    app/detect/signs.py reports where a drive corners harder."""
    import numpy as np

    from app.config import load_config
    from app.decode.decoder import Decoder

    decoder = Decoder(load_config(config_from_template("comma2k19_rav4.toml", tmp_path)))
    latest: dict[str, float] = {}
    rows = []
    with can.LogReader(real_path(*RAV4_LOG)) as reader:
        for message in reader:
            record = decoder.decode(message)
            if record is None:
                continue
            latest.update(record.signals)
            if "yaw_rate" in record.signals and {"speed", "ay", "steer"} <= latest.keys():
                rows.append((record.t, latest["speed"], latest["yaw_rate"], latest["ay"], latest["steer"]))
    t, u, r, ay, steer = np.array(rows).T
    turning = np.abs(u * r) >= 0.5
    assert turning.sum() >= 20
    assert np.mean(np.sign(ay[turning]) == np.sign(r[turning])) >= 0.8
    assert np.mean(np.sign(steer[turning]) == np.sign(r[turning])) >= 0.8
    pose = real_path("comma2k19-rav4-segment", "global_pose")
    times, velocity = np.load(pose / "frame_times"), np.load(pose / "frame_velocities")
    x, y, z = np.load(pose / "frame_positions").mean(axis=0)
    lon, lat = np.arctan2(y, x), np.arctan2(z, np.hypot(x, y))
    east = velocity @ np.array([-np.sin(lon), np.cos(lon), 0.0])
    north = velocity @ np.array([-np.sin(lat) * np.cos(lon), -np.sin(lat) * np.sin(lon), np.cos(lat)])
    heading_rate = np.interp(t, times, np.gradient(np.unwrap(np.arctan2(north, east)), times))  # + left
    assert np.corrcoef(heading_rate, r)[0, 1] > 0.3 and np.corrcoef(heading_rate, ay)[0, 1] > 0.3


@pytest.mark.parametrize("suffix", [".asc", ".blf"])
def test_rav4_converted_log_counts_like_candump(rav4: Analysis, tmp_path: Path, suffix: str) -> None:
    """The candump rewritten by python-can as ASC / BLF gives the same frame counts per id."""
    log = tmp_path / f"rav4{suffix}"
    with can.LogReader(real_path(*RAV4_LOG)) as reader, can.Logger(log) as writer:
        for message in reader:
            writer.on_message_received(message)
    run = analyze(log, config_from_template("comma2k19_rav4.toml", tmp_path), tmp_path / "out.json")
    assert_no_optical_sensor(run)
    assert run.frames == rav4.frames
    assert run.frames_per_id() == rav4.frames_per_id()


# -- CSS Electronics CANedge MF4s -----------------------------------------------------------------


def test_car_mf4_with_obd_on_a_kistler_id(tmp_path: Path) -> None:
    """A real MF4 opens; OBD responses on 0x7E8 (Kistler 'Coordinates', no role) count as unused."""
    log = real_path(*CAR_MF4)
    run = analyze(log, config_from_template("canedge_car_gps.toml", tmp_path), tmp_path / "out.json")
    assert_no_optical_sensor(run)
    assert run.frames["total"] == CAR_MF4_FRAMES
    with can.LogReader(log) as reader:
        counts = Counter(m.arbitration_id for m in reader)
    assert run.frames_per_id() == counts
    assert counts[OBD_RESPONSE_ID] > 0
    gps = real_path(*CAR_MF4_DBC)
    ids = role_ids(gps, CAR_MF4_ROLES)
    assert_roles_had_frames(run, CAR_MF4_ROLES)
    known = dbc_ids((OUR_KISTLER, True), (gps, True))
    assert OBD_RESPONSE_ID in known and OBD_RESPONSE_ID not in ids.values()
    assert {k: run.frames[k] for k in ("used", "unused", "unknown_id")} == split(counts, ids.values(), known)
    assert run.frames["bad_length"] == run.frames["undecodable"] == 0


NOTHING_DECODED = (
    "no frames for any role of",
    "wrong DBC or config for this log? give the car's with --config",
)


def test_j1939_mf4_ids_with_another_source_address_are_unknown(tmp_path: Path) -> None:
    """J1939 ids that differ from the DBC's only in the source address: all unknown, no crash;
    not one frame of a role, which the error says."""
    config = config_from_template("canedge_j1939.toml", tmp_path)
    run = analyze(real_path(*J1939_MF4), config, tmp_path / "out.json")
    assert_no_optical_sensor(run, because=(f"no frames for any role of {config}", NOTHING_DECODED[1]))
    assert run.frames["total"] == J1939_FRAMES
    assert run.frames["unknown_id"] == J1939_FRAMES
    per_id = run.frames_per_id()
    assert all(per_id[i] > 0 for i in J1939_LOG_IDS)
    dbc_frame_ids = {m.frame_id for m in cantools.database.load_file(real_path(*J1939_DBC)).messages}
    assert not dbc_frame_ids & set(per_id)
    assert any(w.startswith("no frames for role 'speed'") for w in run.warnings)


def test_a_real_log_of_another_vehicle_is_refused_for_its_ids_not_its_cornering(tmp_path: Path) -> None:
    """CSS's J1939 truck log with the default (Mondeo) config: no frame of any role. The refusal
    says so, and no result line comes before it (was: `C2n: no result (no cornering in the
    drive: drive steady circles …)` on stdout first, the real reason only in the last line)."""
    stdout, stderr = io.StringIO(), io.StringIO()
    with redirect_stdout(stdout), redirect_stderr(stderr):
        code = main(["analyze", str(real_path(*J1939_MF4))])
    run = Analysis(code, stderr.getvalue(), None)
    assert code == 1 and "Traceback" not in run.stderr
    assert stdout.getvalue() == "" and "cornering" not in run.stderr, stdout.getvalue() + run.stderr
    assert [
        line for line in run.lines if not line.startswith("c2n: warning: no frames for role ")
    ] == run.errors
    assert len(run.errors) == 1 and all(words in run.errors[0] for words in NOTHING_DECODED), run.stderr


# -- nemodrive Dacia Logan: a candump named .can and a DBC cantools refuses -----------------------


@pytest.fixture
def logan_log(tmp_path: Path) -> Path:
    """The Logan candump under a .log name (python-can picks the reader by suffix), as a symlink."""
    link = tmp_path / "logs" / "commands_1544451790.73.log"
    link.parent.mkdir()
    link.symlink_to(real_path(*LOGAN_LOG))
    return link


@pytest.fixture
def fixed_logan_dbc(tmp_path: Path) -> Path:
    """logan.dbc without its stray 'VAL_ 500 ...' line (a value table for a message it lacks)."""
    original = real_path(*LOGAN_DBC).read_text(encoding="latin-1")
    kept = [line for line in original.splitlines(keepends=True) if not line.startswith("VAL_ 500 ")]
    assert len(kept) == len(original.splitlines()) - 1
    fixed = tmp_path / "logan.dbc"
    fixed.write_text("".join(kept), encoding="latin-1")
    return fixed


def test_logan_refused_dbc_is_one_error_line(tmp_path: Path, logan_log: Path) -> None:
    """A DBC cantools cannot read gives exit 1 and one stderr line naming it, no traceback."""
    config = config_from_template("nemodrive_logan.toml", tmp_path, LOGAN_DBC=real_path(*LOGAN_DBC))
    run = analyze(logan_log, config, tmp_path / "out.json")
    assert run.code == 1
    assert len(run.lines) == 1, run.stderr
    assert run.lines[0].startswith("c2n: error:") and "logan.dbc" in run.lines[0]
    assert "Traceback" not in run.stderr
    assert run.summary is None


def test_logan_with_repaired_dbc(tmp_path: Path, logan_log: Path, fixed_logan_dbc: Path) -> None:
    """With the stray VAL_ line removed the log analyzes: all frames, speed and steer found."""
    config = config_from_template("nemodrive_logan.toml", tmp_path, LOGAN_DBC=fixed_logan_dbc)
    run = analyze(logan_log, config, tmp_path / "out.json")
    assert_no_optical_sensor(run)
    counts = candump_ids(logan_log)
    assert counts.total() == LOGAN_FRAMES
    assert run.frames["total"] == LOGAN_FRAMES
    assert run.frames_per_id() == counts
    ids = role_ids(fixed_logan_dbc, LOGAN_ROLES)
    assert all(counts[i] > 0 for i in ids.values())
    assert_roles_had_frames(run, LOGAN_ROLES)
    known = dbc_ids((OUR_KISTLER, True), (fixed_logan_dbc, True))
    assert {k: run.frames[k] for k in ("used", "unused", "unknown_id")} == split(counts, ids.values(), known)


def test_logan_can_suffix_is_one_error_line(tmp_path: Path, fixed_logan_dbc: Path) -> None:
    """The log under its own '.can' name: exit 1, one error line naming the file, no traceback."""
    log = real_path(*LOGAN_LOG)
    config = config_from_template("nemodrive_logan.toml", tmp_path, LOGAN_DBC=fixed_logan_dbc)
    run = analyze(log, config, tmp_path / "out.json")
    assert run.code == 1
    assert "Traceback" not in run.stderr
    assert len(run.errors) == 1 and log.name in run.errors[0], run.stderr


def test_each_warning_is_one_stderr_line(
    tmp_path: Path, logan_log: Path, fixed_logan_dbc: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every warning of the summary appears on stderr as one whole line, whatever its length."""
    monkeypatch.setenv("COLUMNS", "80")
    config = config_from_template("nemodrive_logan.toml", tmp_path, LOGAN_DBC=fixed_logan_dbc)
    run = analyze(logan_log, config, tmp_path / "out.json")
    assert any(len(f"c2n: warning: {w}") > 80 for w in run.warnings), "needs a long warning to test"
    missing = [w for w in run.warnings if f"c2n: warning: {w}" not in run.lines]
    assert not missing, run.stderr


# -- export ---------------------------------------------------------------------------------------

EXPORTED = {"channels.csv", "channels.parquet", "channels.mf4", "events.csv", "summary.json", "report.html"}


def export(log: Path, config: Path, out: Path) -> tuple[int, str]:
    stdout, stderr = io.StringIO(), io.StringIO()
    with redirect_stdout(stdout), redirect_stderr(stderr):
        code = main(["export", str(log), "--config", str(config), "--out", str(out)])
    return code, stderr.getvalue()


def assert_exported(out: Path, code: int, stderr: str, channel: str) -> None:
    """Exit 0 (export converts what there is), every file written, the vehicle channel filled."""
    assert code == 0, stderr
    assert "Traceback" not in stderr and "no frames for role 'vx'" in stderr
    assert {p.name for p in out.iterdir()} >= EXPORTED
    assert len(list(out.glob("*.png"))) == 4
    with (out / "channels.csv").open(encoding="utf-8-sig") as file:
        header = file.readline().strip().split(",")
        rows = [line.split(",") for line in file]
    column = next(i for i, name in enumerate(header) if name.strip('"').startswith(f"{channel} ["))
    values = [float(row[column]) for row in rows if row[column].strip()]
    assert len(values) > 100 and any(v != 0 for v in values)


@pytest.mark.parametrize(
    ("log", "template", "channel"),
    [
        (RAV4_LOG, "comma2k19_rav4.toml", "vehicle_speed"),
        (CAR_MF4, "canedge_car_gps.toml", "vehicle_speed"),
    ],
    ids=["rav4-candump", "canedge-car-mf4"],
)
def test_real_logs_export(tmp_path: Path, log: tuple[str, str], template: str, channel: str) -> None:
    out = tmp_path / "export"
    code, stderr = export(real_path(*log), config_from_template(template, tmp_path), out)
    assert_exported(out, code, stderr, channel)


def test_a_real_log_without_a_frame_of_any_role_is_not_exported(tmp_path: Path) -> None:
    """CSS's J1939 truck log with a config whose roles it does not carry: nothing to convert —
    one line naming the log and the config, exit 1, no folder (it wrote an export of 0 rows)."""
    out = tmp_path / "export"
    code, stderr = export(real_path(*J1939_MF4), config_from_template("canedge_j1939.toml", tmp_path), out)
    assert code == 1 and "Traceback" not in stderr
    assert "no frames for any role of" in stderr and "wrong DBC or config for this log?" in stderr
    assert not out.exists()


def test_logan_exports_with_repaired_dbc(tmp_path: Path, logan_log: Path, fixed_logan_dbc: Path) -> None:
    config = config_from_template("nemodrive_logan.toml", tmp_path, LOGAN_DBC=fixed_logan_dbc)
    out = tmp_path / "export"
    code, stderr = export(logan_log, config, out)
    assert_exported(out, code, stderr, "steer")
