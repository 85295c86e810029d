"""Issue 39, third round: silent wrong results, hangs and tracebacks a hostile user found. Each
attack through the command line as a user makes it: the exit code, the one line, what is printed."""

import http.server
import io
import math
import os
import shlex
import socket
import threading
import time
import uuid
import warnings
from collections.abc import Iterator
from contextlib import redirect_stderr, redirect_stdout
from dataclasses import replace
from pathlib import Path

import can
import numpy as np
import pytest
from rich.console import Console
from scipy.special import stdtrit

from app.campaign.analysis import content_hash
from app.campaign.comparison import finite
from app.campaign.manifest import read_manifest
from app.campaign.meta_analysis import trend
from app.campaign.repeats import counted_once
from app.campaign.row import SessionRow
from app.campaign.work import probe_scheduler
from app.cli import main
from app.cli.replay import Router, log_channel
from app.errors import C2nError
from app.results.agreement import Z95, DriveResult, disagreement
from app.sim.simulated_drive import write_drive
from app.sources.logs import drive_identity, first_of_each
from app.user_text import shown
from tests.simulated import cached_drive
from tests.test_reliability_inputs import config_with


def run_cli(argv: list[str]) -> tuple[int, str, str]:
    out, err = io.StringIO(), io.StringIO()
    with redirect_stdout(out), redirect_stderr(err):
        code = main(argv, Console(file=out, width=100))
    return code, out.getvalue(), err.getvalue()


def one_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.strip()]
    assert "Traceback" not in err and "MarkupError" not in err, err
    return lines[-1]


def candump(path: Path, channels: list[str], frames: int = 40) -> Path:
    """A small candump log alternating over ``channels``."""
    lines = [f"({1.0 + k * 0.001:.6f}) {channels[k % len(channels)]} 123#{k:02X}" for k in range(frames)]
    path.write_text("\n".join(lines) + "\n")
    return path


# --- 14: tracebacks become one line ------------------------------------------------------------


@pytest.mark.parametrize(
    "argv",
    [
        ["simulate", "--seed", "-1"],
        ["simulate", "--campaign", "2", "--seed", "-3"],
        ["simulate", "--session", "standard", "--seed", "-3"],
        ["demo", "--seed", "-5"],
    ],
)
def test_a_negative_seed_is_a_usage_error(argv: list[str], tmp_path: Path) -> None:
    code, _, err = run_cli([*argv, "--out", str(tmp_path / "x.log")])
    assert code == 2
    assert "a seed is 0 to 4294967295" in err and "Traceback" not in err
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("key, option", [("bitrate", "-b"), ("interface", "-i"), ("channel", "-c")])
@pytest.mark.parametrize("command", ["replay", "live"])
def test_a_bus_arg_that_has_its_own_option_is_a_usage_error(
    command: str, key: str, option: str, tmp_path: Path
) -> None:
    log = candump(tmp_path / "d.log", ["can0"])
    argv = ["replay", str(log)] if command == "replay" else ["live", "--no-record", "--duration", "1"]
    code, _, err = run_cli([*argv, "-i", "virtual", "--bus-arg", f"{key}=5"])
    assert code == 2
    assert one_line(err) == f"c2n: error: --bus-arg {key}=5: {key} has its own option, use {option}"


@pytest.mark.parametrize("address", ["garbage://x", "", "tcp://nohost", "local:"])
def test_a_scheduler_address_dask_cannot_use_is_a_usage_error(address: str, tmp_path: Path) -> None:
    manifest = tmp_path / "m.csv"
    manifest.write_text("log\nd.log\n")
    code, _, err = run_cli(["campaign", str(manifest), "--scheduler", address])
    assert code == 2
    assert "is no scheduler address: want 'local' or tcp|tls|ws|wss|ucx://HOST:PORT" in err
    assert not (tmp_path / "m-campaign").exists()


def test_gap_on_a_car_whose_model_diverges_is_one_line(drive_log: Path, tmp_path: Path) -> None:
    # the load transfer stated: else a 1 cm wheelbase is refused at load (its rear would lift braking)
    priors = ("[tyres]", "[priors]\nload_transfer_per_g = 0.2\n\n[tyres]")
    config = config_with(tmp_path, ("wheelbase_m = 2.70", "wheelbase_m = 0.01"), priors)
    code, _, err = run_cli(["gap", str(drive_log), "--config", str(config)])
    assert code == 1
    assert one_line(err).startswith("c2n: error: the config's car cannot follow this drive")
    assert "wheelbase_m" in err


# --- 13: hangs -----------------------------------------------------------------------------------


@pytest.fixture
def web_server() -> Iterator[str]:
    """An HTTP server on a free port: it accepts a connection and waits for a request."""
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), http.server.BaseHTTPRequestHandler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.server_address[1]}"
    server.shutdown()
    server.server_close()


def test_a_web_server_as_scheduler_is_refused_within_the_connect_timeout(web_server: str) -> None:
    started = time.monotonic()
    with pytest.raises(C2nError, match=r"sent no Dask handshake in 0\.5 s"):
        probe_scheduler(web_server, timeout_s=0.5)
    assert time.monotonic() - started < 5


def test_a_closed_port_as_scheduler_is_refused() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # bound, not listening: the connection is refused
        with pytest.raises(C2nError, match="no Dask scheduler answers"):
            probe_scheduler(f"tcp://127.0.0.1:{port}", timeout_s=2)


def test_replay_loop_0_is_a_usage_error_and_help_says_n_at_least_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = candump(tmp_path / "d.log", ["can0"])
    code, _, err = run_cli(["replay", str(log), "-i", "virtual", "--loop", "0"])
    assert code == 2 and "--loop: 0 is out of range: use 1 to" in err
    assert main(["replay", "--help"]) == 0
    assert "play N times, N ≥ 1 (--loop alone: until Ctrl-C)" in " ".join(capsys.readouterr().out.split())


# --- 9: replay --map -----------------------------------------------------------------------------


class FakeBus:
    def __init__(self, name: str) -> None:
        self.channel_info = name


def routed(log_channels: list[str], mapping: list[str], sent: list[str]) -> list[str]:
    buses = [FakeBus("rp1"), FakeBus("rp2")]
    router = Router(buses, ["rp1", "rp2"], mapping, log_channels)  # type: ignore[arg-type]
    return [router.bus_for(can.Message(channel=c)).channel_info for c in sent]  # type: ignore[attr-defined]


def test_an_unmapped_channel_goes_to_a_bus_no_map_names() -> None:
    # before: can0 went to the bus numbered by the routes so far, rp2, as can1 did
    assert routed(["can0", "can1"], ["can1=rp2"], ["can0", "can1", "can0"]) == ["rp1", "rp2", "rp1"]
    assert routed(["can0", "can1"], [], ["can1", "can0"]) == ["rp1", "rp2"]


def test_a_bare_number_maps_the_candump_channel_of_that_number() -> None:
    assert log_channel("1", ["can0", "can1"], "1=rp1") == "can1"
    assert log_channel("1", ["0", "1"], "1=rp1") == "1"  # a BLF's channels are numbers
    assert routed(["can0", "can1"], ["1=rp1"], ["can0", "can1"]) == ["rp2", "rp1"]


def test_a_map_naming_a_channel_the_log_lacks_is_one_line_naming_the_logs_channels(tmp_path: Path) -> None:
    log = candump(tmp_path / "d.log", ["can0", "can1"])
    channel = uuid.uuid4().hex
    code, _, err = run_cli(["replay", str(log), "-i", "virtual", "-c", channel, "--map", f"can7={channel}"])
    assert code == 1
    said = f"c2n: error: --map can7={channel}: the log has no channel can7 (its channels: can0, can1)"
    assert one_line(err) == said
    csv_log = tmp_path / "d.csv"  # python-can's CSV keeps no channel: it said `its channels: None`
    with can.Logger(csv_log) as writer:
        for message in can.LogReader(log):
            writer.on_message_received(message)
    code, _, err = run_cli(["replay", str(csv_log), "-i", "virtual", "-c", channel, "--map", f"0={channel}"])
    assert code == 1 and one_line(err) == (
        f"c2n: error: --map 0={channel}: the log keeps no channel of its frames, so none can be mapped — "
        "replay it without --map (every frame to the first -c bus)"
    )


def test_replay_with_the_readmes_map_form_sends_each_channel_where_asked(tmp_path: Path) -> None:
    log = candump(tmp_path / "d.log", ["can0", "can1"])
    a, b = uuid.uuid4().hex, uuid.uuid4().hex
    with can.Bus(interface="virtual", channel=a) as on_a, can.Bus(interface="virtual", channel=b) as on_b:
        code, _, err = run_cli(
            ["replay", str(log), "-i", "virtual", "-c", a, "-c", b, "--map", f"1={a}", "--rate", "1e6"]
        )
        assert code == 0, err
        got_a = [on_a.recv(1) for _ in range(20)]
        got_b = [on_b.recv(1) for _ in range(20)]
    assert all(m is not None for m in got_a + got_b)
    assert [m.data[0] % 2 for m in got_a if m is not None] == [1] * 20  # can1's frames: odd k
    assert [m.data[0] % 2 for m in got_b if m is not None] == [0] * 20


# --- 10: user text is never markup -------------------------------------------------------------


@pytest.mark.parametrize(
    "text, printed",
    [
        ("Pirelli [old]", "Pirelli [old]"),
        ("[/]", "[/]"),
        ("[bold]x", "[bold]x"),
        ("a\x1b[2Jb", "a\\x1b[2Jb"),
        ("", "(empty)"),
        ("(empty)", "'(empty)'"),  # a tag so named, not the blank cells' group
        ("back\\", "back\\"),
    ],
)
def test_shown_prints_user_text_literally(text: str, printed: str) -> None:
    console = Console(record=True, width=200)
    console.print(f"tag {shown(text)}.")
    assert console.export_text() == f"tag {printed}.\n"


@pytest.mark.parametrize(
    "name", ["-day.log", "--pool.log", "day [tyre change] 1.blf", "it's.log", "/tmp/-a.log"]
)
def test_a_suggested_command_takes_the_log_it_names(name: str) -> None:
    """The fixes say `c2n split <log>`: a log named `-day.log` was printed as is, and the
    command, copied, refused it (`the following arguments are required: LOG`)."""
    from app.cli import build_parser
    from app.user_text import argument

    args = build_parser().parse_args(["split", *shlex.split(argument(Path(name)))])
    assert os.path.normpath(args.log) == name


def test_simulate_to_a_path_with_brackets_prints_it_and_exits_0(tmp_path: Path) -> None:
    out = tmp_path / "d[/]x.log"
    code, printed, err = run_cli(["simulate", "--scenario", "step_steer", "--out", str(out)])
    assert code == 0, err
    assert out.exists()
    assert "d[/]x.log" in " ".join(printed.split()).replace(" ", "")


# --- 8: trends against numeric tags --------------------------------------------------------------


def test_a_trend_against_a_date_tag_matches_the_closed_form() -> None:
    x = [20261124.0, 20261125.0, 20261126.0, 20261124.0, 20261126.0]
    y = [12.0 + 0.5 * (v - 20261124.0) for v in x]  # exact: the line through every session
    fitted = trend(x, y, [0.1] * 5)
    assert fitted is not None
    assert fitted.slope == pytest.approx(0.5, rel=1e-9)
    assert fitted.intercept + fitted.slope * 20261124.0 == pytest.approx(12.0, abs=1e-6)
    # equal weights, no spread about the line: var(slope) = s²/Σ(x − x̄)², a t(k − 2) interval
    sxx = sum((v - sum(x) / 5) ** 2 for v in x)
    half = float(stdtrit(3, 0.975)) * 0.1 / math.sqrt(sxx)
    assert fitted.slope_ci95 == pytest.approx((0.5 - half, 0.5 + half), rel=1e-9)


def test_a_trend_against_tags_near_1e200_is_finite_without_a_warning() -> None:
    x = [1e200, 2e200, 3e200]
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        fitted = trend(x, [13.0, 14.0, 15.0], [0.1] * 3)
    assert fitted is not None
    assert fitted.slope == pytest.approx(1e-200) and fitted.intercept == pytest.approx(12.0)
    assert trend([-1.7e308, 0.0, 1.7e308], [13.0, 14.0, 15.0], [0.1] * 3) is not None


def test_json_never_holds_nan_a_null_and_its_reason_instead() -> None:
    nulled: list[str] = []
    assert finite({"a": [1.0, math.nan], "b": {"c": math.inf}}, "", nulled) == {
        "a": [1.0, None],
        "b": {"c": None},
    }
    assert nulled == ["a[1]", "b.c"]


# --- 13 and 15: manifests and campaign options ---------------------------------------------------


def test_a_device_in_a_manifest_is_refused_not_hashed_forever(tmp_path: Path) -> None:
    manifest = tmp_path / "m.csv"
    manifest.write_text("log,tyre_set\n/dev/zero,A\n")
    with pytest.raises(C2nError, match=r"line 2 names /dev/zero, which is no file \(a device or a pipe\)"):
        read_manifest(manifest)
    with pytest.raises(C2nError, match="not a regular file"):
        content_hash([Path("/dev/zero")])


def test_a_semicolon_separated_manifest_is_read(tmp_path: Path) -> None:
    manifest = tmp_path / "m.csv"
    manifest.write_text("log;tyre_set;pressure_kPa\nd.log;Pirelli [old];220\ne.log;;240\n")
    read = read_manifest(manifest)
    assert read.tag_names == ("tyre_set", "pressure_kPa")
    assert [e.tags["tyre_set"] for e in read.entries] == ["Pirelli [old]", ""]


@pytest.mark.parametrize("config", ["missing.toml", "broken.toml"])
def test_a_bad_campaign_config_is_one_line_before_any_work(config: str, tmp_path: Path) -> None:
    (tmp_path / "broken.toml").write_text("[vehicle\n")
    candump(tmp_path / "d.log", ["can0"])
    manifest = tmp_path / "m.csv"
    manifest.write_text("log\nd.log\n")
    code, _, err = run_cli(["campaign", str(manifest), "--config", str(tmp_path / config), "--workers", "1"])
    assert code == 1
    assert one_line(err).startswith(f"c2n: error: {tmp_path / config}")
    assert not (tmp_path / "m-campaign").exists()


def test_a_truncated_logs_warning_reaches_the_terminal() -> None:
    row = SessionRow(
        summary={"warnings": ["/x/d.log: stopped after frame 12: a damaged frame", "no yaw rate"]}
    )
    assert row.warnings_about(Path("/x/d.log")) == ["/x/d.log: stopped after frame 12: a damaged frame"]


# --- 7: one drive counted once -------------------------------------------------------------------


def small_drive(path: Path, seed: int) -> Path:
    """Two hundred frames of noise-like data, written in the format ``path``'s suffix says."""
    rng = np.random.default_rng(seed)
    with can.Logger(path) as writer:
        for k in range(200):
            data = bytes(rng.integers(0, 256, 8, dtype=np.uint8))
            t = 1.7e9 + k * 0.0013 + rng.uniform(0, 1e-4)
            writer.on_message_received(
                can.Message(timestamp=t, arbitration_id=0x7E0 + k % 3, data=data, channel=0)
            )
    return path


def test_one_drive_as_log_and_as_blf_is_one_drive_another_is_not(tmp_path: Path) -> None:
    log = small_drive(tmp_path / "a.log", 1)
    blf = small_drive(tmp_path / "a.blf", 1)
    other = small_drive(tmp_path / "b.log", 2)
    assert log.read_bytes() != blf.read_bytes()
    assert drive_identity(log).same_drive(drive_identity(blf))
    assert not drive_identity(log).same_drive(drive_identity(other))
    kept, repeats = first_of_each([log, other, blf])
    assert kept == [log, other] and repeats == [(blf, log)]


def test_a_campaigns_repeated_drive_counts_once_and_is_named(tmp_path: Path) -> None:
    a, b, c = (small_drive(tmp_path / name, 1) for name in ("a.log", "b.blf", "c.asc"))
    manifest_path = tmp_path / "m.csv"
    manifest_path.write_text("log,tyre_set\na.log,A\nb.blf,B\nc.asc,B\n")
    manifest = read_manifest(manifest_path)
    rows = [SessionRow(summary={"c2n": 15.0}, drive=drive_identity(p).text) for p in (a, b, c)]
    rows[2] = replace(rows[2], error="c.asc: no C2n")  # a row without a result is no first copy
    out, said = counted_once(manifest, rows)
    assert out[0].error is None and out[2].error == "c.asc: no C2n"
    assert said == [f"{b}: the same drive as {a} (line 2): counted once"]
    assert out[1].error == said[0]


# --- 6: drives pooled or merged must be one C2n ---------------------------------------------------


def test_holm_judges_each_pair_against_the_family_rate() -> None:
    ci = (-Z95, Z95)  # se 1
    same = [DriveResult(str(k), 0.0, ci) for k in range(3)]
    assert disagreement(same) is None
    # two drives 2.8 se apart: z = 2.8/√2 = 1.98, p = 0.0477 < 0.05 — one pair, so refused
    assert disagreement([DriveResult("a", 0.0, ci), DriveResult("b", 2.8, (2.8 - Z95, 2.8 + Z95))])
    # the same pair among three drives: three pairs, Holm's first bar is 0.05/3 — agreed
    b = DriveResult("b", 2.8, (2.8 - Z95, 2.8 + Z95))
    three = [DriveResult("a", 0.0, ci), b, DriveResult("c", 1.4, (1.4 - Z95, 1.4 + Z95))]
    assert disagreement(three) is None
    far = disagreement([*three, DriveResult("d", 20.0, (20.0 - Z95, 20.0 + Z95))])
    assert far is not None and "a and d differ" in far and "over 6 pairs" in far


@pytest.fixture(scope="module")
def two_tyre_sets(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    folder = tmp_path_factory.mktemp("tyres")
    soft, stiff = folder / "soft.blf", folder / "stiff.blf"
    write_drive(cached_drive("constant_radius", 41, 15.1), soft)
    write_drive(cached_drive("constant_radius", 43, 20.0), stiff)
    return soft, stiff


@pytest.mark.parametrize("how", ["--pool", "--merge"])
def test_sweeps_of_two_tyre_sets_are_not_pooled_or_merged(how: str, two_tyre_sets: tuple[Path, Path]) -> None:
    soft, stiff = two_tyre_sets
    code, printed, err = run_cli(["analyze", how, str(soft), str(stiff)])
    assert code == 1
    line = one_line(err)
    assert line.startswith(f"c2n: error: the drives disagree, each alone: {soft} 15.")
    assert f"{stiff} 20." in line or f"{stiff} 19." in line
    assert "C2n =" not in printed


def test_replay_map_without_channels_says_to_name_them(drive_log: Path) -> None:
    """`--map 5=can9` with no -c said `BUS one of the -c channels None`."""
    code, _, err = run_cli(["replay", str(drive_log), "-i", "virtual", "--map", "5=can9"])
    assert code == 2 and err == "c2n: error: --map 5=can9: want LOG=BUS with BUS a channel given with -c\n"
