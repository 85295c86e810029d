"""What a bus's error frames say about its controller: bus-off, error-passive, and back again.

SocketCAN reports controller trouble as error frames whose ``arbitration_id`` holds the error
class bits of ``linux/can/error.h`` and whose ``data[1]`` details a controller problem; python-can
hands them over as they are (``is_error_frame``). ``BusHealth`` turns that stream into the few
changes worth a line in the live run: a controller that went bus-off (it stops receiving until it
is restarted), one that went error-passive (its error counters passed 128: bad termination,
wrong bitrate, a node sending garbage; it still receives), and its return (a restart or
error-active report; after bus-off, frames again).
Error frames without class bits (other interfaces) are counted by the decoder and nothing more.
"""

from dataclasses import dataclass

import can

CAN_ERR_CRTL = 0x004  # controller problem, details in data[1]
CAN_ERR_BUSOFF = 0x040
CAN_ERR_RESTARTED = 0x100  # the controller was restarted (restart-ms or `ip link set up`)
CAN_ERR_CRTL_RX_PASSIVE = 0x10
CAN_ERR_CRTL_TX_PASSIVE = 0x20
CAN_ERR_CRTL_ACTIVE = 0x40  # back to error-active

OFF = "bus-off"
PASSIVE = "error-passive"

_WHY = {
    OFF: "the controller left the bus after too many errors and receives nothing until it restarts"
    " (socketcan: `ip link set CH type can restart-ms 100` restarts it by itself)",
    PASSIVE: "its error counters passed 128 — check the termination, the bitrate and the wiring",
}


@dataclass
class _Trouble:
    state: str
    since: float


class BusHealth:
    """The controller state of each channel, from its error frames and its traffic."""

    def __init__(self) -> None:
        self.troubled: dict[str, _Trouble] = {}  # channel -> what is wrong since when

    def see(self, msg: can.Message, now: float) -> str | None:
        """Take one frame; a line to print when the channel's state changed, else None."""
        channel = str(msg.channel)
        trouble = self.troubled.get(channel)
        if not msg.is_error_frame:  # a bus-off controller receives nothing: frames mean it is back
            return (
                self._recovered(channel, trouble, now)
                if trouble is not None and trouble.state == OFF
                else None
            )
        classes = msg.arbitration_id
        detail = msg.data[1] if len(msg.data) > 1 else 0
        if classes & CAN_ERR_BUSOFF:
            state: str | None = OFF
        elif classes & CAN_ERR_RESTARTED or (classes & CAN_ERR_CRTL and detail & CAN_ERR_CRTL_ACTIVE):
            return self._recovered(channel, trouble, now) if trouble is not None else None
        elif classes & CAN_ERR_CRTL and detail & (CAN_ERR_CRTL_RX_PASSIVE | CAN_ERR_CRTL_TX_PASSIVE):
            state = PASSIVE
        else:
            state = None
        if state is None or (trouble is not None and trouble.state in (state, OFF)):
            return None  # nothing new (a passive report while off changes nothing)
        self.troubled[channel] = _Trouble(state, now)
        return f"{channel}: {state} — {_WHY[state]}; recording kept"

    def _recovered(self, channel: str, trouble: _Trouble, now: float) -> str:
        del self.troubled[channel]
        return f"{channel}: back from {trouble.state} after {now - trouble.since:.1f} s — measuring again"

    def problems(self, now: float) -> list[str]:
        """One phrase per troubled channel, for the dashboard."""
        return [
            f"{channel} {trouble.state} for {now - trouble.since:.0f} s"
            for channel, trouble in sorted(self.troubled.items())
        ]
