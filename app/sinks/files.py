"""Every result file is written the same way: into a temporary file beside it, then renamed into
place, so a crash, a kill or a full disk leaves the old file or the new one, never half of one;
an OS error becomes one OutputError naming the file."""

import contextlib
import dataclasses
import json
import os
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from app.errors import OutputError


def partial_path(path: Path) -> Path:
    """The temporary name a file is written under: hidden, unique to this process, and with the
    file's own suffix (asammdf and matplotlib pick the format from it)."""
    return path.with_name(f".{path.stem}.{os.getpid()}.partial{path.suffix}")


def write_atomically(path: Path, write: Callable[[Path], object], what: str) -> None:
    """``write(tmp)`` writes the file's content to ``tmp``; it then replaces ``path``.
    ``what`` names the file in the error ("the summary", "the report")."""
    tmp = partial_path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        write(tmp)
        os.replace(tmp, path)
    except OSError as error:
        with contextlib.suppress(OSError):  # a file in the folder's place: there is no tmp either
            tmp.unlink(missing_ok=True)
        raise OutputError(f"{path}: cannot write {what} ({error.strerror or error})") from error


def json_ready(value: Any) -> Any:
    """A result dataclass as JSON's own types: dataclasses and mappings as dicts, tuples as lists
    (what ``json.loads`` gives back from the file)."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: json_ready(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, Mapping):
        return {key: json_ready(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [json_ready(item) for item in value]
    return value


def write_text(path: Path, text: str, what: str) -> None:
    write_atomically(path, lambda tmp: tmp.write_text(text, encoding="utf-8"), what)


def write_json(path: Path, data: Any, what: str) -> None:
    write_text(path, json.dumps(data, indent=2) + "\n", what)
