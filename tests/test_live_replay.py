"""Live and offline are one pipeline: a drive replayed over a python-can virtual bus gives the same
crossings as the offline analysis of its log file."""

import itertools
import threading
import time
import uuid
from collections.abc import Callable, Iterator
from pathlib import Path

import can
import pytest

from app.cli import main
from app.cli.demo import Player
from app.config import Config, load_config
from app.pipeline import Pipeline
from app.run_loop import run
from app.sim.simulated_drive import write_drive
from app.sinks import summary
from app.sources.buses import BusSource
from app.sources.logs import LogSource
from tests.simulated import EventLog, cached_drive


def offline(config: Config, log: Path) -> Pipeline:
    pipeline = Pipeline(config)
    run(LogSource([log]), pipeline)
    return pipeline


def test_virtual_bus_replay_equals_analyze(
    config: Config, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    drive = cached_drive("constant_radius", 31, 15.2)
    log = tmp_path / "drive.blf"
    write_drive(drive, log)
    channel = f"test-{uuid.uuid4().hex}"
    printed = EventLog()
    with (
        can.Bus(interface="virtual", channel=channel, preserve_timestamps=True) as tx,
        can.Bus(interface="virtual", channel=channel) as rx,
    ):
        stop = threading.Event()
        player = Player(log, tx, rate=1e6, stop=stop)  # the player thread sends the drive
        live = Pipeline(config)
        player.start()
        completed = run(BusSource([rx], stop, finished=player.finished), live, [printed])
        player.join()
    assert completed and player.error is None and player.sent == len(drive.messages)
    assert live.decoder.counts.total == len(drive.messages)
    reference = offline(config, log)
    assert len(live.state.crossings) == 4
    assert live.state.crossings == reference.state.crossings  # exactly, float for float
    assert [
        e for e in printed.events if type(e).__name__ == "Crossing"
    ] == live.state.crossings  # printed as they came

    # and the CLI's JSON says the same
    assert main(["analyze", str(log), "--json", str(tmp_path / "offline.json")]) == 0
    import json

    cli = json.loads((tmp_path / "offline.json").read_text())
    assert cli["crossings"] == summary.build(live.snapshot(), config, [str(log)]).to_json()["crossings"]


SEPARATE = """
[vehicle]
sensor_ahead_of_rear_axle_m = 1.11
[dbc]
files = ["{dbc}/kistler_smotion.dbc", "{dbc}/vehicle_ford.dbc"]
[roles]
vx = "Correvit.VelX_cor"
vy = "Correvit.VelY_cor"
yaw_rate = "AngVelHor.AngVelZ_hor"
speed = "BrakeSysFeatures.Veh_V_ActlBrk"
[channels]
"{dbc}/kistler_smotion.dbc" = "SENSOR"
"{dbc}/vehicle_ford.dbc" = "VEHICLE"
"""


def test_two_live_channels_kept_apart(write_config: Callable[[str], Path]) -> None:
    """The sensor on a channel of its own and the vehicle bus on another, read at once; an OBD
    request on the vehicle bus with a sensor id is not taken for the sensor."""
    tag = uuid.uuid4().hex
    config = load_config(
        write_config(SEPARATE.replace("SENSOR", f"sensor-{tag}").replace("VEHICLE", f"vehicle-{tag}"))
    )
    drive = cached_drive("constant_radius", 32, 14.4)
    sensor_ids = {m.frame_id for m in config.dbcs[0].database.messages}
    with (
        can.Bus(interface="virtual", channel=f"sensor-{tag}") as sensor_rx,
        can.Bus(interface="virtual", channel=f"vehicle-{tag}") as vehicle_rx,
        can.Bus(interface="virtual", channel=f"sensor-{tag}", preserve_timestamps=True) as sensor_tx,
        can.Bus(interface="virtual", channel=f"vehicle-{tag}", preserve_timestamps=True) as vehicle_tx,
    ):
        finished, stop = threading.Event(), threading.Event()
        pipeline = Pipeline(config)

        def play() -> None:
            for m in drive.messages[:20000]:
                (sensor_tx if m.arbitration_id in sensor_ids else vehicle_tx).send(m)
            obd = can.Message(
                timestamp=drive.messages[20000].timestamp,
                arbitration_id=0x7E5,
                is_extended_id=False,
                data=bytes.fromhex("0201050000000000"),
            )
            vehicle_tx.send(obd)
            finished.set()

        player = threading.Thread(target=play)
        player.start()
        run(BusSource([sensor_rx, vehicle_rx], stop, finished=finished), pipeline)
        player.join()
    counts = pipeline.decoder.counts
    assert counts.total == 20001
    assert counts.other_channel == 1
    assert counts.role_frames["vx"] > 0 and counts.role_frames["speed"] > 0
    assert {str(channel) for channel, _, _ in counts.by_id} == {f"sensor-{tag}", f"vehicle-{tag}"}


def test_the_dashboard_is_drawn_on_a_terminal_and_the_interpreter_left_as_it_was(config: Config) -> None:
    """On a terminal, rich's refresh thread draws the pictures the loop takes of the dashboard;
    the thread switch interval is shortened while it draws and given back at the end."""
    import io
    import sys

    from rich.console import Console

    from app.sinks.dashboard import Dashboard

    out = io.StringIO()
    console = Console(file=out, force_terminal=True, width=120, height=60)
    pipeline = Pipeline(config)
    switch_s = sys.getswitchinterval()
    seen: list[float] = []

    def frames() -> Iterator[can.Message]:
        for message in cached_drive().messages:
            seen.append(sys.getswitchinterval())
            yield message

    run(frames(), pipeline, display=Dashboard("vcan9"), console=console, refresh_s=0.01)
    assert max(seen) < switch_s  # shortened while the dashboard was up
    assert sys.getswitchinterval() == switch_s
    text = out.getvalue()
    assert "c2n live — vcan9" in text and "Correvit" in text
    assert f"total {pipeline.decoder.counts.total}" in text  # the last picture is of the end


def test_live_at_the_replays_rate_measures_what_analyze_gives(tmp_path: Path) -> None:
    """``c2n replay --rate 10`` into a separate ``c2n live --rate 10`` (one process, a virtual bus
    that stamps arrival time as SocketCAN does): the sweeps are taken as driven, and the result is
    what ``c2n analyze`` gives the log; the recording holds the drive's own time."""
    import json

    drive = cached_drive("constant_radius", 31, 15.2)
    log = tmp_path / "drive.blf"
    write_drive(drive, log)
    duration = drive.messages[-1].timestamp - drive.messages[0].timestamp
    channel = f"test-{uuid.uuid4().hex}"

    def replay() -> None:
        threading.Event().wait(0.5)  # the live side opens its bus first
        main(["replay", str(log), "-i", "virtual", "-c", channel, "--rate", "10"])

    sender = threading.Thread(target=replay)
    sender.start()
    live_json, record = tmp_path / "live.json", tmp_path / "sessions"
    argv = ["live", "-i", "virtual", "-c", channel, "--rate", "10", "--record", str(record)]
    code = main([*argv, "--json", str(live_json), "--duration", f"{duration / 10 + 2.5:.1f}"])
    sender.join()
    assert code == 0
    main(["analyze", str(log), "--json", str(tmp_path / "offline.json")])
    live, offline = (json.loads(p.read_text()) for p in (live_json, tmp_path / "offline.json"))
    assert live["frames"]["used"] == offline["frames"]["used"]
    assert len(live["crossings"]) == len(offline["crossings"]) == 4
    assert live["c2n"] == pytest.approx(offline["c2n"], rel=0.005)
    assert not any("faster than a sensor" in w for w in live["warnings"])
    [session] = record.iterdir()
    recorded = [m.timestamp for m in can.LogReader(session / "frames.log")]
    assert recorded[-1] - recorded[0] == pytest.approx(duration, rel=0.02)


def test_a_drive_taken_ten_times_too_fast_is_said_to_be_a_replay(tmp_path: Path) -> None:
    """Frame times squeezed ×10 (a replay taken at arrival time): the optical frames come at
    500 Hz instead of 50, and the run says why no sweep is usable and what to give it."""
    import json

    drive = cached_drive("constant_radius", 31, 15.2)
    log = tmp_path / "fast.blf"
    with can.Logger(log) as writer:
        start = drive.messages[0].timestamp
        for m in drive.messages:
            writer.on_message_received(
                can.Message(
                    timestamp=start + (m.timestamp - start) / 10,
                    arbitration_id=m.arbitration_id,
                    is_extended_id=m.is_extended_id,
                    data=m.data,
                    channel=m.channel,
                )
            )
    main(["analyze", str(log), "--json", str(tmp_path / "fast.json")])
    warnings = json.loads((tmp_path / "fast.json").read_text())["warnings"]
    hint = next(w for w in warnings if "faster than a sensor sends them" in w)
    assert 480 <= float(hint.split("arrive at ")[1].split(" Hz")[0]) <= 520  # 50 Hz × 10
    assert "--rate" in hint


class _Endless(can.BusABC):
    """A bus that always holds one more frame: faster than any reader."""

    def __init__(self, channel: str) -> None:
        super().__init__(channel=channel)
        self.channel_info = channel

    def _recv_internal(self, timeout: float | None) -> tuple[can.Message, bool]:
        return can.Message(arbitration_id=0x300, timestamp=time.time()), False

    def send(self, msg: can.Message, timeout: float | None = None) -> None:
        pass


@pytest.mark.parametrize("buses", [1, 2])
def test_a_bus_faster_than_the_reader_ends_the_stop_and_says_what_is_unread(
    buses: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A stop reads what waits until the buses are empty; a bus that never is (it sends faster
    than c2n reads) ends it after ``_DRAIN_S``, and the session's losses say the frames it still
    held are not in it (they were dropped without a word)."""
    monkeypatch.setattr("app.sources.buses._DRAIN_S", 0.5)
    stop = threading.Event()
    source = BusSource([_Endless(f"endless-{i}") for i in range(buses)], stop)
    started = time.monotonic()
    read = 0
    for msg in source:
        read += msg is not None
        stop.set()
    assert time.monotonic() - started < 0.5 + 2.0  # the receive threads' 1-s stop, slack
    assert read > 100  # it read on after the stop
    [lost] = source.losses
    assert "faster than c2n reads" in lost and "not in the session" in lost


@pytest.mark.parametrize("step_s", [0.0, 0.01])
def test_a_stop_that_reads_for_long_says_so_once(step_s: float) -> None:
    """A reader far behind its bus reads for seconds after Ctrl-C: past a second it says, once,
    that it is stopping and how to end at once — a user who sees nothing happen presses Ctrl-C
    again and loses what waits. A stop read in a moment says nothing. (The clock moves ``step_s``
    at each look: 3000 frames read are 30 s of a far-behind reader, or none.)"""
    channel = f"saying-{uuid.uuid4().hex}"
    receiver = can.Bus(interface="virtual", channel=channel)
    sender = can.Bus(interface="virtual", channel=channel)
    ticks = itertools.count()
    said: list[str] = []
    try:
        for i in range(3000):
            sender.send(can.Message(arbitration_id=0x100, data=i.to_bytes(2, "big")))
        stop = threading.Event()
        source = BusSource([receiver], stop, clock=lambda: next(ticks) * step_s, on_change=said.append)
        seen = 0
        for msg in source:
            if msg is not None:
                seen += 1
                stop.set()
    finally:
        receiver.shutdown()
        sender.shutdown()
    assert seen == 3000
    if step_s:
        [line] = said
        assert line.startswith("stopping: reading the frames that arrived before the stop")
        assert "Ctrl-C again ends the session now, without them" in line
    else:
        assert said == []


@pytest.mark.parametrize("buses", [1, 2])
def test_a_stop_keeps_the_frames_that_arrived_before_it(buses: int, monkeypatch: pytest.MonkeyPatch) -> None:
    """A reader behind its bus (a loaded laptop) holds frames that arrived before the stop: Ctrl-C
    or --duration's end gives them all, from one bus read in this thread and from two read by
    receive threads, then ends — and a bus that goes on sending after the stop ends it within
    ``_DRAIN_S`` (shortened here), not never."""
    monkeypatch.setattr("app.sources.buses._DRAIN_S", 1.0)
    channels = [f"backlog-{uuid.uuid4().hex}" for _ in range(buses)]
    receivers = [can.Bus(interface="virtual", channel=c) for c in channels]
    senders = [can.Bus(interface="virtual", channel=c) for c in channels]
    try:
        for i in range(3000):
            senders[i % buses].send(can.Message(arbitration_id=0x100 + i % buses, data=i.to_bytes(2, "big")))
        stop = threading.Event()
        seen = []
        for msg in BusSource(receivers, stop):
            if msg is not None:
                seen.append(int.from_bytes(msg.data, "big"))
                stop.set()  # at the first frame: 2999 wait unread
        assert sorted(seen) == list(range(3000))
        flooding = threading.Event()

        def flood() -> None:
            while not flooding.is_set():
                senders[0].send(can.Message(arbitration_id=0x200))

        sender = threading.Thread(target=flood)
        sender.start()
        stop = threading.Event()
        started = time.monotonic()
        try:
            for _ in BusSource(receivers, stop):
                stop.set()
        finally:
            flooding.set()
            sender.join()
        assert time.monotonic() - started < 1.0 + 2.0  # the receive threads' 1-s stop, slack
    finally:
        for bus in receivers + senders:
            bus.shutdown()
