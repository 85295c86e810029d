"""What the frames were: every frame counted by its kind, per id, per role, and the values
dropped with the reason."""

from collections import Counter
from dataclasses import dataclass, field, replace


@dataclass
class FrameCounts:
    """What the frames were. ``total`` is the sum of the kinds below it (``fd_frames`` aside)."""

    total: int = 0
    used: int = 0  # gave the pipeline a role value or a sensor status
    unused: int = 0  # a DBC message nothing in the config needs
    unknown_id: int = 0
    other_channel: int = 0  # a known id on a channel its DBC is not decoded on
    bad_length: int = 0
    undecodable: int = 0
    bad_time: int = 0  # a frame of a needed message without a usable timestamp (NaN, infinite)
    error_frames: int = 0
    remote_frames: int = 0
    fd_frames: int = 0  # not a kind: how many of the total were CAN FD (decoded like the rest)
    by_id: Counter[tuple[object, int, bool]] = field(
        default_factory=Counter
    )  # (channel, id, extended) -> frames
    bad_by_id: Counter[tuple[int, str]] = field(default_factory=Counter)  # (id, kind) -> frames
    role_frames: Counter[str] = field(default_factory=Counter)  # role -> frames carrying it
    rejected: Counter[str] = field(default_factory=Counter)  # "reason (roles)" -> frames with values dropped

    def copy(self) -> "FrameCounts":
        """A copy that later frames do not change."""
        return replace(
            self,
            by_id=Counter(self.by_id),
            bad_by_id=Counter(self.bad_by_id),
            role_frames=Counter(self.role_frames),
            rejected=Counter(self.rejected),
        )

    def as_dict(self) -> dict[str, int]:
        return {
            "total": self.total,
            "used": self.used,
            "unused": self.unused,
            "unknown_id": self.unknown_id,
            "other_channel": self.other_channel,
            "bad_length": self.bad_length,
            "undecodable": self.undecodable,
            "bad_time": self.bad_time,
            "error_frames": self.error_frames,
            "remote_frames": self.remote_frames,
            "fd_frames": self.fd_frames,
        }
