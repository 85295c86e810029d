"""Decoding: every frame counted by kind, roles in SI units, sensor-status gating."""

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import can
import pytest

from app.config import Config, load_config
from app.decode import decoder as decode
from app.decode.decoder import Decoder

T0 = 1000.0


def frame(config: Config, name: str, t: float = T0, channel: object = 0, **values: float) -> can.Message:
    for dbc in config.dbcs:
        for message in dbc.database.messages:
            if message.name == name:
                full = {s.name: 0.0 for s in message.signals} | values
                return can.Message(
                    timestamp=t,
                    arbitration_id=message.frame_id,
                    data=message.encode(full),
                    channel=channel,
                    is_extended_id=False,
                )
    raise KeyError(name)


def status(config: Config, t: float = T0, **values: float) -> can.Message:
    return frame(
        config,
        "Status",
        t,
        HeadStatus=values.get("HeadStatus", 1),
        TemperatureOK=values.get("TemperatureOK", 1),
        AngleSwitchedOff=values.get("AngleSwitchedOff", 0),
    )


def test_roles_in_si_units(config: Config) -> None:
    decoder = Decoder(config)
    decoder.decode(status(config))
    rec = decoder.decode(frame(config, "Correvit", VelX_cor=45.0, VelY_cor=-0.36, Angle_cor=-0.46))
    assert rec is not None
    assert rec.signals["vx"] == pytest.approx(12.5)
    assert rec.signals["vy"] == pytest.approx(-0.1)
    assert rec.signals["beta"] == pytest.approx(math.radians(-0.46))
    rec = decoder.decode(frame(config, "BrakeSysFeatures", Veh_V_ActlBrk=46.0))
    assert rec is not None and rec.signals == {"speed": pytest.approx(46 / 3.6)}
    rec = decoder.decode(frame(config, "AngVelHor", AngVelZ_hor=-8.0))
    assert rec is not None and rec.signals["yaw_rate"] == pytest.approx(math.radians(-8.0))


def test_every_frame_is_counted_by_kind(config: Config) -> None:
    decoder = Decoder(config)
    good = frame(config, "Correvit", VelX_cor=40.0)
    messages = [
        status(config),
        good,
        can.Message(timestamp=T0, arbitration_id=0x123, is_extended_id=False, data=bytes(8)),  # unknown id
        can.Message(timestamp=T0, arbitration_id=0x7E5, is_extended_id=False, data=bytes(5)),  # short
        can.Message(
            timestamp=T0, arbitration_id=0x7E4, is_extended_id=False, data=bytes(8)
        ),  # long (AngVelHor has 6)
        can.Message(timestamp=T0, arbitration_id=0x7E5, is_extended_id=False, is_error_frame=True),
        can.Message(timestamp=T0, arbitration_id=0x7E5, is_extended_id=False, is_remote_frame=True, dlc=8),
        can.Message(
            timestamp=T0, arbitration_id=0x7E5, is_extended_id=True, data=bytes(8)
        ),  # 29-bit: another frame
        frame(config, "Coordinates"),  # known, nothing needs it
        can.Message(  # no place in time (a text log's "nan")
            timestamp=float("nan"),
            arbitration_id=good.arbitration_id,
            is_extended_id=good.is_extended_id,
            data=good.data,
            channel=good.channel,
        ),
    ]
    for m in messages:
        decoder.decode(m)
    counts = decoder.counts.as_dict()
    assert counts == {
        "total": 10,
        "used": 2,
        "unused": 1,
        "unknown_id": 2,
        "other_channel": 0,
        "bad_length": 2,
        "undecodable": 0,
        "bad_time": 1,
        "error_frames": 1,
        "remote_frames": 1,
        "fd_frames": 0,
    }
    assert sum(v for k, v in counts.items() if k not in ("total", "fd_frames")) == counts["total"]
    assert decoder.counts.bad_by_id == {(0x7E5, "short"): 1, (0x7E4, "long"): 1}
    by_id = decoder.counts.by_id
    assert (
        by_id[(0, 0x7E5, False)] == 2 and by_id[(None, 0x7E5, False)] == 3 and by_id[(None, 0x7E5, True)] == 1
    )


def test_counts_are_exact_at_every_read_when_frames_of_a_key_repeat(
    config: Config, monkeypatch: pytest.MonkeyPatch
) -> None:
    """After a key's first frame its frames are tallied and added to the counts when they are
    read: reading after every frame and reading once at the end give three times one pass's
    counts, for every kind of frame, CAN FD ones, and past the number of keys tallied."""
    monkeypatch.setattr(decode, "_MAX_SEEN", 6)  # the last keys below are counted one by one
    messages = [
        status(config),
        frame(config, "Correvit", VelX_cor=40.0),
        can.Message(  # VelX_cor beyond the DBC's range: rejected, still used
            timestamp=T0, arbitration_id=0x7E5, is_extended_id=False, data=b"\xff\x7f" + bytes(6), channel=0
        ),
        can.Message(timestamp=T0, arbitration_id=0x7E5, is_extended_id=False, data=bytes(5)),  # short
        can.Message(timestamp=T0, arbitration_id=0x7E5, is_extended_id=False, is_error_frame=True),
        can.Message(timestamp=T0, arbitration_id=0x7E5, is_extended_id=False, is_remote_frame=True, dlc=8),
        can.Message(timestamp=T0, arbitration_id=0x123, is_extended_id=False, data=bytes(8)),  # unknown id
        can.Message(timestamp=T0, arbitration_id=0x123, is_extended_id=False, is_fd=True, data=bytes(12)),
        frame(config, "Coordinates"),  # known, nothing needs it
        frame(config, "BrakeSysFeatures", channel=1, Veh_V_ActlBrk=40.0),
    ]
    messages += [can.Message(timestamp=T0, arbitration_id=0x200 + k, data=bytes(8)) for k in range(8)]
    once, every_frame, at_the_end = Decoder(config), Decoder(config), Decoder(config)
    for m in messages:
        once.decode(m)
    for _ in range(3):
        for m in messages:
            every_frame.decode(m)
            every_frame.counts  # noqa: B018  # a read adds the tallies
            at_the_end.decode(m)
    one = once.counts
    assert one.as_dict() == {
        "total": 18,
        "used": 4,
        "unused": 1,
        "unknown_id": 10,
        "other_channel": 0,
        "bad_length": 1,
        "undecodable": 0,
        "bad_time": 0,
        "error_frames": 1,
        "remote_frames": 1,
        "fd_frames": 1,
    }
    for decoder in (every_frame, at_the_end):
        counts = decoder.counts
        assert counts.as_dict() == {kind: 3 * n for kind, n in one.as_dict().items()}
        for field in ("by_id", "role_frames", "rejected", "bad_by_id"):
            assert getattr(counts, field) == {k: 3 * n for k, n in getattr(one, field).items()}, field


@pytest.mark.parametrize(
    ("status_values", "reason"),
    [
        ({"HeadStatus": 0}, "Status.HeadStatus=0 (needs 1)"),
        ({"TemperatureOK": 0}, "Status.TemperatureOK=0 (needs 1)"),
    ],
)
def test_bad_sensor_status_drops_optical_values(
    config: Config, status_values: dict[str, float], reason: str
) -> None:
    decoder = Decoder(config)
    decoder.decode(status(config, **status_values))
    rec = decoder.decode(frame(config, "Correvit", VelX_cor=40.0, VelY_cor=0.1))
    assert rec is not None
    assert rec.signals == {}
    assert rec.rejected == {"vx": reason, "vy": reason, "beta": reason}
    # the vehicle's own frames are not gated by the optical sensor's status
    rec = decoder.decode(frame(config, "BrakeSysFeatures", Veh_V_ActlBrk=40.0))
    assert rec is not None and "speed" in rec.signals
    assert decoder.counts.rejected == {f"{reason} (vx, vy, beta)": 1}


def test_angle_switched_off_drops_only_beta(config: Config) -> None:
    decoder = Decoder(config)
    decoder.decode(status(config, AngleSwitchedOff=1))
    rec = decoder.decode(frame(config, "Correvit", VelX_cor=4.0, Angle_cor=0.0))
    assert rec is not None
    assert set(rec.signals) == {"vx", "vy"}
    assert rec.rejected == {"beta": "Status.AngleSwitchedOff=1 (needs 0)"}


def test_no_status_yet_and_stale_status(config: Config) -> None:
    decoder = Decoder(config)
    rec = decoder.decode(frame(config, "Correvit", VelX_cor=40.0))
    assert rec is not None and rec.rejected["vx"] == "no sensor status yet"
    decoder.decode(status(config, t=T0))
    rec = decoder.decode(frame(config, "Correvit", t=T0 + 0.5, VelX_cor=40.0))
    assert rec is not None and "vx" in rec.signals
    rec = decoder.decode(frame(config, "Correvit", t=T0 + 3.0, VelX_cor=40.0))
    assert rec is not None and rec.rejected["vx"] == "sensor status older than 1 s"


def test_out_of_range_values_are_dropped(config: Config) -> None:
    decoder = Decoder(config)
    decoder.decode(status(config))
    message = config.dbcs[0].database.get_message_by_name("Correvit")
    data = message.encode({"VelX_cor": 0, "VelY_cor": 0, "Vel_cor": 0, "Angle_cor": 0})
    raw = bytearray(data)
    raw[2:4] = (32000).to_bytes(2, "little", signed=True)  # VelY 1152 km/h: outside the DBC's ±100
    rec = decoder.decode(
        can.Message(timestamp=T0, arbitration_id=0x7E5, is_extended_id=False, data=bytes(raw))
    )
    assert rec is not None and rec.rejected == {"vy": "out of range"}


CHANNELS = """
[vehicle]
sensor_ahead_of_rear_axle_m = 1.11
[dbc]
files = ["{dbc}/kistler_smotion.dbc", "{dbc}/vehicle_ford.dbc"]
[roles]
vx = "Correvit.VelX_cor"
vy = "Correvit.VelY_cor"
speed = "BrakeSysFeatures.Veh_V_ActlBrk"
[channels]
"{dbc}/kistler_smotion.dbc" = "can1"
"{dbc}/vehicle_ford.dbc" = 0
"""


def test_channels_keep_a_vehicle_bus_obd_id_out_of_the_sensor(write_config: Callable[[str], Path]) -> None:
    """0x7E5 is also an OBD request id: on the vehicle bus it must not decode as the sensor."""
    config = load_config(write_config(CHANNELS))
    decoder = Decoder(config)
    sensor = frame(config, "Correvit", channel="can1", VelX_cor=40.0)
    obd = can.Message(
        timestamp=T0,
        arbitration_id=0x7E5,
        is_extended_id=False,
        data=bytes.fromhex("0201050000000000"),
        channel="can0",
    )
    vehicle = frame(config, "BrakeSysFeatures", channel=0, Veh_V_ActlBrk=40.0)
    assert decoder.decode(sensor) is not None
    assert decoder.decode(obd) is None
    assert decoder.decode(vehicle) is not None
    assert decoder.counts.other_channel == 1
    assert decoder.counts.role_frames == {"vx": 1, "vy": 1, "speed": 1}


def test_channel_matching_rules() -> None:
    from app.dbc import channel_matches

    cases: list[tuple[Any, Any, bool]] = [
        (None, "anything", True),
        ("can1", "can1", True),
        ("can1", 1, True),
        (1, "can1", True),
        (1, 1, True),
        (1, "vcan1", True),
        (2, 1, False),
        ("can1", "can0", False),
        ("can1", "vcan1", False),
        (1, None, False),
    ]
    for spec, channel, expected in cases:
        assert channel_matches(spec, channel) is expected, (spec, channel)


def test_a_role_can_name_its_own_channel(write_config: Callable[[str], Path]) -> None:
    """The sensor's yaw rate taken only from the sensor's channel, its velocities from anywhere."""
    text = CHANNELS.replace("[channels]", "[ignored]").split("[ignored]")[0]
    text += 'yaw_rate = {signal = "AngVelHor.AngVelZ_hor", channel = "can1"}\n'
    config = load_config(write_config(text))
    decoder = Decoder(config)
    decoder.decode(status(config))
    assert decoder.decode(frame(config, "AngVelHor", channel="can0", AngVelZ_hor=5.0)) is None
    rec = decoder.decode(frame(config, "AngVelHor", channel="can1", AngVelZ_hor=5.0))
    assert rec is not None and rec.signals["yaw_rate"] == pytest.approx(math.radians(5.0))
    assert decoder.counts.role_frames["yaw_rate"] == 1
    counts = decoder.counts
    assert (counts.other_channel, counts.used, counts.unused) == (
        1,
        1,
        1,
    )  # no [sensor_status]: Status unused
