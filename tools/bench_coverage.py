"""Coverage of the regression's 95 % intervals, cascade against marginal, over drives of every kind.

Each drive runs once through the pipeline; the regression its result rests on (the steady samples',
or where no sweep crossed zero the quasi-steady samples') is then fitted both ways on the same
samples: the cascade of tests (the default before 2026-11-27) and the marginal model (every nuisance with its
prior, ``[priors]``). Kinds: tools/bench_accuracy.py's cases a–o (our simulator's bicycle and
two-track models, CommonRoad's multi-body car) and the dev pack's nine drives (an independent
generator's car; its truth ``c2n.rear_axle_effective_linear``). Printed per kind and estimator: the
drives, the median and worst |error| %, the coverage and the intervals' median half width %, the
term that holds the marginal interval open most often, the errors in their intervals' own σ (rms),
and the warnings a linear drive should not
raise (softening kept on the bicycle model's linear tyres; d's interval apart from the tape's on a
plain drive). Then per kind: each fit's rms error, and the worst |error|'s difference between them
with a paired bootstrap interval (how much one drive moves a worst case). At the end: the coverage
over all drives with its Clopper–Pearson 95 % interval, and the median time of a refit.

    python tools/bench_coverage.py                           # 23 per kind: 299 simulated + 9 = 308
    python tools/bench_coverage.py --sessions 3 --kinds a,f,j,dev
    python tools/bench_coverage.py --summarise rows.jsonl --sessions 20   # kept rows, seeds 0–19
"""

import argparse
import copy
import json
import pickle
import statistics
import time
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
from bench_accuracy import CASES, simulated
from scipy.stats import beta

from app.config import Config, Priors, load_config
from app.pipeline import Pipeline
from app.results.regression import RegressionFit, SampleRegression
from app.sources.logs import LogReport, read_log

DEV_PACK = Path("/work/shared/data/dev-pack")
PLAIN = ("a", "f")  # plain drives on a level pad, d the tape's: no warning of d apart is supported
EXACT_D = ("a", "b", "c", "d", "e", "f", "g")  # simulated with the config's d exact (h–m: the tape's error)
LINEAR = ("a", "b", "d")  # the bicycle model's linear tyres: no softening warning is supported (f's
# two-track tyres soften: Magic-Formula tyres and load transfer, t = −4…−9 in both fits)


def unsupported(kind: str, graded: dict[str, Any]) -> bool:
    """A warning the drive does not support: softening on linear tyres, d apart from the tape on a
    plain drive."""
    return (kind in LINEAR and graded["softening"]) or (kind in PLAIN and graded["d_apart"])


def drive(job: tuple[str, int, float | None, Path | None]) -> dict[str, Any]:
    """One drive of a kind, both estimators on its samples; its samples kept in ``keep`` (a
    pickle of the regression, its truth and config) for ``--refit``."""
    kind, seed, tape_mm, keep = job
    if kind == "dev":
        case = DEV_PACK / f"case_{seed + 1:02d}"
        config = load_config(case / "config.toml")
        truth = float(json.loads((case / "truth.json").read_text())["c2n"]["rear_axle_effective_linear"])
        pipeline = Pipeline(config)
        log = case / "drive.blf"
        for message in read_log(log, LogReport(log), pipeline.decoder):
            pipeline.process(message)
    else:
        config, simulation, truth = simulated(kind, "radii", seed, 100.0, tape_mm)
        pipeline = Pipeline(config)
        for message in simulation.messages:
            pipeline.process(message)
    pipeline.finish()
    state = pipeline.snapshot()
    regression = (
        pipeline.quasi if state.fit is state.quasi and state.quasi is not None else pipeline.regression
    )
    if keep is not None:
        kept = {"kind": kind, "seed": seed, "regression": regression, "truth": truth, "config": config}
        (keep / f"{kind}_{seed:03d}.pickle").write_bytes(pickle.dumps(kept))
    return fitted(kind, seed, regression, truth, config)


def fitted(
    kind: str, seed: int, regression: SampleRegression, truth: float, config: Config, tape: bool = False
) -> dict[str, Any]:
    """The row of a drive's samples, fitted both ways; ``tape``: on the kinds whose simulation has
    the config's d exact (a–g), the tape read off by an error drawn as bench_accuracy's h–m draw it
    (normal, the config's tolerance at 95 %), so the intervals, which count that tolerance, are
    tried on what they claim."""
    row: dict[str, Any] = {"kind": kind, "seed": seed}
    if tape and kind in EXACT_D and regression.d_tape_m is not None:
        regression = copy.deepcopy(regression)
        regression.d_tape_m += float(
            np.random.default_rng(50_000 + seed).normal(0.0, config.calibration.d_se_m)
        )
    priors = replace(config.priors, estimator="marginal")
    for name, chosen in (("cascade", None), ("marginal", priors)):
        model: SampleRegression = copy.deepcopy(regression)
        model.priors = chosen
        started = time.perf_counter()
        fit = model.fit()
        row[f"{name}_s"] = time.perf_counter() - started
        row[name] = _graded(fit, truth, config.d_m)
    return row


def _graded(fit: RegressionFit | None, truth: float, d_tape_m: float) -> dict[str, Any] | None:
    if fit is None:
        return None
    low, high = fit.c2n_ci95
    return {
        "error": float(100.0 * (fit.c2n / truth - 1.0)),  # plain floats and bools: a JSON row
        "covers": bool(low <= truth <= high),
        "half": float(50.0 * (high - low) / truth),
        "held": fit.held_open.by if fit.held_open else None,
        "softening": fit.models.chosen == "softening",
        "d_apart": bool(not fit.d.held and not fit.d.ci95_m[0] <= d_tape_m <= fit.d.ci95_m[1]),
    }


def _todays(config: Config) -> Config:
    """The config a kept drive was simulated with, as this checkout has it today (its priors'
    defaults): the kept path where it still exists, else the file of the same name in config/
    (samples kept by another checkout, since removed)."""
    path = config.path
    if path is not None and not path.exists():
        path = Path(__file__).resolve().parent.parent / "config" / path.name
    return load_config(path)


def _todays_priors(config: Config) -> Priors:
    """Today's priors' defaults for a kept drive, the load transfer's its own car's (case n's SUV
    is the Mondeo's file with its own figures)."""
    priors = _todays(config).priors
    own = config.vehicle.load_transfer_per_g
    return priors if own is None else replace(priors, load_transfer_per_g=own)


def clopper_pearson(k: int, n: int, level: float = 0.95) -> tuple[float, float]:
    """The exact binomial interval of a share k/n."""
    tail = (1.0 - level) / 2.0
    low = float(beta.ppf(tail, k, n - k + 1)) if k > 0 else 0.0
    high = float(beta.ppf(1.0 - tail, k + 1, n - k)) if k < n else 1.0
    return low, high


def _z_rms(graded: list[dict[str, Any]]) -> float:
    """The errors in their intervals' own σ (half width / 1.96), rms: 1 where the intervals are as
    wide as the errors — sharper than a coverage count of a few drives."""
    z = [g["error"] / (g["half"] / 1.96) for g in graded if g["half"] > 0]
    return (sum(x * x for x in z) / len(z)) ** 0.5 if z else float("nan")


def _interval(k: int, n: int) -> str:
    low, high = clopper_pearson(k, n)
    return f"{low:4.2f}–{high:4.2f}"


def _row(kind: str, name: str, graded: list[dict[str, Any]], total: int) -> str:
    if not graded:
        return f"{kind:<5} {name:<9} {0:>3}/{total:<3}"
    errors = [abs(g["error"]) for g in graded]
    covered = sum(g["covers"] for g in graded)
    held = Counter(g["held"] for g in graded if g["held"]).most_common(1)
    warned = sum(unsupported(kind, g) for g in graded)
    return (
        f"{kind:<5} {name:<9} {len(graded):>3}/{total:<3} "
        f"{statistics.median(errors):7.3f} {max(errors):7.3f} "
        f"{covered:>3}/{len(graded):<3} {_interval(covered, len(graded))} "
        f"{statistics.median(g['half'] for g in graded):6.2f} {_z_rms(graded):5.2f} "
        f"{warned:>4}  {held[0][0] + ' ' + str(held[0][1]) if held else '—'}"
    )


def worst_difference(
    rows: list[dict[str, Any]], resamples: int = 10_000
) -> tuple[float, float, float, float]:
    """The worst |error| %, marginal less cascade, over drives both fitted; its paired bootstrap
    95 % interval (the drives drawn again with replacement, seeded) and the share of draws in which
    the marginal's worst is the larger. A maximum's bootstrap is rough — no draw holds a drive
    worse than those seen — so this shows how much one drive moves the statistic, not a test."""
    paired = [r for r in rows if r["cascade"] is not None and r["marginal"] is not None]
    errors = np.abs([[r["marginal"]["error"], r["cascade"]["error"]] for r in paired])
    draws = np.random.default_rng(0).integers(0, len(paired), size=(resamples, len(paired)))
    worst = errors[draws].max(axis=1)  # (resamples, 2)
    difference = worst[:, 0] - worst[:, 1]
    low, high = np.quantile(difference, [0.025, 0.975])
    observed = float(errors[:, 0].max() - errors[:, 1].max())
    return observed, float(low), float(high), float(np.mean(difference > 0))


def _rms(graded: list[dict[str, Any]]) -> float:
    return float(np.sqrt(np.mean([g["error"] ** 2 for g in graded]))) if graded else float("nan")


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--sessions", type=int, default=23, help="drives per simulated kind")
    parser.add_argument("--kinds", default=",".join([*CASES, "dev"]), help="bench_accuracy's cases a–o, dev")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--first-seed", type=int, default=0, help="start here (a run continued)")
    parser.add_argument("--tape-mm", type=float, default=None, help="as tools/bench_accuracy.py's")
    parser.add_argument(
        "--rows", type=Path, help="append each drive's row to this JSON-lines file as it ends"
    )
    parser.add_argument(
        "--summarise", type=Path, nargs="+", help="print the tables of rows files, run nothing"
    )
    parser.add_argument(
        "--tape-drawn",
        action="store_true",
        help="with --refit: a–g's tape read off by an error within the config's tolerance (as h–m's)",
    )
    parser.add_argument("--keep", type=Path, help="keep each drive's samples in this directory")
    parser.add_argument(
        "--refit", type=Path, help="fit the samples kept in this directory again (today's code), run nothing"
    )
    args = parser.parse_args()
    kinds = args.kinds.split(",")
    started = time.perf_counter()
    if args.summarise:
        rows = [json.loads(line) for path in args.summarise for line in path.read_text().splitlines() if line]
        # --sessions 20: bench_accuracy's seeds
        rows = [r for r in rows if r["seed"] < args.sessions and r["kind"] in kinds]
        kinds = [k for k in kinds if any(r["kind"] == k for r in rows)]
    elif args.refit:
        rows = []
        for path in sorted(args.refit.glob("*.pickle")):
            kept = pickle.loads(path.read_bytes())
            config = replace(kept["config"], priors=_todays_priors(kept["config"]))
            rows.append(
                fitted(kept["kind"], kept["seed"], kept["regression"], kept["truth"], config, args.tape_drawn)
            )
        rows.sort(key=lambda r: (r["seed"], r["kind"]))
        kinds = [k for k in kinds if any(r["kind"] == k for r in rows)]
    else:
        if args.keep:
            args.keep.mkdir(parents=True, exist_ok=True)
        jobs = [  # seed by seed, every kind in each: a run cut short still has every kind
            (k, seed, args.tape_mm, args.keep)
            for seed in range(args.first_seed, max(9, args.sessions))
            for k in kinds
            if seed < (9 if k == "dev" else args.sessions)
        ]
        rows = []
        with ProcessPoolExecutor(args.workers) as pool:
            for row in pool.map(drive, jobs):
                rows.append(row)
                if args.rows:
                    with args.rows.open("a") as file:
                        file.write(json.dumps(row) + "\n")
    print(
        "kind  estimator  fits  |error| % median worst  covered (Clopper–Pearson)  half%  z rms  warn  "
        "held open by (most often)"
    )
    for kind in kinds:
        for name in ("cascade", "marginal"):
            mine = [r for r in rows if r["kind"] == kind]
            print(_row(kind, name, [r[name] for r in mine if r[name] is not None], len(mine)))
    print(
        "\nkind  rms |error| %: cascade marginal   worst |error|, marginal − cascade % "
        "(paired bootstrap 95 %; draws with the marginal's the larger)"
    )
    for kind in kinds:
        mine = [r for r in rows if r["kind"] == kind]
        if any(r["cascade"] and r["marginal"] for r in mine):
            observed, low, high, larger = worst_difference(mine)
            print(
                f"{kind:<5} {_rms([r['cascade'] for r in mine if r['cascade']]):21.3f} "
                f"{_rms([r['marginal'] for r in mine if r['marginal']]):8.3f}   "
                f"{observed:+7.3f} ({low:+.3f} … {high:+.3f}; {larger:.0%})"
            )
    for name in ("cascade", "marginal"):
        graded = [r[name] for r in rows if r[name] is not None]
        k, n = sum(g["covers"] for g in graded), len(graded)
        low, high = clopper_pearson(k, n)
        plain = [r[name] for r in rows if r["kind"] in PLAIN and r[name] is not None]
        warned = sum(
            unsupported(r["kind"], r[name]) for r in rows if r["kind"] in PLAIN and r[name] is not None
        )
        refit = statistics.median(r[f"{name}_s"] for r in rows) * 1000.0
        print(
            f"{name}: coverage {k}/{n} = {k / max(n, 1):.3f} (Clopper–Pearson 95 %: {low:.3f}–{high:.3f}); "
            f"warnings on plain linear drives {warned}/{len(plain)}; refit {refit:.1f} ms (median)"
        )
    print(f"{len(rows)} drives, {time.perf_counter() - started:.0f} s")


if __name__ == "__main__":
    main()
