"""Issue 20, second round: what an adversarial user still broke with inputs — roles the wrong way
round, numbers out of range, files that are not text, options that make no sense. Each attack as a
user makes it, through the command line: the exit code, the one line, what is on disk."""

import io
import json
import threading
import time
import uuid
from contextlib import redirect_stderr, redirect_stdout
from pathlib import Path

import can
import pytest
from rich.console import Console

from app.cli import main
from tests.simulated import REPO, cached_drive

MONDEO = (REPO / "config" / "mondeo.toml").read_text().replace('"../dbc/', f'"{REPO}/dbc/')


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main(argv, Console(file=out, width=100))
    flat = " ".join(out.getvalue().split())  # the console wraps long lines
    return code, flat, err.getvalue()


def config_with(tmp_path: Path, *replacements: tuple[str, str], name: str = "car.toml") -> Path:
    text = MONDEO
    for old, new in replacements:
        assert old in text, old
        text = text.replace(old, new)
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def drive_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("drive") / "drive.blf"
    with can.Logger(path) as writer:
        for m in cached_drive("constant_radius", 41, 15.1).messages:
            writer.on_message_received(m)
    return path


YAW = 'yaw_rate = "AngVelHor.AngVelZ_hor"'
FLIPPED_YAW = (YAW, 'yaw_rate = {signal = "AngVelHor.AngVelZ_hor", scale = -1.0}')
FLIPPED_SIDESLIP = (
    ('vy = "Correvit.VelY_cor"', 'vy = {signal = "Correvit.VelY_cor", scale = -1.0}'),
    ('beta = "Correvit.Angle_cor"', 'beta = {signal = "Correvit.Angle_cor", scale = -1.0}'),
)


@pytest.mark.parametrize("flips", [(FLIPPED_YAW,), FLIPPED_SIDESLIP], ids=["yaw rate", "vy and beta"])
def test_a_role_the_wrong_way_round_is_named_never_a_negative_c2n(
    flips: tuple[tuple[str, str], ...], drive_log: Path, tmp_path: Path
) -> None:
    config = config_with(tmp_path, *flips)
    code, out, err = run_cli(
        ["analyze", str(drive_log), "--config", str(config), "--json", str(tmp_path / "a.json")]
    )
    assert code == 0 and "Traceback" not in err
    assert "C2n: no result (the sideslip and the yaw rate disagree in sign" in out
    assert "check `scale` of the roles yaw_rate" in out
    summary = json.loads((tmp_path / "a.json").read_text())
    assert summary["c2n"] is None and summary["u0_mps"] is None
    assert summary["warnings"][0].startswith("the sideslip and the yaw rate disagree in sign")
    assert summary["regression"]["c2n"] < 0  # the fit is kept for the record, not reported as C2n
    # export: the same, and every file written
    code, _, err = run_cli(["export", str(drive_log), "--config", str(config), "--out", str(tmp_path / "x")])
    assert code == 0 and "Traceback" not in err
    exported = json.loads((tmp_path / "x" / "summary.json").read_text())
    assert exported["c2n"] is None and "disagree in sign" in exported["warnings"][0]
    assert (tmp_path / "x" / "report.html").exists()


def test_live_with_a_flipped_yaw_rate_records_every_frame_and_names_the_sign(tmp_path: Path) -> None:
    config = config_with(tmp_path, FLIPPED_YAW)
    channel = f"flip-{uuid.uuid4().hex}"
    frames = cached_drive("constant_radius", 41, 15.1).messages
    started = threading.Event()

    def send() -> None:
        with can.Bus(interface="virtual", channel=channel, preserve_timestamps=True) as bus:
            started.wait(5)
            time.sleep(0.3)
            for m in frames:
                bus.send(m)

    sender = threading.Thread(target=send)
    sender.start()
    started.set()
    record = tmp_path / "sessions"
    argv = ["live", "-i", "virtual", "-c", channel, "--config", str(config), "--record", str(record)]
    code, out, err = run_cli([*argv, "--duration", "6"])
    sender.join()
    assert code == 0 and "Traceback" not in err
    [session] = list(record.glob("20*"))
    recorded = list(can.LogReader(session / "frames.log"))
    assert len(recorded) == len(frames)
    summary = json.loads((session / "summary.json").read_text())
    assert summary["frames"]["total"] == len(frames) and summary["c2n"] is None
    assert "disagree in sign" in out
