"""Reading the few signals a frame is needed for, straight from its bits.

cantools decodes every signal of a message through layers of Python; a frame of the optical
sensor is needed for one or two of them, and on a saturated bus that decoding is a third of the
live loop's time (tools/bench.py). A plain integer signal — little- or big-endian, signed or
not, linearly scaled, not multiplexed — is a shift, a mask and a multiply, done here. Anything
else (floats, multiplexed messages, choices) goes through cantools. tests/test_signal_reader.py
holds these equal to cantools' own decoding over every such signal of every DBC at hand.

The reader of a message is written out as one expression per signal and compiled, as
``collections.namedtuple`` and ``dataclasses`` write their methods: a loop over the signals'
layouts costs twice as much per frame (tools/bench.py, ``decode, relevant frame``).
"""

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

Reader = Callable[[bytes | bytearray], dict[str, float]]
ColumnReader = Callable[[np.ndarray], dict[str, np.ndarray]]
_EXACT_BITS = 53  # a raw value this long is a float64 exactly, as Python's int * float makes it


def signal_reader(message: Any, names: Sequence[str]) -> Reader:
    """A function from a frame's data (of the message's length) to {name: scaled value} for the
    named signals of a cantools message: the hand path where every named signal allows it,
    else cantools' decode."""
    signals = [message.get_signal_by_name(name) for name in names]
    if message.is_multiplexed() or not all(_plain(signal) for signal in signals):
        return lambda data: _cantools_values(message, data, names)
    size = message.length
    namespace: dict[str, Any] = {}
    items = []
    for k, signal in enumerate(signals):
        shift, mask, sign = _layout(signal, size)
        order = "little" if signal.byte_order == "little_endian" else "big"
        raw = f"({order} >> {shift}) & {mask}"
        if sign:  # two's complement: flipping the sign bit and taking it away extends it
            raw = f"(({raw}) ^ {sign}) - {sign}"
        namespace[f"scale{k}"], namespace[f"offset{k}"] = signal.scale, signal.offset
        items.append(f"{signal.name!r}: ({raw}) * scale{k} + offset{k}")
    orders = sorted({"little" if s.byte_order == "little_endian" else "big" for s in signals})
    source = "\n".join(
        ["def read(data):"]
        + [f"    {order} = int.from_bytes(data, {order!r})" for order in orders]
        + ["    return {" + ", ".join(items) + "}"]
    )
    exec(compile(source, f"<signal reader of {message.name}>", "exec"), namespace)
    read: Reader = namespace["read"]
    return read


def column_reader(message: Any, names: Sequence[str]) -> ColumnReader | None:
    """The named signals of many frames at once: from a byte matrix (a row per frame, at least
    the message's length wide) to {name: float64 column}, each value what ``signal_reader``
    gives for that frame. None where the message needs cantools or is longer than 8 bytes."""
    signals = [message.get_signal_by_name(name) for name in names]
    size = message.length
    if message.is_multiplexed() or size > 8 or not all(_plain(s) for s in signals):
        return None
    if any(signal.length > _EXACT_BITS for signal in signals):
        return None
    layouts = [(s.name, s.byte_order == "little_endian", *_layout(s, size)) for s in signals]
    scales = [(signal.scale, signal.offset) for signal in signals]

    def read(data: np.ndarray) -> dict[str, np.ndarray]:
        words: dict[bool, np.ndarray] = {}
        for little in {layout[1] for layout in layouts}:
            padded = np.zeros((len(data), 8), np.uint8)  # the frame as one 64-bit integer
            if little:
                padded[:, :size] = data[:, :size]
            else:
                padded[:, 8 - size :] = data[:, :size]
            words[little] = padded.view("<u8" if little else ">u8")[:, 0].astype(np.int64)
        values = {}
        for (name, little, shift, mask, sign), (scale, offset) in zip(layouts, scales, strict=True):
            raw = (words[little] >> shift) & mask
            if sign:
                raw = (raw ^ sign) - sign
            values[name] = raw.astype(np.float64) * scale + offset
        return values

    return read


def _plain(signal: Any) -> bool:
    return not signal.is_float and not signal.is_multiplexer and signal.multiplexer_ids is None


def _layout(signal: Any, size: int) -> tuple[int, int, int]:
    """(shift, mask, sign bit or 0) of a signal in a frame of ``size`` bytes read as one integer
    in the signal's byte order."""
    length = signal.length
    if signal.byte_order == "little_endian":
        shift = signal.start
    else:  # Motorola: DBC's start bit is the most significant bit, numbered 7..0 within a byte
        msb = 8 * (signal.start // 8) + 7 - signal.start % 8  # counted from the first byte's MSB
        shift = 8 * size - msb - length
    sign = 1 << (length - 1) if signal.is_signed else 0
    return shift, (1 << length) - 1, sign


def _cantools_values(message: Any, data: bytes | bytearray, names: Sequence[str]) -> dict[str, float]:
    decoded = message.decode(bytes(data), decode_choices=False, scaling=True)
    return {name: decoded[name] for name in names}
