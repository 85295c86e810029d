"""A replay goes onto a virtual bus unless the user says otherwise: on a real one (a car's) its
frames, the vehicle speed's with the car's own ids among them, would reach every node."""

import json
import subprocess
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can
import pytest

from app.sources import bus_kind
from tests.test_reliability_inputs import run_cli
from tests.test_reliability_round3 import candump


@pytest.fixture
def opened(monkeypatch: pytest.MonkeyPatch) -> list[dict[str, Any]]:
    """Every bus the command opens, each a virtual one on a channel of its own here."""
    calls: list[dict[str, Any]] = []
    real_bus = can.Bus

    def bus(**kwargs: Any) -> can.BusABC:
        calls.append(kwargs)
        return real_bus(interface="virtual", channel=f"stand-in-{uuid.uuid4().hex}")

    monkeypatch.setattr(can, "Bus", bus)
    return calls


@pytest.fixture
def devices(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Callable[[str, str | None], None]:
    """Make a SocketCAN device of a name, with the link kind ``ip`` gives it (None: ``ip``
    cannot say)."""
    net = tmp_path / "net"
    net.mkdir()
    links: dict[str, str | None] = {}

    def add(name: str, link: str | None) -> None:
        (net / name).mkdir()
        links[name] = link

    monkeypatch.setattr(bus_kind, "_NET", net)
    monkeypatch.setattr(bus_kind, "link_kind", links.get)
    return add


def test_a_replay_onto_a_real_interface_is_refused_before_any_bus_opens(
    tmp_path: Path, opened: list[dict[str, Any]]
) -> None:
    log = candump(tmp_path / "d.log", ["can0"])
    code, _, err = run_cli(["replay", str(log), "-i", "pcan", "-c", "PCAN_USBBUS1"])
    assert code == 2
    assert err.count("\n") == 1 and "Traceback" not in err
    assert err.startswith("c2n: error: pcan PCAN_USBBUS1: is not a virtual bus")
    assert "replay onto -i socketcan -c vcan0 (a virtual SocketCAN bus), or add --real-bus" in err
    assert opened == []


def test_an_in_car_laptop_s_default_bus_is_refused_and_a_vcan_is_not(
    tmp_path: Path,
    opened: list[dict[str, Any]],
    devices: Callable[[str, str | None], None],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``c2n live`` on the car's can0 set up once (CAN_INTERFACE/CAN_CHANNEL, ~/can.conf): a
    ``c2n replay LOG`` with no -i/-c would send onto the car's bus."""
    devices("can0", "can")
    devices("vcan0", "vcan")
    monkeypatch.setenv("CAN_INTERFACE", "socketcan")
    monkeypatch.setenv("CAN_CHANNEL", "can0")
    log = candump(tmp_path / "d.log", ["can0"])
    code, _, err = run_cli(["replay", str(log), "--rate", "1e6"])
    assert code == 2 and err.startswith("c2n: error: socketcan can0: is not a virtual bus")
    assert opened == []
    code, _, err = run_cli(["replay", str(log), "-c", "vcan0", "--rate", "1e6"])
    assert code == 0, err
    assert [call.get("channel") for call in opened] == ["vcan0"]


def test_a_socketcan_bus_of_unknown_kind_or_no_channel_is_refused(
    tmp_path: Path, opened: list[dict[str, Any]], devices: Callable[[str, str | None], None]
) -> None:
    devices("slcan0", None)  # ip could not say
    log = candump(tmp_path / "d.log", ["can0"])
    code, _, err = run_cli(["replay", str(log), "-i", "socketcan", "-c", "slcan0"])
    assert code == 2
    assert "socketcan slcan0: is not known to be virtual (ip -details link show slcan0)" in err
    code, _, err = run_cli(["replay", str(log), "-i", "socketcan"])
    assert code == 2
    assert "socketcan: with no channel each frame goes to the device its log names (can0…)" in err
    assert opened == []


def test_real_bus_sends_there(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    channel = f"bench-{uuid.uuid4().hex}"
    real_bus = can.Bus
    monkeypatch.setattr(can, "Bus", lambda **kwargs: real_bus(interface="virtual", channel=channel))
    log = candump(tmp_path / "d.log", ["can0"], frames=40)
    with real_bus(interface="virtual", channel=channel) as listener:
        code, _, err = run_cli(["replay", str(log), "-i", "kvaser", "-c", "0", "--rate", "1e6", "--real-bus"])
        assert code == 0, err
        received = [listener.recv(timeout=1.0) for _ in range(40)]
    assert [m.data[0] for m in received if m is not None] == list(range(40))


def test_the_kind_of_a_bus() -> None:
    assert bus_kind.kind("virtual", "anything") == "virtual"
    assert bus_kind.kind("pcan", "PCAN_USBBUS1") == "real"
    assert bus_kind.kind("udp_multicast", "239.74.163.2") == "real"  # it leaves the machine
    assert bus_kind.kind(None, None) == "missing"  # nothing named: opening the bus says what to do
    assert bus_kind.kind("socketcan", f"nosuch{uuid.uuid4().hex[:6]}") == "missing"


@pytest.mark.parametrize(
    "stdout, expected",
    [
        ([{"ifname": "vcan0", "linkinfo": {"info_kind": "vcan"}}], "vcan"),
        (
            [{"ifname": "can0", "linkinfo": {"info_kind": "can", "info_data": {"state": "ERROR-ACTIVE"}}}],
            "can",
        ),
        ([{"ifname": "slcan0"}], ""),
    ],
)
def test_a_link_s_kind_is_read_from_ip(
    stdout: list[dict[str, Any]], expected: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    def run(argv: list[str], **kwargs: Any) -> subprocess.CompletedProcess[str]:
        assert argv[:5] == ["ip", "-details", "-json", "link", "show"]
        return subprocess.CompletedProcess(argv, 0, json.dumps(stdout), "")

    monkeypatch.setattr(subprocess, "run", run)
    assert bus_kind.link_kind(str(stdout[0]["ifname"])) == expected


def test_without_ip_a_link_s_kind_is_not_known(monkeypatch: pytest.MonkeyPatch) -> None:
    def missing(argv: list[str], **kwargs: Any) -> subprocess.CompletedProcess[str]:
        raise FileNotFoundError(2, "No such file or directory", "ip")

    monkeypatch.setattr(subprocess, "run", missing)
    assert bus_kind.link_kind("can0") is None


def test_an_interface_name_python_can_does_not_know_is_no_bus_not_a_real_one(tmp_path: Path) -> None:
    """`-i virutal` was refused as a real bus, `--real-bus` offered as the way on — the one option
    that would let the replay reach a car's ECUs once the name is put right. It is no bus at all."""
    log = candump(tmp_path / "d.log", ["can0"])
    code, _, err = run_cli(["replay", str(log), "-i", "virutal"])
    assert code == 1 and "--real-bus" not in err, err
    assert 'Unknown interface type "virutal"' in err and "check the interface name" in err
