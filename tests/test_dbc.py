"""Our DBCs (dbc/) against the real layouts they were written from (data/real/).

A frame laid out by the real DBC must decode to the same values with ours: same names, bits,
byte order, scale, offset and signedness. Every signal of the real message is randomised
(counters and checksums too), so a signal of ours that overlaps a neighbour's bits shows.
"""

import math
from functools import cache
from pathlib import Path
from typing import Any

import cantools
import numpy as np
import pytest

from app.dbc import LARGEST_DBC, load_dbc
from app.errors import DbcError
from tests.real_data import REPO_ROOT, needs_real_data, real_path

OUR_KISTLER = REPO_ROOT / "dbc" / "kistler_smotion.dbc"
OUR_FORD = REPO_ROOT / "dbc" / "vehicle_ford.dbc"
REAL_KISTLER = ("kistler-smotion-dbc", "S-Motion_Sensor.dbc")
REAL_FORD = ("opendbc-dbc", "ford_lincoln_base_pt.dbc")
# DESIGN §4: steering angle, yaw rate, lateral acceleration, wheel speeds, vehicle speed.
FORD_IDS = (0x7E, 0x91, 0x92, 0x217, 0x415)
LAYOUT = ("start", "length", "byte_order", "is_signed", "is_float", "scale", "offset")
SAMPLES = 200


@cache
def _ours(path: Path) -> Any:
    return cantools.database.load_file(path, strict=True)


@cache
def _real(parts: tuple[str, str]) -> Any:
    return cantools.database.load_file(real_path(*parts), strict=True)


def _raw_bounds(signal: Any) -> tuple[int, int]:
    """The raw integers a signal may carry: within its bit width and its [min|max]."""
    if signal.is_signed:
        low, high = -(2 ** (signal.length - 1)), 2 ** (signal.length - 1) - 1
    else:
        low, high = 0, 2**signal.length - 1
    if signal.minimum is not None and signal.maximum is not None:
        ends = sorted(
            (
                (signal.minimum - signal.offset) / signal.scale,
                (signal.maximum - signal.offset) / signal.scale,
            )
        )
        low = max(low, math.ceil(ends[0] - 1e-6))
        high = min(high, math.floor(ends[1] + 1e-6))
    assert low <= high, f"{signal.name}: empty raw range"
    return low, high


def _valid_payloads(message: Any, rng: np.random.Generator, n: int = SAMPLES) -> list[bytes]:
    """Frames encoded by ``message`` from random valid raw values of each signal (and both ends)."""
    columns = {}
    for signal in message.signals:
        low, high = _raw_bounds(signal)
        columns[signal.name] = np.concatenate(
            ([low, high], rng.integers(low, high, size=n - 2, endpoint=True))
        )
    return [
        message.encode(
            {name: int(values[i]) for name, values in columns.items()}, scaling=False, strict=False
        )
        for i in range(n)
    ]


def _random_payloads(message: Any, rng: np.random.Generator, n: int = SAMPLES) -> list[bytes]:
    """Frames of random bytes: every bit pattern, valid or not."""
    return [bytes(row) for row in rng.integers(0, 256, size=(n, message.length), dtype=np.uint8)]


def _assert_same_layout(ours: Any, real: Any) -> None:
    assert ours.name == real.name
    assert ours.length == real.length
    assert ours.is_extended_frame == real.is_extended_frame
    real_signals = {s.name: s for s in real.signals}
    missing = [s.name for s in ours.signals if s.name not in real_signals]
    assert not missing, f"0x{ours.frame_id:X} {ours.name}: signals not in the real DBC: {missing}"
    for signal in ours.signals:
        other = real_signals[signal.name]
        got = {key: getattr(signal, key) for key in LAYOUT}
        want = {key: getattr(other, key) for key in LAYOUT}
        assert got == want, f"{ours.name}.{signal.name}"


def _assert_same_decode(ours: Any, real: Any, payloads: list[bytes]) -> None:
    for data in payloads:
        want = real.decode(data, decode_choices=False, scaling=True)
        got = ours.decode(data, decode_choices=False, scaling=True)
        for signal in ours.signals:
            assert math.isclose(got[signal.name], want[signal.name], rel_tol=1e-9, abs_tol=1e-9), (
                f"{ours.name}.{signal.name}: ours {got[signal.name]!r}, "
                f"real {want[signal.name]!r} for {data.hex()}"
            )


def _kistler_ids() -> list[int]:
    return [m.frame_id for m in _ours(OUR_KISTLER).messages]


def _param_id(frame_id: int) -> str:
    return f"0x{frame_id:X}"


def test_our_dbcs_load_strict() -> None:
    """Both DBCs load with cantools strict=True, so our loader never has to relax them."""
    for path in (OUR_KISTLER, OUR_FORD):
        database = cantools.database.load_file(path, strict=True)
        assert database.messages, path
        assert not load_dbc(path).relaxed, path


def test_ford_dbc_has_the_five_messages() -> None:
    """The vehicle DBC carries exactly the messages DESIGN §4 names."""
    assert sorted(m.frame_id for m in _ours(OUR_FORD).messages) == sorted(FORD_IDS)


@needs_real_data
@pytest.mark.parametrize("frame_id", _kistler_ids(), ids=_param_id)
def test_kistler_layout_matches_real(frame_id: int) -> None:
    """Names, bits, byte order, scale, offset and signedness follow the real S-Motion DBC."""
    ours = _ours(OUR_KISTLER).get_message_by_frame_id(frame_id)
    real = _real(REAL_KISTLER).get_message_by_frame_id(frame_id)
    _assert_same_layout(ours, real)


@needs_real_data
@pytest.mark.parametrize("frame_id", _kistler_ids(), ids=_param_id)
def test_kistler_decodes_like_real(frame_id: int) -> None:
    """Frames encoded by the real S-Motion DBC, and random bytes, decode the same with ours."""
    ours = _ours(OUR_KISTLER).get_message_by_frame_id(frame_id)
    real = _real(REAL_KISTLER).get_message_by_frame_id(frame_id)
    rng = np.random.default_rng(frame_id)
    _assert_same_decode(ours, real, _valid_payloads(real, rng))
    _assert_same_decode(ours, real, _random_payloads(real, rng))


@needs_real_data
@pytest.mark.parametrize("frame_id", FORD_IDS, ids=_param_id)
def test_ford_layout_matches_real(frame_id: int) -> None:
    """Names, bits, byte order, scale, offset and signedness follow opendbc's Ford DBC."""
    ours = _ours(OUR_FORD).get_message_by_frame_id(frame_id)
    real = _real(REAL_FORD).get_message_by_frame_id(frame_id)
    _assert_same_layout(ours, real)


@needs_real_data
@pytest.mark.parametrize("frame_id", FORD_IDS, ids=_param_id)
def test_ford_decodes_like_real(frame_id: int) -> None:
    """Frames with every real signal random (counters, checksums too) decode the same with ours."""
    ours = _ours(OUR_FORD).get_message_by_frame_id(frame_id)
    real = _real(REAL_FORD).get_message_by_frame_id(frame_id)
    rng = np.random.default_rng(frame_id)
    _assert_same_decode(ours, real, _valid_payloads(real, rng))
    _assert_same_decode(ours, real, _random_payloads(real, rng))


def test_a_folder_or_a_huge_file_as_a_dbc_is_one_line_that_says_what_it_is(tmp_path: Path) -> None:
    """A folder was "not found" though it is there; a 300 MB sparse file took 3.2 GB of RAM in
    cantools before its one-line error."""
    with pytest.raises(DbcError, match=r"is a folder or a device, not a DBC file — check \[dbc\] files"):
        load_dbc(tmp_path)
    huge = tmp_path / "huge.dbc"
    with huge.open("wb") as file:
        file.truncate(LARGEST_DBC + 1)  # sparse: no disk used
    with pytest.raises(DbcError, match=r"huge.dbc: 64 MB is no DBC"):
        load_dbc(huge)
    with pytest.raises(DbcError, match=r"gone.dbc: DBC file not found"):
        load_dbc(tmp_path / "gone.dbc")
