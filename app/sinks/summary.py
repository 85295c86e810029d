"""The session summary (DESIGN §6): what ``c2n analyze --json`` and a live session write."""

import json
import math
import os
from collections.abc import Sequence
from dataclasses import asdict
from pathlib import Path
from typing import Any

from app import __version__
from app.config import Config
from app.errors import C2nError
from app.pipeline import Pipeline
from app.records import Crossing
from app.results.pairing import Paired
from app.results.regression import RegressionFit
from app.sources.logs import LogReport

REQUIRED_ROLES = (("vx",), ("vy", "beta"))


def _frame_ids(config: Config, role: str) -> str:
    spec = config.roles[role]
    for dbc in config.dbcs:
        for message in dbc.database.messages:
            if message.name == spec.message:
                where = f" on channel {spec.channel}" if spec.channel is not None else ""
                return f"{spec.name}, id 0x{message.frame_id:X}{where}"
    return spec.name


def roles_without_frames(pipeline: Pipeline) -> list[str]:
    counts = pipeline.decoder.counts.role_frames
    return [role for role in pipeline.config.roles if counts[role] == 0]


def missing_required(pipeline: Pipeline) -> str | None:
    """A message naming the required role that had no frames, or None."""
    silent = set(roles_without_frames(pipeline))
    for group in REQUIRED_ROLES:
        configured = [r for r in group if r in pipeline.config.roles]
        if configured and all(r in silent for r in configured):
            role = configured[0]
            return (
                f"no frames for role '{role}' ({_frame_ids(pipeline.config, role)}) — "
                "is the optical sensor on this bus/log and channel?"
            )
    return None


def warnings(pipeline: Pipeline, reports: Sequence[LogReport] = ()) -> list[str]:
    config = pipeline.config
    counts = pipeline.decoder.counts
    out: list[str] = []
    for report in reports:
        if report.stopped:
            out.append(f"{report.path}: {report.stopped}")
    for role in roles_without_frames(pipeline):
        out.append(f"no frames for role '{role}' ({_frame_ids(config, role)})")
    if "yaw_rate" not in config.roles and "ay" not in config.roles:
        out.append(
            "no yaw rate or lateral acceleration: the steady-state gate cannot check a_y "
            "or tell straight driving"
        )
    for dbc in config.dbcs:
        if dbc.relaxed:
            out.append(f"{dbc.path.name} loaded with strict=False (overlapping or oversized signals)")
    if counts.other_channel:
        out.append(
            f"{counts.other_channel} frames of known ids arrived on a channel their DBC "
            "is not decoded on ([channels])"
        )
    for reason, n in counts.rejected.most_common():
        out.append(f"{n} frames' values dropped: {reason}")
    f = pipeline.filter.counts
    if f.time_jumps:
        out.append(f"timestamps went backwards {f.time_jumps} times: the filter restarted")
    if f.resets - f.time_jumps:
        out.append(
            f"the optical data stopped {f.resets - f.time_jumps} times for over "
            f"{config.filter.gap_reset_s:g} s: the filter restarted"
        )
    fit = pipeline.state.regression
    if fit is not None and not fit.d_ci95[0] <= config.d_m <= fit.d_ci95[1]:
        low, high = fit.d_ci95
        out.append(
            f"the fitted sensor position d = {fit.d_m:.3f} m [{low:.3f}, {high:.3f}] disagrees with the "
            f"config's {config.d_m:g} m: check sensor_ahead_of_rear_axle_m (the crossings' C2n scales "
            "with d; the regression's does not)"
        )
    if fit is not None and fit.model == "softening":
        out.append(
            f"the tyres soften with slip (t = {fit.softening_t:.1f}): C2n is extrapolated to zero lateral "
            f"acceleration ({fit.c2n:.3f}; a straight-line fit would give {fit.c2n_linear_model:.3f})"
        )
    paired = pipeline.state.paired
    yaw, yaw_se = (paired.misalignment_rad, paired.misalignment_se) if paired is not None else (None, None)
    if yaw is not None and yaw_se is not None and abs(yaw) > max(1.96 * yaw_se, math.radians(0.1)):
        out.append(
            f"the sensor head looks yawed by {math.degrees(yaw):+.2f}° (left and right turns disagree); "
            "pairing and the regression remove it, but align the head"
        )
    rejected = pipeline.state.rejections
    if rejected:
        out.append(f"{len(rejected)} sign changes not used (see 'rejected_crossings')")
    if pipeline.state.t_first is not None and not pipeline.state.crossings:
        out.append(
            "no sideslip sign change was found in steady cornering: sweep the speed through u0 on a circle"
        )
    return out


def format_id(frame_id: int, extended: bool) -> str:
    """0x7E5 for an 11-bit id, 0x000007E5 for a 29-bit one, as CAN tools write them."""
    return f"0x{frame_id:08X}" if extended else f"0x{frame_id:X}"


def _round(value: float, digits: int = 4) -> float | None:
    return round(float(value), digits) if math.isfinite(value) else None


def _crossing(c: Crossing, t0: float) -> dict[str, Any]:
    return {
        "t": _round(c.t - t0, 3),
        "t_abs": c.t,
        "u0_mps": _round(c.u0_mps),
        "u0_kmh": _round(c.u0_kmh, 3),
        "u0_ci95": [_round(v) for v in c.u0_ci95],
        "c2n": _round(c.c2n),
        "ci95": [_round(v) for v in c.ci95],
        "direction": c.direction,
        "sweep": c.sweep,
        "ay_mps2": _round(c.ay_mps2, 3),
        "radius_m": _round(c.radius_m, 2),
        "sweep_rate_mps2": _round(c.sweep_rate_mps2, 3),
        "n_samples": c.n_samples,
        "method": c.method,
    }


def _pair(
    values: tuple[float, float] | None, scale: float = 1.0, digits: int = 4
) -> list[float | None] | None:
    return None if values is None else [_round(v * scale, digits) for v in values]


def _regression(fit: RegressionFit | None) -> dict[str, Any] | None:
    if fit is None:
        return None
    deg = math.degrees(1.0)
    return {
        "c2n": _round(fit.c2n),
        "c2n_ci95": _pair(fit.c2n_ci95),
        "d_m": _round(fit.d_m),
        "d_ci95": _pair(fit.d_ci95),
        "psi0_deg": _round(fit.psi0_rad * deg) if fit.psi0_rad is not None else None,
        "psi0_ci95_deg": _pair(fit.psi0_ci95, deg),
        "model": fit.model,
        "softening_t": _round(fit.softening_t, 2),
        "softening_per_mps2_2": _round(fit.softening_per_mps2_2, 6)
        if fit.softening_per_mps2_2 is not None
        else None,
        "c2n_linear_model": _round(fit.c2n_linear_model),
        "c2n_softening_model": _round(fit.c2n_softening_model)
        if fit.c2n_softening_model is not None
        else None,
        "n_samples": fit.n_samples,
        "ay_range_mps2": _pair(fit.ay_range, digits=3),
    }


def _paired(paired: Paired | None) -> dict[str, Any] | None:
    if paired is None:
        return None
    deg = math.degrees(1.0)

    def ci(value: float | None, se: float | None, scale: float = 1.0) -> list[float | None] | None:
        if value is None or se is None:
            return None
        return [_round((value - 1.96 * se) * scale), _round((value + 1.96 * se) * scale)]

    return {
        "c2n": _round(paired.c2n),
        "c2n_ci95": _pair(paired.ci95),
        "misalignment_deg": _round(paired.misalignment_rad * deg)
        if paired.misalignment_rad is not None
        else None,
        "misalignment_ci95_deg": ci(paired.misalignment_rad, paired.misalignment_se, deg),
        "lag_s": _round(paired.lag_s) if paired.lag_s is not None else None,
        "lag_ci95_s": ci(paired.lag_s, paired.lag_se),
        "cancels": list(paired.cancels),
        "cells": {key: _round(value) for key, value in paired.cells.items()},
        "n": paired.n,
        "birge_ratio": _round(paired.birge_ratio, 3),
    }


def build(pipeline: Pipeline, inputs: Sequence[str], reports: Sequence[LogReport] = ()) -> dict[str, Any]:
    state = pipeline.state
    config = pipeline.config
    t0 = state.t_first or 0.0
    combined = state.combined
    headline = state.headline
    g, d = config.vehicle.gravity_mps2, config.d_m
    counts = pipeline.decoder.counts
    return {
        "c2n": _round(headline.c2n) if headline else None,
        "c2n_ci95": _pair(headline.ci95) if headline else None,
        "c2n_method": headline.method if headline else None,
        "u0_mps": _round(math.sqrt(headline.c2n * g * d)) if headline else None,
        "crossings": [_crossing(c, t0) for c in state.crossings],
        "regression": _regression(state.regression),
        "paired": _paired(state.paired),
        "frames": counts.as_dict(),
        "warnings": warnings(pipeline, reports),
        "combined": {
            "n": combined.n,
            "birge_ratio": _round(combined.birge_ratio, 3),
            "se": _round(combined.se, 5),
        }
        if combined
        else None,
        "rejected_crossings": [
            {
                "t": _round(r.t - t0, 3),
                "direction": r.direction,
                "sweep": r.sweep,
                "u_mps": _round(r.u_mps, 3),
                "reason": r.reason,
            }
            for r in state.rejections
        ],
        "d_m": d,
        "g_mps2": g,
        "duration_s": _round((state.t_last or t0) - t0, 3),
        "inputs": list(inputs),
        "config": str(config.path),
        "frames_by_id": [
            {"channel": str(ch), "id": format_id(i, ext), "frames": n}
            for (ch, i, ext), n in sorted(
                counts.by_id.items(), key=lambda kv: (str(kv[0][0]), kv[0][1], kv[0][2])
            )
        ],
        "filter": asdict(pipeline.filter.counts)
        | {
            "health": _round(pipeline.filter.health, 3),
            "noise": {k: _round(v, 5) for k, v in pipeline.filter.noise_sigma().items()},
        },
        "version": __version__,
    }


def write(path: Path, summary: dict[str, Any]) -> None:
    """Write atomically: a crash leaves the old file or the new one, never half of one."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(path.name + ".tmp")
        tmp.write_text(json.dumps(summary, indent=2) + "\n")
        os.replace(tmp, path)
    except OSError as error:
        raise C2nError(f"{path}: cannot write the summary ({error.strerror})") from None
