"""Every command driven with random options, numbers and config files (hypothesis, seeded): the
exit code is 0, 1 or 2, there is never a traceback, and nothing half-written is left looking
complete (every output is written aside and renamed into place)."""

import io
import uuid
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import can
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rich.console import Console

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
