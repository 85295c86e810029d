"""The command line: exit codes, one-line errors, and each command doing its job."""

import errno
import json
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path

import can
import pytest
from rich.console import Console

from app.cli import main
from app.sim.simulated_drive import write_drive
from tests.live_process import foreground
from tests.simulated import REPO, cached_drive


def console() -> Console:
    return Console(file=None, force_terminal=False, soft_wrap=True, width=200)


@pytest.fixture(scope="module")
def drive_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    log = tmp_path_factory.mktemp("cli") / "drive.blf"
    write_drive(cached_drive("constant_radius", 41, 15.1), log)
    return log


def one_error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert len(lines) == 1, err
    assert lines[0].startswith("c2n: error: ") and "Traceback" not in err
    return lines[0]


def test_analyze_prints_each_crossing_then_the_result_and_writes_json(
    drive_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "summary.json"
    assert main(["analyze", str(drive_log), "--json", str(out)]) == 0
    lines = capsys.readouterr().out.splitlines()
    crossing_lines = [
        line for line in lines if " s  " in line and "C2n " in line and not line.startswith("C2n =")
    ]
    assert len(crossing_lines) == 4
    assert lines[-2].startswith("C2n = ")  # the result comes after the crossings ...
    assert lines[-1].startswith("  d = ")  # ... and what the fits found besides C2n under it
    summary = json.loads(out.read_text())
    assert set(summary) >= {"c2n", "c2n_ci95", "u0_mps", "crossings", "regression", "frames", "warnings"}
    assert abs(summary["c2n"] / 15.1 - 1) <= 0.01
    assert summary["frames"]["total"] == len(cached_drive("constant_radius", 41, 15.1).messages)
    crossing = summary["crossings"][0]
    assert set(crossing) >= {"t", "u0_mps", "c2n", "ci95", "direction", "sweep", "ay_mps2"}
    assert crossing["direction"] in ("left", "right") and crossing["sweep"] in ("up", "down")
    for c, line in zip(summary["crossings"], crossing_lines, strict=True):
        assert f"{c['c2n']:.3f}" in line and c["direction"] in line


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["analyze", "nothere.blf"], "nothere.blf: no such file"),
        (["analyze", "{tmp}/x.json"], "unknown log format '.json'"),
        (["analyze", "{tmp}/empty.log"], "the file is empty"),
        (["analyze", "{log}", "--config", "{tmp}/none.toml"], "none.toml: config file not found"),
        (["simulate", "--out", "{tmp}/x.txt"], "unknown log format '.txt'"),
        (["live", "-i", "nosuchinterface", "-c", "x", "--no-record"], "cannot open"),
        # was: "sent 0 frames", exit 0
        (
            ["replay", "{tmp}/garbage.log", "-i", "virtual", "-c", "g"],
            "not a readable log, damaged from the start",
        ),
    ],
)
def test_user_errors_are_one_line_and_exit_1(
    args: list[str], message: str, drive_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "x.json").write_text("{}")
    (tmp_path / "empty.log").write_text("")
    (tmp_path / "garbage.log").write_text("garbage\n")
    argv = [a.replace("{tmp}", str(tmp_path)).replace("{log}", str(drive_log)) for a in args]
    assert main(argv, console()) == 1
    assert message in one_error_line(capsys.readouterr().err)


def test_bad_usage_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["analyze"]) == 2
    assert main(["frobnicate"]) == 2
    assert main([]) == 2
    assert "usage" in capsys.readouterr().err
    assert main(["live", "-i", "virtual", "-c", "x", "--no-record", "--bus-arg", "foo"]) == 2
    assert one_error_line(capsys.readouterr().err) == "c2n: error: --bus-arg wants KEY=VALUE, got 'foo'"
    # one channel twice: every frame read, recorded and decoded twice, the sweeps lost to the
    # times going back and forth (it ran so)
    assert main(["live", "-i", "virtual", "-c", "x", "-c", "y", "-c", "x", "--no-record"]) == 2
    assert (
        one_error_line(capsys.readouterr().err) == "c2n: error: -c x is given twice — name each channel once"
    )


def test_an_output_error_names_the_file_and_debug_shows_its_cause(
    drive_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    def full(path: Path) -> None:  # the disk fills as the summary is written
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr("app.output.files.synced", full)
    out = tmp_path / "s.json"
    assert main(["analyze", str(drive_log), "--json", str(out)]) == 1
    said = one_error_line(capsys.readouterr().err)
    assert f"c2n: error: {out}: cannot write the summary (No space left on device)" in said
    assert main(["analyze", str(drive_log), "--json", str(out), "--debug"]) == 1
    err = capsys.readouterr().err
    assert "The above exception was the direct cause" in err and "OutputError" in err


def test_truncated_log_uses_every_frame_before_the_damage(
    drive_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text_log = tmp_path / "drive.log"
    with can.Logger(text_log) as writer:
        for m in can.LogReader(drive_log):
            writer.on_message_received(m)
    lines = text_log.read_text().splitlines()
    keep = len(lines) // 2
    text_log.write_text(
        "\n".join(lines[:keep]) + "\n(1763900099.5) can1 7E5#00GARBAGE\n" + "\n".join(lines[keep:])
    )
    out = tmp_path / "s.json"
    assert main(["analyze", str(text_log), "--json", str(out)]) == 0
    summary = json.loads(out.read_text())
    assert summary["frames"]["total"] == keep
    assert any(f"stopped after frame {keep}" in w for w in summary["warnings"])
    assert f"stopped after frame {keep}" in capsys.readouterr().err


def test_missing_required_role_names_it(
    drive_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A log without the optical sensor: the message says which role had no frames."""
    vehicle_only = tmp_path / "vehicle.log"
    with can.Logger(vehicle_only) as writer:
        for m in can.LogReader(drive_log):
            if not 0x7E0 <= m.arbitration_id <= 0x7EB:
                writer.on_message_received(m)
    out = tmp_path / "s.json"
    assert main(["analyze", str(vehicle_only), "--json", str(out)]) == 1
    line = one_error_line("\n".join(line for line in capsys.readouterr().err.splitlines() if "error" in line))
    assert "no frames for role 'vx' (Correvit.VelX_cor, id 0x7E5)" in line
    summary = json.loads(out.read_text())  # nothing lost: the counts are still written
    assert summary["c2n"] is None and summary["frames"]["total"] > 0


def test_merge_per_channel_logs_of_one_drive(
    drive_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two candump files, one per interface, merged by timestamp give the single log's crossings."""
    sensor, vehicle = tmp_path / "can1.log", tmp_path / "can0.log"
    with can.Logger(sensor) as s, can.Logger(vehicle) as v:
        for m in can.LogReader(drive_log):
            (s if m.channel == 1 else v).on_message_received(m)
    one, two = tmp_path / "one.json", tmp_path / "two.json"
    assert main(["analyze", str(drive_log), "--json", str(one)]) == 0
    assert main(["analyze", str(sensor), str(vehicle), "--merge", "--json", str(two)]) == 0
    a, b = json.loads(one.read_text()), json.loads(two.read_text())
    assert [c["c2n"] for c in a["crossings"]] == [c["c2n"] for c in b["crossings"]]


def test_simulate_writes_log_and_truth(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "step.asc"
    assert (
        main(
            [
                "simulate",
                "--scenario",
                "step_steer",
                "--seed",
                "5",
                "--c2n",
                "12.5",
                "--out",
                str(out),
                "--optical-hz",
                "50",
            ]
        )
        == 0
    )
    truth = json.loads((tmp_path / "step.asc.truth.json").read_text())
    assert truth["c2n"] == pytest.approx(12.5) and truth["d_m"] == 1.11
    assert truth["u0_mps"] == pytest.approx((12.5 * 9.81 * 1.11) ** 0.5)
    assert sum(1 for _ in can.LogReader(out)) == truth["frames"]
    assert "wrote" in capsys.readouterr().out


def test_replay_sends_every_frame_onto_a_virtual_bus(
    drive_log: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    channel = f"replay-{uuid.uuid4().hex}"
    received: list[can.Message] = []
    with can.Bus(interface="virtual", channel=channel) as listener:
        notifier = can.Notifier(listener, [received.append])
        assert (
            main(["replay", str(drive_log), "-i", "virtual", "-c", channel, "--rate", "1e6"], console()) == 0
        )
        deadline = time.monotonic() + 10
        total = len(cached_drive("constant_radius", 41, 15.1).messages)
        while len(received) < total and time.monotonic() < deadline:
            time.sleep(0.05)
        notifier.stop()
    assert len(received) == total
    assert [m.arbitration_id for m in received[:50]] == [
        m.arbitration_id for m in list(can.LogReader(drive_log))[:50]
    ]


def test_live_records_every_frame_and_writes_the_summary(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    channel = f"live-{uuid.uuid4().hex}"
    frames = cached_drive("constant_radius", 41, 15.1).messages[:5000]
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
    code = main(
        [
            "live",
            "-i",
            "virtual",
            "-c",
            channel,
            "--record",
            str(tmp_path),
            "--duration",
            "3",
            "--json",
            str(tmp_path / "s.json"),
        ],
        console(),
    )
    sender.join()
    assert code == 0
    [session] = list(tmp_path.glob("20*"))
    recorded = list(can.LogReader(session / "frames.log"))
    assert len(recorded) == len(frames)
    assert [bytes(m.data) for m in recorded] == [bytes(m.data) for m in frames]
    assert {p.name for p in (session / "config").iterdir()} == {
        "mondeo.toml",
        "kistler_smotion.dbc",
        "vehicle_ford.dbc",
    }
    summary = json.loads((session / "summary.json").read_text())
    assert summary["frames"]["total"] == len(frames)
    assert json.loads((tmp_path / "s.json").read_text())["frames"] == summary["frames"]
    assert (session / "events.csv").read_text().startswith("t,event,direction,sweep,u0_mps")
    assert f"session saved in {session}" in capsys.readouterr().out


def test_demo_prints_crossings_and_c2n_beside_the_truth(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--speedup", "1000", "--seed", "5"], console()) == 0
    out = capsys.readouterr().out
    assert sum(" s  " in line and "C2n " in line for line in out.splitlines()) >= 4
    [truth_line] = [line for line in out.splitlines() if line.startswith("simulated truth C2n")]
    error = float(truth_line.rsplit("error ", 1)[1].rstrip(" %"))
    assert abs(error) <= 1.0


def test_python_dash_m_app_is_the_same_program() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "app", "--version"], capture_output=True, text=True, cwd=REPO, check=False
    )
    assert result.returncode == 0 and result.stdout.startswith("c2n ")


def test_bad_role_in_the_config_is_one_line(
    drive_log: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = (REPO / "config" / "mondeo.toml").read_text().replace('"../dbc/', f'"{REPO}/dbc/')
    config = tmp_path / "car.toml"
    config.write_text(text.replace('vy = "Correvit.VelY_cor"', 'vy = "Correvit.VelY"'))
    assert main(["analyze", str(drive_log), "--config", str(config)]) == 1
    line = one_error_line(capsys.readouterr().err)
    assert str(config) in line and "[roles] vy names signal 'Correvit.VelY' that no DBC has" in line


@pytest.mark.parametrize(
    ("signal", "ignored_at_start"), [("SIGINT", False), ("SIGINT", True), ("SIGTERM", False)]
)
def test_live_ends_cleanly_on_ctrl_c_and_sigterm_and_writes_the_summary(
    tmp_path: Path, signal: str, ignored_at_start: bool
) -> None:
    """Also when started with SIGINT ignored, as a shell starts background jobs."""
    import signal as signals

    def ignore_sigint() -> None:
        signals.signal(signals.SIGINT, signals.SIG_IGN)

    process = subprocess.Popen(
        [sys.executable, "-m", "app", "live", "-i", "virtual", "-c", "nobody", "--record", str(tmp_path)],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        preexec_fn=ignore_sigint if ignored_at_start else None,
    )
    assert process.stdout is not None
    prompt = process.stdout.readline()  # the user presses Ctrl-C once the session says how to end it
    assert "Ctrl-C ends the session" in prompt
    time.sleep(0.5)
    process.send_signal(getattr(signals, signal))
    out, err = process.communicate(timeout=30)
    out = prompt + out
    assert process.returncode == 0, err
    [session] = list(tmp_path.glob("20*"))
    summary = json.loads((session / "summary.json").read_text())
    assert summary["frames"]["total"] == 0 and summary["c2n"] is None
    assert "session saved in" in out and "Traceback" not in err


@pytest.mark.parametrize(
    "command", ["live", "replay", "analyze", "export", "simulate", "gap", "gap-check", "demo"]
)
def test_every_command_has_help(command: str, capsys: pytest.CaptureFixture[str]) -> None:
    assert main([command, "--help"]) == 0
    assert f"usage: c2n {command}" in capsys.readouterr().out


@pytest.mark.parametrize(
    "command", ["live", "replay", "analyze", "export", "simulate", "gap", "gap-check", "campaign", "demo"]
)
def test_help_is_self_contained_and_says_the_defaults(
    command: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """No reference to a document users do not have, no code marks, and each default said."""
    assert main([command, "--help"]) == 0
    text = capsys.readouterr().out
    assert "DESIGN" not in text and "``" not in text
    flat = " ".join(text.split())
    expected = {
        "live": "--rate X the bus carries a replay",
        "replay": "(default: 1.0)",
        "analyze": "(- : standard output)",
        "export": "(default:",
        "simulate": "(default: 0)",
        "gap": "(- : standard output)",
        "gap-check": "(default:",
        "campaign": "--by COLUMN",
        "demo": "(default:",
    }
    assert expected[command] in flat


def test_json_dash_is_standard_output_and_the_words_go_to_stderr(
    drive_log: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["analyze", str(drive_log), "--json", "-"]) == 0
    captured = capsys.readouterr()
    summary = json.loads(captured.out)  # nothing but the JSON on stdout
    assert summary["c2n"] == pytest.approx(15.1, rel=0.01)
    assert "C2n = " in captured.err and not Path("-").exists()


def test_replay_and_simulate_show_their_progress_on_a_terminal(drive_log: Path, tmp_path: Path) -> None:
    import io

    out = io.StringIO()
    terminal = Console(file=out, force_terminal=True, width=120)
    channel = f"progress-{uuid.uuid4().hex}"
    assert main(["replay", str(drive_log), "-i", "virtual", "-c", channel, "--rate", "1000"], terminal) == 0
    shown = out.getvalue()
    assert f"replaying {drive_log.name}" in shown and "frames sent" in shown
    out = io.StringIO()
    assert main(["simulate", "--out", str(tmp_path / "x.blf")], Console(file=out, force_terminal=True)) == 0
    assert "simulating the constant_radius drive" in out.getvalue()


def test_a_ctrl_c_that_passed_through_source_text_still_exits_130(tmp_path: Path) -> None:
    """A KeyboardInterrupt raised inside an exec() of source text (a signal landing while a
    dataclass's methods are made) leaves CPython's unhandled-interrupt flag set though c2n caught
    it: under `python -m`, the interpreter then ended itself by SIGINT (-2), 1 run in 4 of an
    export ended by SIGTERM, after `c2n: interrupted`."""
    (tmp_path / "forced.py").write_text(
        "import sys\n"
        f"sys.path.insert(0, {str(REPO)!r})\n"
        "from app.cli import entry, split\n"
        "def run(args, console):\n"
        "    exec('raise KeyboardInterrupt')\n"
        "split.run = run\n"
        "sys.argv = ['c2n', 'split', 'day.log']\n"
        "entry()\n"
    )
    ended = subprocess.run([sys.executable, "-m", "forced"], cwd=tmp_path, capture_output=True, timeout=120)
    assert ended.returncode == 130 and ended.stderr.decode().endswith("c2n: interrupted\n"), ended.stderr


def test_ctrl_c_while_c2n_s_modules_load_is_one_line_and_exit_130(tmp_path: Path) -> None:
    """Ctrl-C in the command's first 0.7 s, while its modules load, printed the traceback of
    whichever import it landed in."""
    (tmp_path / "early.py").write_text(
        "import os, signal, sys\n"
        f"sys.path.insert(0, {str(REPO)!r})\n"
        "class Press:\n"
        "    def find_spec(self, name, path=None, target=None):\n"
        "        if name == 'app.cli.analyze':  # Ctrl-C as c2n's modules load\n"
        "            os.kill(os.getpid(), signal.SIGINT)\n"
        "sys.meta_path.insert(0, Press())\n"
        "sys.argv = ['c2n', 'demo']\n"
        "from app.__main__ import run\n"
        "run()\n"
    )
    ended = subprocess.run(
        [sys.executable, "early.py"], cwd=tmp_path, capture_output=True, timeout=120, preexec_fn=foreground
    )
    assert ended.returncode == 130 and ended.stderr == b"c2n: interrupted\n", ended.stderr
    assert not (tmp_path / "c2n-demo").exists()


@pytest.mark.parametrize("loop", [[], ["--loop"]])
def test_replay_ended_by_a_signal_says_it_did_not_send_the_whole_log(
    drive_log: Path, loop: list[str]
) -> None:
    """`replay` stopped by SIGTERM said `sent 19760 frames` and exit 0, as if the log had gone
    out whole. `--loop` alone (until Ctrl-C) ends so as meant: exit 0."""
    import signal

    child = subprocess.Popen(
        [sys.executable, "-m", "app", "replay", str(drive_log), "-i", "virtual", "--rate", "1", *loop],
        cwd=REPO,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    time.sleep(3.0)  # sending, at the drive's own pace
    assert child.poll() is None
    child.send_signal(signal.SIGTERM)
    out, err = child.communicate(timeout=60)
    sent = int(out.split("sent ")[1].split(" frames")[0])
    assert 0 < sent < 100_000 and "Traceback" not in err
    if loop:
        assert child.returncode == 0 and "interrupted" not in err, err
    else:
        assert child.returncode == 130, err
        assert f"c2n: interrupted — {sent:,} frames sent, not the whole of {drive_log}" in err
