"""The hand signal readers against cantools, the reference: every signal of every message of
every DBC at hand (ours and the real third-party ones, Intel and Motorola), on random payloads,
read frame by frame and as columns of many frames (the MF4 block path)."""

from pathlib import Path
from typing import Any

import cantools
import numpy as np
import pytest

from app.decode.bits import column_reader, signal_reader
from tests.real_data import REAL_DATA, needs_real_data

OURS = sorted((Path(__file__).resolve().parent.parent / "dbc").glob("*.dbc"))
REAL = sorted(REAL_DATA.rglob("*.dbc")) if REAL_DATA is not None else []


def check_against_cantools(path: Path, frames_per_message: int = 200) -> int | None:
    """Assert the reader equals cantools for each message's signals; return how many signals
    went through the hand path (None: cantools cannot load the file at all)."""
    try:
        database: Any = cantools.database.load_file(path, strict=False)
    except cantools.database.errors.UnsupportedDatabaseFormatError:
        return None
    rng = np.random.default_rng(7)
    by_hand = 0
    by_columns = 0
    for message in database.messages:
        if message.length == 0 or not message.signals:
            continue
        names = [signal.name for signal in message.signals]
        read = signal_reader(message, names)
        hand = read.__name__ == "read"
        by_hand += len(names) if hand else 0
        payloads = rng.integers(0, 256, (frames_per_message, message.length), dtype=np.uint8)
        payloads[0], payloads[1] = 0, 255  # the extremes of every field
        columns = column_reader(message, names)
        if columns is not None:  # a wider matrix, as an MF4's 64-byte data column
            wide = np.concatenate([payloads, rng.integers(0, 256, (len(payloads), 5), np.uint8)], axis=1)
            read_columns = columns(wide)
            by_columns += len(names)
            for k, payload in enumerate(payloads):
                one = read(bytes(payload))
                assert {name: float(read_columns[name][k]) for name in names} == one, (message.name, k)
        for payload in payloads:
            data = bytes(payload)
            try:
                reference: Any = message.decode(data, decode_choices=False, scaling=True)
            except Exception:
                continue  # a multiplexer value the DBC does not define: cantools' path anyway
            values = read(data)
            for name in names:
                assert values[name] == pytest.approx(reference[name], rel=0, abs=1e-9), (
                    path.name,
                    message.name,
                    name,
                )
                assert type(values[name]) is type(reference[name]) or not hand
    assert by_columns > 0 or by_hand == 0, (path.name, "no message read as columns")
    return by_hand


@pytest.mark.parametrize("path", OURS, ids=lambda p: p.name)
def test_our_signals_read_by_hand_equal_cantools(path: Path) -> None:
    assert (check_against_cantools(path) or 0) > 0


@needs_real_data
def test_real_dbcs_read_by_hand_equal_cantools() -> None:
    assert REAL, "no DBC in the real data folder"
    by_hand = {path.name: check_against_cantools(path, frames_per_message=50) for path in REAL}
    loaded = {name: n for name, n in by_hand.items() if n is not None}
    assert len(loaded) >= 4 and all(n > 0 for n in loaded.values()), by_hand


def test_big_endian_signed_signal_closed_form() -> None:
    """A Motorola signed 12-bit field, start bit 7 (the first byte's MSB): bytes 0x80 0x10 hold
    raw 0x801 = −2047; scale 0.5, offset 1 → −1022.5."""
    dbc = """VERSION ""
BS_:
BU_: A
BO_ 100 M: 2 A
 SG_ S : 7|12@0- (0.5,1) [-2000|2000] "" A
"""
    database: Any = cantools.database.load_string(dbc, "dbc")
    message = database.get_message_by_name("M")
    assert signal_reader(message, ["S"])(bytes([0x80, 0x10])) == {"S": -1022.5}
