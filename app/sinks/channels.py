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
from app.sinks.files import write_atomically
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


def _table(trace: Trace, names: Callable[[str, str], str]) -> Any:
    """A pyarrow Table of the trace's columns."""
    import pyarrow as pa

    arrays = [pa.array(trace[c.name], type=pa.float64(), from_pandas=True) for c in trace.channels]
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


def write_csv(trace: Trace, path: Path) -> None:
    import pyarrow.csv

    pyarrow.csv.write_csv(_table(trace, csv_header), str(path))


def write_parquet(trace: Trace, path: Path) -> None:
    """Column names without units; each field's metadata holds ``unit`` and ``description``."""
    import pyarrow.parquet

    pyarrow.parquet.write_table(_table(trace, lambda name, unit: name), str(path), compression="zstd")


def write_mf4(trace: Trace, path: Path) -> None:
    from asammdf import MDF, Signal

    time = trace[TIME.name]
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


def write(trace: Trace, fmt: str, path: Path) -> None:
    """Write atomically (``app.sinks.files``), translating OS errors."""
    need_writers((fmt,))
    write_atomically(path, partial(WRITERS[fmt], trace), f"the {fmt.upper()} channels")
