"""The real measured drive (data/real/stanford-revs-thunderhill) in the project's CAN layouts.

A slice of the race laps is turned into frames at the virtual sensor of config/revs_250lm.toml,
written as a BLF, read back through the pipeline and compared with the source files: the data
survive the conversion within the DBCs' resolution and the sensor model's noise, every role
comes back in its unit with its sign, and ``c2n analyze`` and ``c2n gap`` run on the log to a
sentence, never a traceback. A missing or malformed source file is one error line naming it.
"""

import importlib.util
import io
import json
import math
from collections import Counter
from collections.abc import Callable
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType

import can
import numpy as np
import pytest

from app.cli import main
from app.config import Config, load_config
from app.errors import LogFileError
from app.pipeline import Pipeline
from app.sim.measured_drive import SOURCE_FILES, MeasuredOptions, measured_drive, read_channels
from app.sim.sensors import LOG_START
from app.sim.simulated_drive import SimulatedDrive, truth_path, write_drive
from tests.real_data import REPO_ROOT, needs_real_data, real_path

pytestmark = needs_real_data

FOLDER = "stanford-revs-thunderhill"
CONFIG = REPO_ROOT / "config" / "revs_250lm.toml"
TOOL = REPO_ROOT / "tools" / "measured_drive.py"

# The source's facts (its README): 55 001 samples at 100 Hz, 149.99 … 699.99 s; lr = 1.07 m.
SAMPLES, STEP_S, T_FIRST, T_LAST, LR_M = 55_001, 0.01, 149.99, 699.99, 1.07
# One minute of laps with corners both ways and the sideslip at the sensor of both signs.
START_S, DURATION_S, SEED = 400.0, 60.0, 3
SIGMA_V = 0.02  # m/s: the sensor model's optical noise (SensorSetup)
KMH_BIT = 0.036 / 3.6  # m/s: one bit of VelX/VelY


@pytest.fixture(scope="module")
def config() -> Config:
    return load_config(CONFIG)


@pytest.fixture(scope="module")
def source() -> dict[str, np.ndarray]:
    folder = real_path(FOLDER)
    names = ("t", "vx", "vy", "yawRate", "delta", "ayCG")
    return {name: np.loadtxt(folder / f"{name}.txt") for name in names}


@pytest.fixture(scope="module")
def drive(config: Config) -> SimulatedDrive:
    options = MeasuredOptions(seed=SEED, start_s=START_S, duration_s=DURATION_S)
    return measured_drive(config, real_path(FOLDER), options)


@pytest.fixture(scope="module")
def log(drive: SimulatedDrive, tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("revs") / "drive.blf"
    write_drive(drive, path)
    return path


@dataclass(frozen=True)
class Decoded:
    """What the pipeline decoded from the written log: role → (source index, SI value)."""

    pipeline: Pipeline
    frames: int
    roles: dict[str, tuple[np.ndarray, np.ndarray]]


@pytest.fixture(scope="module")
def decoded(config: Config, log: Path) -> Decoded:
    pipeline, frames = Pipeline(config), 0
    first = round(START_S / STEP_S) - round(T_FIRST / STEP_S)
    values: dict[str, list[tuple[int, float]]] = {}
    with can.LogReader(log) as reader:
        for message in reader:
            frames += 1
            record = pipeline.process(message)
            if record is None:
                continue
            # a frame carries the value at its 10 ms grid point; the jitter after it is < 1 ms
            index = first + round((record.t - LOG_START) / STEP_S)
            for role, value in record.signals.items():
                values.setdefault(role, []).append((index, value))
    pipeline.finish()
    columns = {role: np.array(pairs) for role, pairs in values.items()}
    roles = {role: (column[:, 0].astype(int), column[:, 1]) for role, column in columns.items()}
    return Decoded(pipeline, frames, roles)


def test_the_slice_and_its_metadata(drive: SimulatedDrive, log: Path) -> None:
    truth = json.loads(truth_path(log).read_text())
    assert truth["measured"] is True and truth["c2n"] is None
    assert truth["source"]["dataset"] == FOLDER
    assert truth["licence"].startswith("MIT")
    point = truth["sensor_point"]
    assert point["d_m"] == 3.0
    assert point["ahead_of_cg_m"] == pytest.approx(3.0 - LR_M, abs=1e-4)
    assert truth["source_t_s"] == pytest.approx([START_S, START_S + DURATION_S])
    assert truth["frames"] == len(drive.messages)


def test_the_whole_drive_converts_sample_for_sample(config: Config) -> None:
    """All 550 s: one frame per source sample on every 100 Hz message, one per two at 50 Hz."""
    whole = measured_drive(config, real_path(FOLDER))
    assert whole.trace is not None and len(whole.trace.t) == SAMPLES
    per_id = Counter(m.arbitration_id for m in whole.messages)
    at_100_hz = (0x7E0, 0x7E4, 0x7E5, 0x7E, 0x91, 0x92, 0x217)
    assert {i: per_id[i] for i in at_100_hz} == dict.fromkeys(at_100_hz, SAMPLES)
    assert per_id[0x7EB] == per_id[0x415] == (SAMPLES + 1) // 2
    assert whole.truth["duration_s"] == pytest.approx(T_LAST - T_FIRST)
    assert whole.truth["speed_range_mps"] == pytest.approx([16.478, 61.231], abs=1e-3)


def test_every_frame_of_the_log_decodes(drive: SimulatedDrive, decoded: Decoded) -> None:
    counts = decoded.pipeline.snapshot().frames
    assert decoded.frames == counts.total == len(drive.messages)
    assert counts.used + counts.unused == counts.total
    per_id = Counter({frame_id: n for (_, frame_id, _), n in counts.by_id.items()})
    samples = round(DURATION_S / STEP_S) + 1
    assert per_id[0x7E5] == per_id[0x91] == per_id[0x7E] == samples
    assert per_id[0x7EB] == per_id[0x415] == (samples + 1) // 2


def _errors(got: np.ndarray, want: np.ndarray) -> tuple[float, float, float]:
    error = got - want
    return float(np.mean(error)), float(np.std(error)), float(np.max(np.abs(error)))


def test_optical_speed_and_the_sideslip_at_the_sensor_match_the_source(
    source: dict[str, np.ndarray], decoded: Decoded
) -> None:
    x_p = 3.0 - LR_M
    index, vx = decoded.roles["vx"]
    u = source["vx"][index]
    mean, std, worst = _errors(vx, u)
    quantised = math.hypot(SIGMA_V, KMH_BIT / math.sqrt(12))
    assert abs(mean) < 0.002 and 0.8 * quantised < std < 1.2 * quantised, (mean, std)
    assert worst < 6 * SIGMA_V + KMH_BIT

    index, vy = decoded.roles["vy"]
    v_p = source["vy"][index] + x_p * source["yawRate"][index]
    mean, std, worst = _errors(vy, v_p)
    assert abs(mean) < 0.002 and 0.8 * quantised < std < 1.2 * quantised, (mean, std)
    assert worst < 6 * SIGMA_V + KMH_BIT

    index, beta = decoded.roles["beta"]
    want = np.arctan2(source["vy"][index] + x_p * source["yawRate"][index], source["vx"][index])
    sigma = SIGMA_V / source["vx"][index]  # rad: the optical noise seen as an angle
    normalised = (beta - want) / np.hypot(sigma, math.radians(0.01) / math.sqrt(12))
    assert abs(float(np.mean(normalised))) < 0.05 and 0.85 < float(np.std(normalised)) < 1.15
    assert float(np.max(np.abs(normalised))) < 6
    clear = np.abs(want) > 10 * sigma
    assert np.array_equal(np.sign(beta[clear]), np.sign(want[clear]))
    # the reason for the sensor point: the sideslip there has both signs relative to the turn
    turning = np.abs(source["yawRate"][index]) > 0.1
    same = np.sign(beta[turning & clear]) == np.sign(source["yawRate"][index][turning & clear])
    assert 0.1 < float(np.mean(same)) < 0.9


@pytest.mark.parametrize(
    ("role", "column", "unit", "scale", "sigma", "bit"),
    [
        ("yaw_rate", "yawRate", "deg/s", 1.0, math.radians(0.05), math.radians(0.02)),
        ("steer", "delta", "deg", 12.0, 0.0, math.radians(0.1)),
        ("speed", "vx", "km/h", 1.0, 0.05 / 3.6, 0.01 / 3.6),
        ("ay", "ayCG", "m/s^2", 1.0, 0.05, 0.01),
    ],
)
def test_vehicle_roles_come_back_in_their_units_with_their_signs(
    config: Config,
    source: dict[str, np.ndarray],
    decoded: Decoded,
    role: str,
    column: str,
    unit: str,
    scale: float,
    sigma: float,
    bit: float,
) -> None:
    """The yaw rate (rad/s, + left), the steering-wheel angle (rad, + left: the road-wheel angle
    times the steering ratio), the vehicle speed and the lateral acceleration (SI) as measured."""
    assert config.roles[role].unit == unit
    index, got = decoded.roles[role]
    want = scale * source[column][index]
    slope = float(np.polyfit(want, got, 1)[0])
    assert slope == pytest.approx(1.0, abs=0.002), "scale or sign"
    mean, std, worst = _errors(got, want)
    spread = math.hypot(sigma, bit / math.sqrt(12))
    assert abs(mean) < 0.1 * spread + 1e-9 and std < 1.2 * spread, (mean, std, spread)
    assert worst < 6 * sigma + bit


# -- the source files: a missing or malformed one is one error line naming it --------------------


def _load_tool() -> ModuleType:
    spec = importlib.util.spec_from_file_location("measured_drive_tool", TOOL)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _copy_with(folder: Path, name: str, change: Callable[[list[str]], list[str] | None]) -> Path:
    """The source folder linked into ``folder``, with ``name`` rewritten (or left out, on None)."""
    data = real_path(FOLDER)
    for other in SOURCE_FILES:
        if other != name:
            (folder / f"{other}.txt").symlink_to(data / f"{other}.txt")
    lines = change((data / f"{name}.txt").read_text().splitlines())
    if lines is not None:
        (folder / f"{name}.txt").write_text("\n".join(lines) + "\n")
    return folder


def _replace(k: int, text: str) -> Callable[[list[str]], list[str]]:
    return lambda lines: [*lines[:k], text, *lines[k + 1 :]]


@pytest.mark.parametrize(
    ("name", "change", "says"),
    [
        ("yawRate", lambda lines: None, "yawRate.txt: missing"),
        ("vy", _replace(2, "  abc"), "vy.txt: line 3 is 'abc', not a number"),
        ("delta", lambda lines: lines[:10], "delta.txt: 10 values but t.txt has 55001"),
        ("ayCG", _replace(99, "nan"), "ayCG.txt: line 100 is nan"),
        ("axCG", _replace(4, "1.0 2.0"), "axCG.txt: line 5 holds several values"),
        ("vx", lambda lines: [], "vx.txt: empty"),
        ("t", _replace(1000, "159.97"), "t.txt: line 1001 is -0.01 s after the one before"),
    ],
)
def test_a_missing_or_malformed_file_is_one_error_line_naming_it(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    name: str,
    change: Callable[[list[str]], list[str] | None],
    says: str,
) -> None:
    (tmp_path / "data").mkdir()
    folder = _copy_with(tmp_path / "data", name, change)
    with pytest.raises(LogFileError, match=says.replace(".", r"\.")):
        read_channels(folder)
    out = tmp_path / "drive.blf"
    assert _load_tool().main([str(folder), "--out", str(out), "--config", str(CONFIG)]) == 1
    captured = capsys.readouterr()
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("measured_drive: error: "), captured.err
    assert str(folder / f"{name}.txt") in lines[0] and says in lines[0]
    assert not out.exists()


def test_the_tool_writes_the_log_and_says_what_it_wrote(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "slice.log"
    argv = [str(real_path(FOLDER)), "--out", str(out), "--start", "300", "--duration", "2"]
    assert _load_tool().main(argv) == 0
    printed = capsys.readouterr().out
    assert printed.startswith(f"wrote {out} and slice.log.truth.json") and "sensor point d 3.000 m" in printed
    with can.LogReader(out) as reader:
        assert sum(1 for _ in reader) == json.loads(truth_path(out).read_text())["frames"]


# -- the commands on the written log ---------------------------------------------------------------


def _run(*argv: str) -> tuple[int, str, str]:
    stdout, stderr = io.StringIO(), io.StringIO()
    with redirect_stdout(stdout), redirect_stderr(stderr):
        code = main(list(argv))
    return code, stdout.getvalue(), stderr.getvalue()


def test_c2n_analyze_gives_a_result_or_one_clear_sentence(log: Path, tmp_path: Path) -> None:
    """Race laps have no steady sweep through u0: whatever the pipeline says, it says in words."""
    out = tmp_path / "summary.json"
    code, stdout, stderr = _run("analyze", str(log), "--config", str(CONFIG), "--json", str(out))
    assert code in (0, 1) and "Traceback" not in stdout + stderr
    errors = [line for line in stderr.splitlines() if line.startswith("c2n: error:")]
    assert len(errors) == (code == 1), stderr
    summary = json.loads(out.read_text())
    assert summary["frames"]["total"] == json.loads(truth_path(log).read_text())["frames"]
    if code == 0 and summary["c2n"] is None:
        result = [line for line in stdout.splitlines() if line.startswith("C2n:")]
        assert len(result) == 1 and "no result (" in result[0], stdout
        assert summary["warnings"], "a drive without a result says why"


@pytest.fixture(scope="module")
def whole_log(config: Config, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """All 550 s of the laps."""
    log = tmp_path_factory.mktemp("revs") / "laps.blf"
    write_drive(measured_drive(config, real_path(FOLDER), MeasuredOptions(seed=SEED)), log)
    return log


def test_race_laps_beyond_the_linear_range_are_refused_with_what_the_cornering_was(
    whole_log: Path, tmp_path: Path
) -> None:
    """No sweep through u0, and the corners taken at 5–8 m/s²: no C2n, and the refusal counts the
    cornering by what kept it out and says what to drive."""
    out = tmp_path / "summary.json"
    code, stdout, stderr = _run("analyze", str(whole_log), "--config", str(CONFIG), "--json", str(out))
    assert code == 0, stderr
    summary = json.loads(out.read_text())
    assert summary["c2n"] is None and summary["quasi_steady"] is None
    cornering = summary["cornering"]
    assert cornering["turning_s"] > 300 and cornering["ay_high_s"] > 0.8 * cornering["turning_s"]
    parts = cornering["ay_high_s"] + cornering["transient_s"] + cornering["usable_s"] + cornering["tight_s"]
    assert parts == pytest.approx(cornering["turning_s"], abs=0.3)
    (line,) = [line for line in stdout.splitlines() if line.startswith("C2n:")]
    assert f"of {cornering['turning_s']:.0f} s cornering, {cornering['ay_high_s']:.0f} s beyond" in line
    assert "drive steady circles at 2–4 m/s²" in line


def test_c2n_gap_runs_to_a_verdict(config: Config, whole_log: Path, tmp_path: Path) -> None:
    """The whole drive: race laps are beyond the linear model the gap compares with (a minute has
    too little driving in its linear range to diagnose). Either a refusal in one line naming the
    manoeuvre the laps lack (no steady cornering near u0), or a report in which no named effect
    and no calibrated nuisance it rests on sits on a physical bound unannounced, and every
    calibrated value comes with its interval."""
    out = tmp_path / "gap.json"
    code, stdout, stderr = _run("gap", str(whole_log), "--config", str(CONFIG), "--json", str(out))
    assert "Traceback" not in stdout + stderr
    if code == 1:
        assert stderr.count("\n") == 1 and "no steady cornering near the sideslip's sign change" in stderr
        assert "drive constant-radius sweeps through u0, left and right" in stderr
        assert not out.exists()
        return
    assert code == 0, stderr
    assert "Traceback" not in stdout + stderr
    assert stdout.startswith("gap: ")
    result = json.loads(out.read_text())
    assert result["diagnosis"] in {"none", "unexplained", *(c["effect"] for c in result["candidates"])}
    assert all(c["at_bound"] == [] for c in result["candidates"] if c["named"])
    for name, value in result["calibration"].items():
        low, high = value["ci95"]
        assert low <= value["fitted"] <= high, name
        assert ("at its physical bound" in stdout) >= value["at_bound"]
