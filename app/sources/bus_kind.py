"""Whether a bus is virtual — its frames reach only programs on this machine — or real, where
every frame sent reaches every node on the wire: a car's ECUs, a bench's loggers.

``c2n replay`` sends a drive's frames, the vehicle's speed among them, with their recorded ids.
On a car's bus they would stand beside the car's own frames of those ids; so a replay goes onto
a virtual bus unless the user says otherwise (``--real-bus``). The bus is the one python-can
would open: ``-i``/``-c`` where given, else its config file and ``CAN_INTERFACE``/``CAN_CHANNEL``
— an in-car laptop's ``~/can.conf`` naming ``can0`` for ``c2n live`` is the case in point.
"""

import json
import subprocess
from pathlib import Path
from typing import Literal

# python-can's interface whose buses live in this process only
_VIRTUAL_INTERFACES = frozenset({"virtual"})
# SocketCAN's virtual link kinds (ip -details link: linkinfo's info_kind): vcan, and vxcan's
# tunnel between two network namespaces of this machine
_VIRTUAL_LINKS = frozenset({"vcan", "vxcan"})
_NET = Path("/sys/class/net")
_IP_TIMEOUT_S = 5.0

Kind = Literal["virtual", "real", "unknown", "missing"]


def resolved(interface: str | None, channel: str | int | None) -> tuple[str | None, str | int | None]:
    """The interface and channel python-can would open for these options (its config file and
    environment filling what is not given); as given where python-can cannot resolve them (its
    own error, when the bus is opened, says why)."""
    import can

    given: dict[str, object] = {}
    if interface is not None:
        given["interface"] = interface
    if channel is not None:
        given["channel"] = channel
    try:
        config = can.util.load_config(config=given)
    except Exception:  # an unknown interface: opening the bus says so
        return interface, channel
    return config.get("interface"), config.get("channel")


def _known_interfaces() -> frozenset[str]:
    """python-can's interface names (its own and its plugins'): a typo (``virutal``) is no bus
    at all, and was refused as a real one, with ``--real-bus`` offered as the way on."""
    import can.interfaces

    return frozenset(can.interfaces.VALID_INTERFACES)


def kind(interface: str | None, channel: str | int | None) -> Kind:
    """``virtual``, ``real``, ``unknown`` (a SocketCAN link whose kind ``ip`` could not tell), or
    ``missing`` (no interface named anywhere, no such SocketCAN device: opening it fails with its
    own hint)."""
    if interface is None or interface not in _known_interfaces():  # opening it: "Unknown interface type"
        return "missing"
    if interface in _VIRTUAL_INTERFACES:
        return "virtual"
    if interface != "socketcan":
        return "real"
    if channel is None or channel == "":  # bound to every device: each frame sent to its own channel's
        return "unknown"
    name = str(channel)
    if not (_NET / name).exists():
        return "missing"
    link = link_kind(name)
    if link is None:
        return "unknown"
    return "virtual" if link in _VIRTUAL_LINKS else "real"


def link_kind(name: str) -> str | None:
    """A SocketCAN device's link kind as ``ip -details -json link show`` gives it (``can`` for a
    controller, ``vcan``…; ``""`` where it has none, as slcan's), or None where ``ip`` cannot say."""
    try:
        done = subprocess.run(
            ["ip", "-details", "-json", "link", "show", "dev", name],
            capture_output=True,
            text=True,
            timeout=_IP_TIMEOUT_S,
            check=True,
        )
        links = json.loads(done.stdout)
        info = links[0].get("linkinfo", {})
        return str(info.get("info_kind", ""))
    except (OSError, subprocess.SubprocessError, ValueError, IndexError, AttributeError):
        return None
