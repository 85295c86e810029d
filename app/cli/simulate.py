"""``c2n simulate``: a simulated test drive written as a CAN log, with its truth beside it.

``--scenario`` drives the bicycle model; ``--session standard|track|circles`` drives a test session
on the two-track model (or CommonRoad's, ``--model``) with one unmodelled effect (``--effect``):
the standard session (speed sweeps through u0 on three radii, step steers), laps of a circuit
(quasi-steady corners above u0, no sweep through it) or circles at one speed (d and C2n cannot be
told apart); ``--pack N`` writes N standard sessions, each with a random effect, as a blind pack
whose truth is sealed in DIR/sealed/.
"""

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from rich.console import Console
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TaskID, TextColumn, TimeElapsedColumn

from app.cli.common import SEED, add_config, add_force, number, path_argument
from app.config import COMMONROAD_CONFIG, DEFAULT_CONFIG, load_config
from app.errors import C2nError
from app.output.paths import Output, check, config_files, never
from app.sim.effects import EFFECT_NAMES, EFFECTS, Effect
from app.sim.scenarios import SCENARIOS
from app.user_text import shown

if TYPE_CHECKING:
    from app.sim.pack import CaseResult
    from app.sim.standard import StandardPlan

SESSIONS = {
    "standard": "speed swept through u0 on three radii both ways, step steers (~9 min)",
    "track": "laps of a circuit: corners at 1.2–2.4·u0 and 1–4.4 m/s², no sweep through u0 (~9 min)",
    "circles": "three radii both ways at one speed (1.25·u0): d and C2n cannot be told apart (~5 min)",
}
# options of the bicycle-model path, with their defaults: sessions take effects instead
_SCENARIO_ONLY = {
    "tyre": "linear",
    "mu": 1.0,
    "sweep_rate": 0.3,
    "ay_max": 3.5,
    "misalignment": 0.0,
    "speed_scale": 1.0,
    "speed_latency": 0.0,
}
# options of a single drive that a pack does not take (its cases all use the config as it is)
_DRIVE_ONLY = {
    "c2n": None,
    "optical_hz": 100.0,
    "noise": 0.02,
    "sensor_lateral": None,
    "single_channel": False,
}


_OPTICAL_HZ = 100.0


def add_parser(subparsers: "argparse._SubParsersAction[argparse.ArgumentParser]") -> argparse.ArgumentParser:
    parser = subparsers.add_parser(
        "simulate", help="write a simulated test drive as a CAN log", description=__doc__
    )
    parser.add_argument(
        "--scenario", choices=sorted(SCENARIOS), help="bicycle-model manoeuvre (default: constant_radius)"
    )
    parser.add_argument(
        "--session",
        choices=tuple(SESSIONS),
        help="a test session on --model's generator: "
        + "; ".join(f"{name}: {what}" for name, what in SESSIONS.items()).replace("%", "%%"),
    )
    parser.add_argument(
        "--pack",
        type=number(1, 10000, integer=True),
        metavar="N",
        help="write N standard sessions with random effects (--effect: that one in each) into --out DIR",
    )
    parser.add_argument(
        "--campaign",
        type=number(1, 10000, integer=True),
        metavar="N",
        help="write N drives of three tyre sets (known C2n, day-to-day scatter) with their manifest.csv "
        "into --out DIR, for c2n campaign",
    )
    parser.add_argument(
        "--effect",
        choices=EFFECT_NAMES,
        metavar="NAME",
        help=f"unmodelled effect of the session: {', '.join(EFFECT_NAMES)}",
    )
    parser.add_argument(
        "--effect-size",
        type=number(-1e3, 1e3),
        metavar="X",
        help="its size in its unit ("
        + ", ".join(f"{name} {spec.unit}".replace("%", "%%") for name, spec in EFFECTS.items() if spec.unit)
        + "; default: the middle of its range)",
    )
    parser.add_argument(
        "--quick", action="store_true", help="a shortened session (smoke tests; too coarse for a diagnosis)"
    )
    parser.add_argument(
        "--workers",
        type=number(1, 64, integer=True),
        metavar="N",
        help="pack: processes (default: CPU count)",
    )
    parser.add_argument(
        "--model",
        choices=("two_track", "commonroad"),
        default="two_track",
        help="session/pack generator: our two-track model, or CommonRoad's multi-body model (a model "
        "nobody here wrote; pip install -e '.[crosscheck]'; its default config is "
        "config/commonroad_vehicle2.toml) (default: two_track)",
    )
    day = parser.add_mutually_exclusive_group()
    day.add_argument(
        "--realistic",
        dest="realistic",
        action="store_true",
        default=None,
        help="a real test day: gyro bias, steering offset, a steering ratio and tyres a few %% off, "
        "mixed sensor rates; a pack's cases also get a handbook config (C1n, C2n ±20 %%) "
        "(default for --pack)",
    )
    day.add_argument(
        "--ideal",
        dest="realistic",
        action="store_false",
        help="no imperfections and the config's exact tyres (default for --session)",
    )
    parser.add_argument(
        "--out",
        type=path_argument,
        metavar="LOG",
        help="log to write (.blf, .asc, .log, .csv, .mf4, .trc); with --pack a new folder",
    )
    parser.add_argument(
        "--seed",
        type=SEED,
        default=0,
        metavar="N",
        help="seed of the noise (and of a pack's or campaign's cases)",
    )
    add_config(parser)
    add_force(parser)
    parser.add_argument(
        "--c2n",
        type=number(0.0, 200.0, low_allowed=False),
        metavar="X",
        help="true C2n [1/rad] (default: the config's [tyres])",
    )
    parser.add_argument(
        "--tyre", choices=("linear", "magic"), default="linear", help="linear or saturating tyres"
    )
    parser.add_argument(
        "--mu", type=number(0.1, 3.0), default=1.0, help="peak friction of the saturating tyre"
    )
    parser.add_argument(
        "--sweep-rate", type=number(0.01, 5.0), default=0.3, metavar="MPS2", help="speed sweep rate"
    )
    parser.add_argument(
        "--ay-max",
        type=number(0.1, 10.0),
        default=3.5,
        metavar="MPS2",
        help="lateral acceleration at the top speed",
    )
    parser.add_argument(
        "--optical-hz", type=number(50.0, 250.0), default=_OPTICAL_HZ, help="optical sensor rate (50–250)"
    )
    parser.add_argument(
        "--noise", type=number(0.0, 1.0), default=0.02, metavar="MPS", help="optical velocity noise (σ)"
    )
    parser.add_argument(
        "--sensor-lateral",
        type=number(-3.0, 3.0),
        metavar="M",
        help="true sensor offset left of the centre line",
    )
    parser.add_argument(
        "--misalignment",
        type=number(-10.0, 10.0),
        default=0.0,
        metavar="DEG",
        help="sensor head yawed left by DEG",
    )
    parser.add_argument("--speed-scale", type=number(0.5, 1.5), default=1.0, help="vehicle speed scale error")
    parser.add_argument(
        "--speed-latency", type=number(0.0, 2.0), default=0.0, metavar="S", help="vehicle speed delay"
    )
    parser.add_argument(
        "--single-channel", action="store_true", help="sensor and vehicle frames on one channel"
    )
    parser.set_defaults(run=run)
    return parser


def run(args: argparse.Namespace, console: Console) -> int:
    if args.model == "commonroad" and args.config == DEFAULT_CONFIG:
        args.config = COMMONROAD_CONFIG  # the CommonRoad car's own
    if args.campaign is not None:
        return _run_campaign(args, console)
    if args.pack is not None or args.session is not None:
        _check_session_options(args)
        return _run_pack(args, console) if args.pack is not None else _run_session(args, console)
    if args.model != "two_track":
        raise C2nError("--model is for --session standard or --pack N (scenarios drive the bicycle model)")
    if args.effect is not None or args.effect_size is not None or args.quick or args.realistic is not None:
        raise C2nError(
            "--effect, --effect-size, --quick, --realistic and --ideal need --session standard or --pack N"
        )
    from app.sim.simulated_drive import DriveOptions, describe, simulate_drive, write_drive

    args.scenario = args.scenario or "constant_radius"
    config = load_config(args.config)
    sensor: dict[str, object] = {
        "optical_hz": args.optical_hz,
        "sigma_velocity_mps": args.noise,
        "yaw_misalignment_deg": args.misalignment,
        "speed_scale": args.speed_scale,
        "speed_latency_s": args.speed_latency,
    }
    if args.sensor_lateral is not None:
        sensor["lateral_m"] = args.sensor_lateral
    if args.single_channel:
        sensor["sensor_channel"] = 0
    options = DriveOptions(
        scenario=args.scenario,
        seed=args.seed,
        c2n=args.c2n,
        tyre=args.tyre,
        mu=args.mu,
        sweep_mps2=args.sweep_rate,
        ay_max_mps2=args.ay_max,
        sensor=sensor,
    )
    out = args.out or Path(f"sim-{args.scenario}-seed{args.seed}.blf")
    _check_log(out, config, args.force)
    with console.status(f"simulating the {args.scenario} drive…"):
        drive = simulate_drive(config, options)
        truth = write_drive(drive, out)
    console.print(f"wrote {shown(out)} and {shown(truth.name)}: {describe(drive.truth)}")
    return 0


def _check_log(out: Path, config: object, force: bool) -> None:
    """A log and its truth: never an input, never an existing file unless ``--force``; a log
    format c2n writes (said before the drive is simulated, not after)."""
    from app.errors import LogFileError
    from app.sim.simulated_drive import LOG_SUFFIXES, truth_path

    outputs = [Output("--out", out, never)]
    if out != Path("-"):
        outputs.append(Output("--out (its truth beside it)", truth_path(out), never))
    check(outputs, config_files(config), force)
    if out.suffix.lower() not in LOG_SUFFIXES:
        raise LogFileError(f"{out}: unknown log format '{out.suffix}' — use one of {', '.join(LOG_SUFFIXES)}")


def _check_folder(out: Path, args: argparse.Namespace) -> None:
    """A pack's or a campaign's folder: new or empty, never holding the config or its DBCs."""
    check([Output("--out", out, never, folder=True)], config_files(load_config(args.config)))


def _check_session_options(args: argparse.Namespace) -> None:
    if args.scenario is not None:
        raise C2nError("--scenario drives the bicycle model: leave it out with --session or --pack")
    for option, default in _SCENARIO_ONLY.items():
        if getattr(args, option) != default:
            flag = "--" + option.replace("_", "-")
            raise C2nError(f"{flag} is for --scenario; sessions take --effect NAME --effect-size X")
    if args.pack is not None:
        for option, default in _DRIVE_ONLY.items():
            if getattr(args, option) != default:
                flag = "--" + option.replace("_", "-")
                raise C2nError(f"{flag} is for a single --session; a pack's cases use the config as it is")
    if args.effect_size is not None and args.effect is None:
        raise C2nError("--effect-size needs --effect NAME")
    if args.effect_size is not None and args.pack is not None:
        raise C2nError("--effect-size is for one --session; a pack draws its sizes from the effect's range")
    if args.pack is not None and args.session not in (None, "standard"):
        raise C2nError(f"--pack writes standard sessions: leave out --session {args.session}")


def _plan(args: argparse.Namespace) -> "StandardPlan":
    from app.sim.standard import QUICK_PLAN, STANDARD_PLAN

    return QUICK_PLAN if args.quick else STANDARD_PLAN


def _run_session(args: argparse.Namespace, console: Console) -> int:
    from app.sim.imperfections import NO_IMPERFECTIONS, of_session
    from app.sim.laps_and_circles import CIRCLES_PLAN, QUICK_CIRCLES_PLAN, QUICK_TRACK_PLAN, TRACK_PLAN
    from app.sim.simulated_drive import describe, write_drive
    from app.sim.standard import StandardOptions, simulate_standard

    config = load_config(args.config)
    effect = Effect.of(args.effect or "none", 0.0 if args.effect in (None, "none") else args.effect_size)
    sensor: dict[str, object] = {"sigma_velocity_mps": args.noise}
    if not args.realistic or args.optical_hz != _OPTICAL_HZ:  # a test day's rate, unless one is given
        sensor["optical_hz"] = args.optical_hz
    if args.sensor_lateral is not None:
        sensor["lateral_m"] = args.sensor_lateral
    if args.single_channel:
        sensor["sensor_channel"] = 0
    imperfections = of_session(args.seed) if args.realistic else NO_IMPERFECTIONS
    options = StandardOptions(
        seed=args.seed,
        effect=effect,
        c2n=args.c2n,
        plan=_plan(args),
        sensor=sensor,
        imperfections=imperfections,
        model=args.model,
        session=args.session,
        track_plan=QUICK_TRACK_PLAN if args.quick else TRACK_PLAN,
        circles_plan=QUICK_CIRCLES_PLAN if args.quick else CIRCLES_PLAN,
    )
    out = args.out or Path(f"sim-{args.session}-seed{args.seed}.blf")
    _check_log(out, config, args.force)
    with console.status(f"simulating the {args.session} session on the {args.model} model…"):
        drive = simulate_standard(config, options)
        truth = write_drive(drive, out)
    console.print(f"wrote {shown(out)} and {shown(truth.name)}: {effect.describe()}, {describe(drive.truth)}")
    return 0


def _run_pack(args: argparse.Namespace, console: Console) -> int:
    from app.sim.pack import write_pack

    if args.pack < 1:
        raise C2nError(f"--pack needs at least one case, not {args.pack}")
    out = args.out or Path(f"pack-seed{args.seed}")
    _check_folder(out, args)
    progress, task = _counting(console, args.pack)

    def done(case: "CaseResult") -> None:
        # nothing about the effect: whoever makes the pack stays blind too
        progress.console.print(
            f"{shown(out / case.name)}: {case.duration_s:.0f} s of driving, {case.frames:,} frames "
            f"({case.elapsed_s:.1f} s)"
        )
        progress.advance(task)

    with progress:
        realistic = True if args.realistic is None else args.realistic
        result = write_pack(
            out,
            args.pack,
            args.seed,
            args.config,
            _plan(args),
            args.workers,
            done,
            realistic=realistic,
            model=args.model,
            only=args.effect,
        )
    console.print(
        f"wrote {len(result.cases)} cases to {shown(out)} in {result.elapsed_s:.1f} s; "
        f"truth sealed in {shown(result.truth_path)}"
    )
    return 0


def _run_campaign(args: argparse.Namespace, console: Console) -> int:
    from app.sim.tyre_programme import write_campaign

    if args.pack is not None or args.session is not None or args.scenario is not None:
        raise C2nError("--campaign writes drives of its own: leave out --pack, --session and --scenario")
    out = args.out or Path(f"campaign-seed{args.seed}")
    _check_folder(out, args)
    progress, task = _counting(console, args.campaign)
    with progress:
        manifest = write_campaign(
            out, args.campaign, args.seed, args.config, args.workers, lambda spec, s: progress.advance(task)
        )
    console.print(
        f"wrote {args.campaign} drives and {shown(manifest)}; "
        f"truth sealed in {shown(out / 'sealed' / 'truth.json')} — "
        f"next: c2n campaign {shown(manifest)} --by tyre_set"
    )
    return 0


def _counting(console: Console, total: int) -> tuple[Progress, TaskID]:
    """A bar of drives simulated, on a terminal."""
    progress = Progress(
        TextColumn("simulating"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        disable=not console.is_terminal,
    )
    return progress, progress.add_task("", total=total)
