"""Channel files of ``c2n export``: the trace's columns with their units, in the formats people
open — CSV (a spreadsheet), Parquet (pandas, polars, Spark) and MF4 (asammdf's GUI, CANape,
DIAdem).

CSV and Parquet are written with pyarrow (fast, columnar; NaN becomes an empty cell / null), MF4
with asammdf: one channel group on the trace's time base, each channel named, unit-tagged and
commented. Both are optional extras (``LIBRARIES``), imported when a file is written.
"""

import datetime
from collections.abc import Callable
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from app import __version__
from app.errors import need
from app.output.csv_dialects import CSV_DIALECTS
from app.output.files import write_atomically
from app.sinks.trace import TIME, Trace

FORMATS = ("csv", "parquet", "mf4")
# the library each format is written with (the extra EXTRA installs them), and the format's name
LIBRARIES = {"csv": ("pyarrow", "CSV"), "parquet": ("pyarrow", "Parquet"), "mf4": ("asammdf", "MF4")}
EXTRA = "export"


def need_writers(formats: tuple[str, ...]) -> None:
    """The libraries of these formats, or one line saying how to install the one missing."""
    for fmt in formats:
        library, name = LIBRARIES[fmt]
        need(library, f"writing {name} channels", EXTRA)


def csv_header(name: str, unit: str) -> str:
    """A CSV column name carries its unit: ``speed [m/s]`` (``steady`` has none)."""
    return f"{name} [{unit}]" if unit else name


def _table(trace: Trace, names: Callable[[str, str], str], rounded: bool = False) -> Any:
    """A pyarrow Table of the trace's columns (``rounded``: each to its channel's decimals)."""
    import pyarrow as pa

    def values(c: Any) -> np.ndarray:
        return np.round(trace[c.name], c.decimals) + 0.0 if rounded else trace[c.name]  # + 0.0: no "-0"

    arrays = [pa.array(values(c), type=pa.float64(), from_pandas=True) for c in trace.channels]
    fields = [
        pa.field(
            names(c.name, c.unit),
            pa.float64(),
            metadata={"unit": c.unit, "description": c.description},
        )
        for c in trace.channels
    ]
    schema = pa.schema(fields, metadata={"t0": repr(trace.t0), "source": f"c2n {__version__}"})
    return pa.Table.from_arrays(arrays, schema=schema)


def write_csv(trace: Trace, path: Path, dialect: str = "excel") -> None:
    """Each value rounded to its channel's decimals (no ``28.40000000000009``), UTF-8 with a
    byte-order mark so a spreadsheet reads the units (``m/s²``) as they are."""
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.csv

    delimiter, decimal = CSV_DIALECTS[dialect]
    table = _table(trace, csv_header, rounded=True)
    if decimal != ".":
        columns = [
            pc.replace_substring(pc.cast(column, pa.string()), ".", decimal) for column in table.columns
        ]
        table = pa.Table.from_arrays(columns, names=table.column_names)
    with path.open("wb") as file:
        file.write("\ufeff".encode())
        # numbers as text (a decimal comma) unquoted, as a spreadsheet writes them; no name holds a ';'
        quoting = "needed" if decimal == "." else "none"
        pyarrow.csv.write_csv(
            table, file, pyarrow.csv.WriteOptions(delimiter=delimiter, quoting_style=quoting)
        )


def write_parquet(trace: Trace, path: Path) -> None:
    """Column names without units; each field's metadata holds ``unit`` and ``description``."""
    import pyarrow.parquet

    with path.open("wb") as file:  # a file, not its name: pyarrow cannot encode a name's undecodable bytes
        pyarrow.parquet.write_table(_table(trace, lambda name, unit: name), file, compression="zstd")


# Flags shown as words in an MF4 viewer (asammdf's value-to-text conversions); the raw values stay.
VALUE_TABLES: dict[str, dict[int, str]] = {
    "steady": {0: "not steady", 1: "steady"},
    "direction": {-1: "right", 0: "straight", 1: "left"},
}
_TIME_STEP_S = 1e-9  # frames of one microsecond are spread by this much, in arrival order


def rising(time: np.ndarray) -> np.ndarray:
    """Repeated timestamps (several frames in one microsecond) moved on by 1 ns per repeat, in
    arrival order, so a reader that keys rows by time (asammdf's ``to_dataframe``) keeps every
    row. The shift is a thousandth of the timestamps' resolution; a time that went backwards
    (a restarted logger) is left as it was."""
    n = len(time)
    starts = np.ones(n, dtype=bool)
    starts[1:] = time[1:] != time[:-1]
    run_start = np.maximum.accumulate(np.where(starts, np.arange(n), 0))
    return np.asarray(time, dtype=np.float64) + (np.arange(n) - run_start) * _TIME_STEP_S


def _conversion(name: str) -> dict[str, Any] | None:
    table = VALUE_TABLES.get(name)
    if table is None:
        return None
    conversion: dict[str, Any] = {"default_addr": b"no estimate"}  # NaN: before the filter starts
    for k, (value, text) in enumerate(table.items()):
        conversion[f"val_{k}"], conversion[f"text_{k}"] = value, text.encode()
    return conversion


def write_mf4(trace: Trace, path: Path) -> None:
    from asammdf import MDF, Signal

    time = rising(trace[TIME.name])
    mdf = MDF(version="4.10")
    if trace.t0 > 1e8:  # an absolute (epoch) timestamp: the measurement's start
        mdf.header.start_time = datetime.datetime.fromtimestamp(trace.t0, datetime.UTC)
    signals = [
        Signal(
            samples=np.ascontiguousarray(trace[c.name]),
            timestamps=time,
            name=c.name,
            unit=c.unit,
            comment=c.description,
            conversion=_conversion(c.name),
        )
        for c in trace.channels
        if c.name != TIME.name
    ]
    if len(time):
        mdf.append(signals, comment=f"c2n {__version__}: decoded and filtered channels")
    mdf.save(path, overwrite=True)
    mdf.close()


WRITERS: dict[str, Callable[[Trace, Path], None]] = {
    "csv": write_csv,
    "parquet": write_parquet,
    "mf4": write_mf4,
}


def write(trace: Trace, fmt: str, path: Path, csv_dialect: str = "excel") -> None:
    """Write atomically (``app.output.files``), translating OS errors."""
    need_writers((fmt,))
    writer = partial(write_csv, dialect=csv_dialect) if fmt == "csv" else WRITERS[fmt]
    write_atomically(path, partial(writer, trace), f"the {fmt.upper()} channels")
