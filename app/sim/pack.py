"""Blind packs: N standard sessions on the two-track model, each with one effect drawn at random.

    DIR/case_001/drive.blf        the drive; nothing in the folder tells its effect
    DIR/case_001/config.toml      only when the pack was made with a config other than the default
    DIR/sealed/truth.json         every case's effect, size, unit, true C2n, true d, seed, …

Case i is seeded from the pack seed and i alone, so a pack is reproducible and its first cases do
not depend on N; ``c2n simulate --session standard --effect E --effect-size X --seed <case seed>``
writes the same drive as the pack's case.
"""

import json
import os
import re
import time
import tomllib
from collections.abc import Callable
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import can
import numpy as np

from app.config import DEFAULT_CONFIG, load_config
from app.errors import C2nError, ConfigError, OutputError
from app.output.files import folder_atomically, write_json, write_text
from app.sim import commonroad
from app.sim.effects import EFFECT_NAMES, Effect, draw_effect
from app.sim.imperfections import HANDBOOK_SPREAD, NO_IMPERFECTIONS, Imperfections, handbook, of_session
from app.sim.standard import STANDARD_PLAN, StandardOptions, StandardPlan, simulate_standard
from app.sim.workers import ends_with_parent

LOG_NAME = "drive.blf"
_EFFECT_STREAM = 0xEFFEC7  # the effect's draw has a random stream of its own, apart from the noise
_HANDBOOK_STREAM = 0x4A4DB0  # and the case config's nominal tyres


@dataclass(frozen=True)
class CaseSpec:
    name: str
    seed: int
    effect: Effect
    imperfections: Imperfections = NO_IMPERFECTIONS
    handbook: tuple[float, float] | None = None  # the case config's (C1n, C2n) factors: ±20 %


@dataclass(frozen=True)
class CaseResult:
    name: str
    log: Path
    duration_s: float
    frames: int
    elapsed_s: float
    truth: dict[str, Any]


@dataclass(frozen=True)
class PackResult:
    out: Path
    cases: tuple[CaseResult, ...]
    truth_path: Path
    elapsed_s: float


def case_seed(pack_seed: int, index: int) -> int:
    """The seed of case ``index`` (1-based) of a pack."""
    return int(np.random.SeedSequence([pack_seed, index]).generate_state(1)[0])


def plan_pack(
    n: int, pack_seed: int, realistic: bool = True, model: str = "two_track", only: str | None = None
) -> list[CaseSpec]:
    """The cases: each one's effect (``only``: that effect in every case, its size drawn from its
    range — a pack of 'none' counts false alarms), and with ``realistic`` a test day's
    imperfections and a handbook config (its C1n and C2n each ±20 % off the car's), every draw
    from a random stream of its own, so the effects do not depend on whether the pack is realistic."""
    names = commonroad.EFFECTS if model == "commonroad" else EFFECT_NAMES
    if only is not None:
        if only not in names:
            raise C2nError(f"--effect {only}: the {model} model cannot carry it (it can: {', '.join(names)})")
        names = (only,)
    cases = []
    for index in range(1, n + 1):
        seed = case_seed(pack_seed, index)
        effect = draw_effect(np.random.default_rng([seed, _EFFECT_STREAM]), names)
        if realistic:
            imperfections = of_session(seed)
            factors = handbook(np.random.default_rng([seed, _HANDBOOK_STREAM]), 1.0, 1.0)
            cases.append(CaseSpec(f"case_{index:03d}", seed, effect, imperfections, factors))
        else:
            cases.append(CaseSpec(f"case_{index:03d}", seed, effect))
    return cases


def write_pack(
    out: Path,
    n: int,
    pack_seed: int,
    config_path: Path = DEFAULT_CONFIG,
    plan: StandardPlan = STANDARD_PLAN,
    workers: int | None = None,
    on_case: Callable[[CaseResult], None] | None = None,
    clock: Callable[[], float] = time.perf_counter,
    realistic: bool = True,
    model: str = "two_track",
    only: str | None = None,
) -> PackResult:
    """Write the pack into ``out`` (new or empty); ``on_case`` hears of each case as it is done.
    ``realistic``: every case carries a test day's imperfections and a handbook config."""
    if n < 1:
        raise C2nError(f"a pack needs at least one case, not {n}")
    if out.exists() and (not out.is_dir() or any(out.iterdir())):
        raise OutputError(f"{out}: exists and is not an empty folder — choose a new one")
    config_text = _portable_config(Path(config_path))
    load_config(config_path)  # a bad config fails here, once, not in every worker
    specs = plan_pack(n, pack_seed, realistic, model, only)
    start = clock()
    # written in a hidden folder beside ``out``, renamed to it when whole: a Ctrl-C, a kill or a
    # full disk leaves no half pack under its name
    with folder_atomically(out, lambda path: False, "c2n simulate", replace=False) as staging:
        results = _write_cases(staging, specs, config_path, plan, config_text, model, workers, on_case)
        truth = {
            "pack_seed": pack_seed,
            "n": n,
            "config": str(Path(config_path).resolve()),
            "realistic": realistic,
            "model": model,
            "cases": {result.name: result.truth for result in results},
        }
        write_json(staging / "sealed" / "truth.json", truth, "the sealed truth")
    cases = tuple(replace(result, log=out / result.name / LOG_NAME) for result in results)
    return PackResult(out, cases, out / "sealed" / "truth.json", clock() - start)


def _write_cases(
    out: Path,
    specs: list[CaseSpec],
    config_path: Path,
    plan: StandardPlan,
    config_text: str | None,
    model: str,
    workers: int | None,
    on_case: Callable[[CaseResult], None] | None,
) -> list[CaseResult]:
    n = len(specs)
    jobs = [(Path(config_path), out / spec.name, spec, plan, config_text, model) for spec in specs]
    workers = max(1, min(workers or os.cpu_count() or 1, n))
    results: list[CaseResult] = []
    if workers == 1:
        for job in jobs:
            results.append(_write_case(*job))
            if on_case:
                on_case(results[-1])
    else:
        executor = ProcessPoolExecutor(max_workers=workers, initializer=ends_with_parent)
        try:
            futures: list[Future[CaseResult]] = [executor.submit(_write_case, *job) for job in jobs]
            for future in as_completed(futures):
                results.append(future.result())
                if on_case:
                    on_case(results[-1])
        finally:
            executor.shutdown(wait=True, cancel_futures=True)
    results.sort(key=lambda result: result.name)
    return results


def _write_case(
    config_path: Path, folder: Path, spec: CaseSpec, plan: StandardPlan, config_text: str | None, model: str
) -> CaseResult:
    start = time.perf_counter()
    config = load_config(config_path)
    options = StandardOptions(
        seed=spec.seed,
        effect=spec.effect,
        plan=plan,
        imperfections=spec.imperfections,
        model="commonroad" if model == "commonroad" else "two_track",
    )
    nominal: dict[str, float] = {}
    if spec.handbook is not None:  # the case's config: the car's tyres as a handbook gives them
        c1n, c2n = config.tyres.c1n_per_rad, config.tyres.c2n_per_rad
        if c1n is None or c2n is None:
            raise ConfigError(f"{config_path}: a realistic pack needs [tyres] c1n_per_rad and c2n_per_rad")
        nominal = {"c1n_per_rad": c1n * spec.handbook[0], "c2n_per_rad": c2n * spec.handbook[1]}
        options = replace(options, plan_c2n=nominal["c2n_per_rad"])
        config_text = _with_tyres(config_text or _portable_config(config_path, force=True) or "", nominal)
        config_text = _with_tolerance(config_text, 100.0 * HANDBOOK_SPREAD)
    drive = simulate_standard(config, options)
    folder.mkdir(parents=True, exist_ok=True)
    log = folder / LOG_NAME
    write_log(drive.messages, log)
    if config_text is not None:
        write_text(folder / "config.toml", config_text, "the case's config")
    truth = {"case": spec.name, "log": f"{spec.name}/{LOG_NAME}"} | drive.truth
    if nominal:
        truth["config_tyres"] = nominal  # what the case's config says; "c1n", "c2n": the car's
    return CaseResult(
        spec.name, log, float(truth["duration_s"]), len(drive.messages), time.perf_counter() - start, truth
    )


def _with_tyres(text: str, tyres: dict[str, float]) -> str:
    """The config text with its [tyres] values replaced."""
    for key, value in tyres.items():
        text, found = re.subn(rf"(?m)^(\s*{key}\s*=\s*)[-+0-9.eE]+", rf"\g<1>{value:.4f}", text)
        if not found:
            raise ConfigError(f"the config has no [tyres] {key} to perturb")
    return text


def _with_tolerance(text: str, pct: float) -> str:
    """The config text saying how well its [tyres] C2n is known (a handbook's figure)."""
    line = f"c2n_tolerance_pct = {pct:g}  # a handbook's figure, not a rig's"
    text, found = re.subn(r"(?m)^\s*c2n_tolerance_pct\s*=.*$", line, text)
    if not found:
        text = re.sub(r"(?m)^(\s*c2n_per_rad\s*=.*)$", rf"\g<1>\n{line}", text, count=1)
    return text


def write_log(messages: list[can.Message], log: Path) -> None:
    """The frames alone, in the format the suffix names (no truth, no comments)."""
    try:
        with can.Logger(log) as writer:
            for message in messages:
                writer.on_message_received(message)
    except OSError as error:
        raise OutputError(f"{log}: cannot write ({error.strerror})") from error


def _portable_config(path: Path, force: bool = False) -> str | None:
    """None for the default config (cases need no config of their own) unless ``force``;
    otherwise its text with the DBC paths made absolute, so it works from the case's folder."""
    if path.resolve() == DEFAULT_CONFIG.resolve() and not force:
        return None
    try:
        text = path.read_text()
        table = tomllib.loads(text)
    except (OSError, tomllib.TOMLDecodeError) as error:
        raise ConfigError(f"{path}: cannot read ({error})") from error
    files = table.get("dbc", {}).get("files", [])
    for name in files if isinstance(files, list) else []:
        if isinstance(name, str) and not Path(name).is_absolute():
            absolute = (path.parent / name).resolve()
            text = text.replace(f'"{name}"', json.dumps(str(absolute))).replace(
                f"'{name}'", json.dumps(str(absolute))
            )
    return text
