"""Grade ``c2n gap`` on a pack whose cases carry their whole truth (``case_*/drive.blf``,
``config.toml``, ``truth.json`` as the dev pack has them) and print the per-case table and the
total.

    nice -n 5 .venv/bin/python tools/gap_pack_grade.py ../shared/data/dev-pack [--jobs 1] [--out DIR]

A case is right when
- the withheld effect is named — a finding (``effects`` with ``matters``), or confounded with
  one — with its size inside its 95 % interval or within 30 % of the truth where a size maps one
  to one (misalignment, d, speed scale, latency, slope);
- nothing is named that the truth does not hold: every finding is an effect the drive carries
  (withheld or in its baseline), and where its size maps one to one, that size is right by the
  same test (a 0.03° head named on a drive whose head is yawed 0.005° is a false finding).
The drive with nothing withheld is right when it names only what its baseline holds.

``--out DIR`` keeps each case's JSON (``DIR/case_NN.json``); ``--reuse`` grades those without
running ``c2n gap`` again.
"""

import argparse
import json
import math
import shutil
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

SIZE_SHARE = 0.3  # the bar: a size within 30 % of the truth (or inside its interval)

# effects every drive of a car with Magic-Formula tyres and ply steer carries
OFFSETS = {"sensor_yaw_misalignment", "tyre_ply_steer"}  # one offset of the sideslip, either way
ALWAYS_HELD = {"load_transfer_nonlinearity", "tyre_ply_steer"}


def truth_sizes(truth: dict[str, Any]) -> dict[str, dict[str, float] | None]:
    """What the drive holds: effect → its size in the report's parameter (None: held, no
    one-to-one size)."""
    config = truth["config"]
    sensor, can = config["optical_sensor"], config["vehicle_can"]
    detail = config.get("effect_detail") or {}
    withheld = truth["effect"]["name"]
    scale = detail.get(
        "speed_scale_error", (config.get("baseline_imperfections") or {}).get("speed_scale_error", 0.0)
    )
    held: dict[str, dict[str, float] | None] = {
        "sensor_yaw_misalignment": {"misalignment_deg": sensor["yaw_misalignment_deg"]},
        "sensor_position_error": {"d_error_m": sensor["d_true"] - config["d_nominal"]},
        "speed_scale_error": {"speed_scale_pct": 100.0 * scale},
        "signal_latency": {"latency_s": can["speed_latency_s"] - sensor.get("latency_s", 0.0)},
        "road_cross_slope": {"slope_pct": config["road"]["cross_slope_pct"]},
        **dict.fromkeys(ALWAYS_HELD),
    }
    if config["vehicle"].get("rear_roll_steer") or withheld == "roll_steer":
        held["roll_steer"] = None
    if withheld not in held and withheld != "none":
        held[withheld] = None
    return held


def _magnitude(effect: str, params: dict[str, float]) -> float | None:
    if effect == "road_cross_slope":
        if "slope_pct" in params:
            return abs(params["slope_pct"])
        return (params.get("slope_sin_pct", 0.0) ** 2 + params.get("slope_cos_pct", 0.0) ** 2) ** 0.5
    return abs(next(iter(params.values()))) if params else None


def size_ok(effect: str, entry: dict[str, Any], want: dict[str, float] | None) -> bool:
    """The reported size within 30 % of the truth's, or the truth inside its 95 % interval."""
    if want is None:
        return True
    got, true = _magnitude(effect, entry.get("params") or {}), _magnitude(effect, want)
    if got is None or true is None:
        return False
    if abs(got - true) <= SIZE_SHARE * true:
        return True
    name, value = next(iter(want.items()))
    low, high = (entry.get("ci95") or {}).get(name, (None, None))
    return low is not None and (
        low <= value <= high or (low <= -value <= high and effect != "signal_latency")
    )


def offset_ok(entry: dict[str, Any], truth: dict[str, Any]) -> bool:
    """A head's yaw and the rear tyres' ply steer move the sideslip alike (the drive cannot tell
    them apart): an offset named as either is right when its size is within 30 % of what the two
    together can make, |head| ± |ply|, the ply steer as its slip F/(C2n·W2)."""
    config = truth["config"]
    head = abs(config["optical_sensor"]["yaw_misalignment_deg"])
    w2 = truth.get("rear_axle_load_N") or next(
        (v for k, v in config["vehicle"].items() if k in ("rear_axle_load_N", "W2")), None
    )
    c2n = truth["c2n"]["rear_axle_effective_linear"]
    ply = 0.0
    if w2:
        ply = abs(math.degrees(config["vehicle"].get("ply_steer_rear", 0.0) / (c2n * w2)))
    got = _magnitude(entry["effect"], entry.get("params") or {}) or 0.0
    return (1 - SIZE_SHARE) * max(head - ply, 0.0) <= got <= (1 + SIZE_SHARE) * (head + ply)


def grade_json(g: dict[str, Any], truth: dict[str, Any]) -> dict[str, Any]:
    withheld = truth["effect"]["name"]
    held = truth_sizes(truth)
    effects = [e for e in g.get("effects") or [] if isinstance(e, dict)]
    findings = [e for e in effects if e.get("matters")]
    false = [
        e["effect"]
        for e in findings
        if e["effect"] not in held
        or not (
            size_ok(e["effect"], e, held[e["effect"]]) or (e["effect"] in OFFSETS and offset_ok(e, truth))
        )
    ]
    ok = not false
    said = ", ".join(
        f"{e['effect']}{_sized(e)}"
        + (f" (or {'/'.join(e['confounded_with'])})" if e.get("confounded_with") else "")
        for e in findings
    )
    if withheld != "none":
        named = {e["effect"]: e for e in findings}
        for e in findings:
            for twin in e.get("confounded_with") or []:
                named.setdefault(twin, next((x for x in effects if x["effect"] == twin), e))
        entry = named.get(withheld)
        found = entry is not None and (
            entry["effect"] != withheld or size_ok(withheld, entry, held.get(withheld))
        )
        ok = ok and found
    return {"diagnosis": g.get("diagnosis"), "ok": ok, "said": said or "-", "false": false}


def _sized(e: dict[str, Any]) -> str:
    params = e.get("params") or {}
    return " " + " ".join(f"{k}={v:.4g}" for k, v in params.items()) if params else ""


def run_case(case: Path, c2n: str, out: Path, reuse: bool) -> dict[str, Any]:
    truth = json.loads((case / "truth.json").read_text())
    path = out / f"{case.name}.json"
    if not (reuse and path.exists()):
        p = subprocess.run(
            [c2n, "gap", str(case / "drive.blf"), "--config", str(case / "config.toml"), "--json", str(path)],
            capture_output=True,
            text=True,
        )
        if p.returncode != 0 or not path.exists():
            last = (p.stderr.strip().splitlines() or ["?"])[-1][:90]
            return {
                "case": case.name,
                "truth": truth["effect"]["name"],
                "ok": False,
                "said": f"error: {last}",
            }
    row = grade_json(json.loads(path.read_text()), truth)
    return {"case": case.name, "truth": truth["effect"]["name"], **row}


def main() -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("pack", type=Path)
    ap.add_argument(
        "--c2n", default=str(Path(sys.executable).parent / "c2n") if shutil.which("c2n") is None else "c2n"
    )
    ap.add_argument("--jobs", type=int, default=1)
    ap.add_argument("--out", type=Path, help="keep each case's JSON here")
    ap.add_argument("--reuse", action="store_true", help="grade the JSON in --out without running c2n gap")
    a = ap.parse_args()
    cases = sorted(p for p in a.pack.glob("case_*") if (p / "truth.json").exists())
    if not cases:
        print(f"{a.pack}: no case_*/truth.json — pass a pack with truth files", file=sys.stderr)
        return 1
    with tempfile.TemporaryDirectory() as tmp:
        out = a.out or Path(tmp)
        out.mkdir(parents=True, exist_ok=True)
        with ThreadPoolExecutor(a.jobs) as pool:
            rows = list(pool.map(lambda c: run_case(c, a.c2n, out, a.reuse), cases))
    for r in rows:
        false = f"  false: {', '.join(r['false'])}" if r.get("false") else ""
        print(f"{r['case']}  {r['truth']:<27} {'right' if r['ok'] else 'WRONG':<6} {r['said']}{false}")
    print(f"{a.pack.name}, c2n gap: {sum(r['ok'] for r in rows)}/{len(rows)} right")
    return 0


if __name__ == "__main__":
    sys.exit(main())
