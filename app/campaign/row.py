"""One drive of a campaign as its analysis left it: the typed row every stage of a campaign passes
on — the worker's result, the cache's file, the repeats' check, the comparison and the tables.

``result`` is what the comparison takes of a drive with a C2n: its headline with the data's error
held apart from the sensors' scales, and its two fits where it chose between them by a test. The
analyze summary rides along as it is written (``summary``) and becomes columns only where
``results.csv`` and ``results.parquet`` are written (``columns``).
"""

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

from app.campaign.meta_analysis import Estimate, Fits, Model
from app.output.files import json_ready

ROW_FORMAT = 3  # the cache file's layout: a row of another layout is analysed again
# the row's own columns, after the summary's
OWN_COLUMNS = ("drive", "error", "frames", "seconds", "worker_peak_mib", "key", "cached")


@dataclass(frozen=True)
class SessionResult:
    """A session's C2n as the comparison reads it."""

    own: Estimate  # its headline
    scale: float  # C2n's relative standard error from the sensors' scales, counted in own.ci95
    softening_t: float | None  # its fit's a_y³ t, where its a_y range could tell the models apart
    fits: Fits | None  # its two fits, where the headline chose between them by a test (the cascade)


@dataclass(frozen=True)
class SessionRow:
    """One drive of a campaign: its result or its error, and what its analysis cost."""

    summary: dict[str, Any] = field(default_factory=dict)  # analyze's summary file, as written
    result: SessionResult | None = None  # None: no C2n (``error`` says why, or the comparison does)
    error: str | None = None
    drive: str | None = None  # the drive's content identity: a copy elsewhere counts once
    runs: tuple[tuple[int, float], ...] = ()  # a sample of its sensor's runs: a near-copy counts once
    frames: int = 0
    seconds: float = 0.0
    worker_peak_mib: float | None = None  # the worker's peak memory so far
    key: str | None = None  # its log's and config's hashes: the cache's name for it
    cached: bool | None = None  # known from an earlier run (None: never sent, its log unreadable)

    def columns(self) -> dict[str, Any]:
        """The row as ``results``' columns: the summary's keys joined with dots, then the row's own."""
        own = {name: getattr(self, name) for name in OWN_COLUMNS}
        if self.drive is None:  # its log was never read
            del own["drive"]
        return flatten(self.summary) | own

    def warnings_about(self, log: Path) -> list[str]:
        """The summary's warnings about the log file itself (damage that ended the reading, a
        recording given twice): what the terminal says beside results.csv's column."""
        said = self.summary.get("warnings")
        if not isinstance(said, list):
            return []
        return [w for w in said if isinstance(w, str) and (str(log) in w or f"{log.name}:" in w)]

    def seen_at(self, inputs: Sequence[str], config: str) -> "SessionRow":
        """The row of a drive whose log or config was moved or renamed since it was analysed (the
        key is their content): the paths its summary and its error name, as they are now."""
        then = self.summary.get("inputs")
        if not isinstance(then, list) or len(then) != len(inputs):
            return self
        moves = [
            (old, new) for old, new in zip(then, inputs, strict=True) if isinstance(old, str) and old != new
        ]
        old_config = self.summary.get("config")
        if isinstance(old_config, str) and old_config != config:
            moves.append((old_config, config))
        if not moves:
            return self

        def now(text: str) -> str:
            for old, new in moves:
                text = text.replace(old, new)
            return text

        summary = {**self.summary, "inputs": list(inputs), "config": config}
        if isinstance(summary.get("warnings"), list):
            summary["warnings"] = [now(w) if isinstance(w, str) else w for w in summary["warnings"]]
        return replace(self, summary=summary, error=None if self.error is None else now(self.error))

    def to_json(self) -> dict[str, Any]:
        """The cache file's content (``cached`` is not kept: it is the run's, not the drive's)."""
        kept = json_ready(self)
        del kept["cached"]
        return {"format": ROW_FORMAT, **kept}

    @classmethod
    def from_json(cls, data: Any) -> "SessionRow":
        """A row from its cache file; ValueError where the file holds no such row (another layout,
        another version's, damaged): its drive is then analysed again."""
        try:
            if data["format"] != ROW_FORMAT or not isinstance(data["summary"], dict):
                raise ValueError("another layout")
            r = data["result"]
            result = None
            if r is not None:
                fits = r["fits"]
                result = SessionResult(
                    own=_estimate(r["own"]),
                    scale=float(r["scale"]),
                    softening_t=_number(r["softening_t"]),
                    fits=None
                    if fits is None
                    else Fits(
                        float(fits["softening_t"]),
                        _estimate(fits["linear"]),
                        _estimate(fits["softening"]) if fits["softening"] is not None else None,
                        _model(fits["chosen"]),
                    ),
                )
            return cls(
                summary=data["summary"],
                result=result,
                error=_text(data["error"]),
                drive=_text(data["drive"]),
                runs=tuple((int(h), float(t)) for h, t in data["runs"]),
                frames=int(data["frames"]),
                seconds=float(data["seconds"]),
                worker_peak_mib=_number(data["worker_peak_mib"]),
                key=_text(data["key"]),
            )
        except (KeyError, TypeError, IndexError) as error:
            raise ValueError(f"no campaign row ({type(error).__name__}: {error})") from None


def _estimate(value: Any) -> Estimate:
    c2n, (low, high), se = value
    if not finite_numbers(c2n, low, high, se):  # a worker writes only finite ones
        raise ValueError(f"{value!r}: not a C2n with its interval")
    return Estimate(float(c2n), (float(low), float(high)), float(se))


def _number(value: Any) -> float | None:
    return None if value is None else float(value)


def _text(value: Any) -> str | None:
    if value is not None and not isinstance(value, str):
        raise TypeError(f"{value!r} is no text")
    return value


def _model(value: Any) -> Model:
    if value not in ("linear", "softening"):
        raise ValueError(f"{value!r} is no tyre model")
    return "linear" if value == "linear" else "softening"


def flatten(value: dict[str, Any], prefix: str = "") -> dict[str, Any]:
    """Nested keys joined with dots; an interval [low, high] as ``.low``/``.high``; other lists
    (crossings, warnings …) as JSON text, so every value fits a CSV cell or a Parquet column."""
    out: dict[str, Any] = {}
    for key, item in value.items():
        name = f"{prefix}{key}"
        if isinstance(item, dict):
            out.update(flatten(item, f"{name}."))
        elif isinstance(item, list) and len(item) == 2 and all(_scalar_number(x) for x in item):
            out[f"{name}.low"], out[f"{name}.high"] = item
        elif isinstance(item, list):
            out[name] = json.dumps(item, ensure_ascii=False)
        else:
            out[name] = item
    return out


def _scalar_number(value: object) -> bool:
    return value is None or (isinstance(value, int | float) and not isinstance(value, bool))


def finite_numbers(*values: Any) -> bool:
    return all(isinstance(v, int | float) and math.isfinite(v) for v in values)
