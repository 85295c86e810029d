"""Performance on a saturated bus and offline, each figure the median (min, max) of several runs.

1. live throughput: frames/s through the live loop (bus, decode, filter, detect, recorder) from a
   pre-filled python-can ``virtual`` bus carrying a saturated 1 Mbit/s mix, as a multiple of
   9,009 frames/s;
2. CPU share of the process while the mix arrives in real time, dashboard refreshed at 10 Hz into
   a pseudo-terminal: the live loop, python-can's receive thread and the dashboard; the feeder
   thread (standing in for the driver) is measured apart and left out;
3. latency from a frame's arrival on the bus to the estimate it updates: p50 and p99;
4. offline: ``c2n analyze`` on a 1,000,000-frame BLF and the same drive as MF4, against a loop that
   only iterates python-can's reader over the same file;
5. memory: peak RSS of a 10-minute and an 8-hour session (accelerated, each in its own process);
   and the compiled motion filter against the reference on filterpy's KalmanFilter, and what each
   stage costs a frame, with a refit of the regression under each estimator (``parts``);
6. startup: wall time and peak RSS of ``c2n --help`` and ``c2n analyze --help``, each in a fresh
   process, and what an install of c2n weighs, alone and with each extra: the files of every
   distribution it needs, from this venv's records, and the launch-to-first-frame time of
   ``c2n live`` (``startup``);
8. gap: ``c2n gap`` on a simulated 10-minute standard session (two-track model, a test day), in a
   fresh process with its CPU count, reading the log included, per 10 minutes of driving; the log
   read alone into the pipeline's blocks; and the diagnosis alone, the log read once (``gap``, not
   in the default set: ``--only gap``).
7. campaign: ``c2n campaign`` on simulated drives: frames/s per worker on 1 and 2 local workers
   against a lone analysis of the same files, the re-run with nothing changed, and the workers'
   peak RSS (``campaign``, not in the default set: ``--only campaign``).

The mix: the optical sensor at 250 Hz (three messages), the vehicle messages at their cycle
times, and 96 background ids at about 81 Hz each, 9,009 frames/s in all.

    python tools/bench.py [--runs 5] [--only kernel,parts,live,cpu,offline,memory,startup] [--hours 8]
    python tools/bench.py --only campaign [--campaign-sessions 8]
    python tools/bench.py --only gap [--runs 3]
"""

import argparse
import contextlib
import copy
import io
import json
import os
import pty
import resource
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import replace
from importlib import metadata
from pathlib import Path
from typing import Any

import can
import numpy as np
from packaging.requirements import Requirement
from packaging.utils import canonicalize_name
from rich.console import Console

from app.cli import main as c2n
from app.config import Config, load_config
from app.pipeline import PartedPipeline, Pipeline
from app.records import Record
from app.run_loop import run
from app.sim.simulated_drive import DriveOptions, simulate_drive
from app.sinks.dashboard import Dashboard
from app.sinks.recorder import SessionRecorder, _CandumpWriter
from app.sinks.sink import Sink
from app.sources.buses import BusSource

SATURATED_FPS = 9009
BACKGROUND_IDS = range(0x300, 0x360)


def saturated_mix(seconds: float, seed: int = 1) -> list[can.Message]:
    """A simulated drive with the optical sensor at 250 Hz, filled up to 9,009 frames/s."""
    config = load_config()
    drive = simulate_drive(config, DriveOptions(seed=seed, sensor={"optical_hz": 250.0}))
    start = drive.messages[0].timestamp
    period = drive.truth["duration_s"] + 0.01
    messages = []
    for k in range(int(seconds // period) + 1):  # the drive over and over, as long as asked
        messages += [
            can.Message(
                timestamp=m.timestamp + k * period,
                arbitration_id=m.arbitration_id,
                is_extended_id=m.is_extended_id,
                data=m.data,
                channel=m.channel,
            )
            for m in drive.messages
            if m.timestamp + k * period < start + seconds
        ]
    rng = np.random.default_rng(seed)
    n = int(seconds * SATURATED_FPS) - len(messages)
    times = np.sort(rng.uniform(start, start + seconds, n)).tolist()
    ids = rng.choice(np.array(BACKGROUND_IDS), n).tolist()
    payload = rng.integers(0, 256, (n, 8), dtype=np.uint8)
    messages += [
        can.Message(timestamp=t, arbitration_id=i, data=bytes(payload[k]), channel=0)
        for k, (t, i) in enumerate(zip(times, ids, strict=True))
    ]
    messages.sort(key=lambda m: m.timestamp)
    return messages


def summary(values: list[float], unit: str, scale: float = 1.0, digits: int = 0) -> str:
    def f(v: float) -> str:
        return f"{v * scale:,.{digits}f}"

    return f"{f(statistics.median(values))} {unit} (min {f(min(values))}, max {f(max(values))})"


# -- 1. live throughput ---------------------------------------------------------------------------


class _NoPipeline:
    """For the floor of the live loop: the frames are read and recorded, nothing else."""

    def __init__(self) -> None:
        self.decoder = self

    def decode(self, msg: can.Message) -> None:
        return None

    def take(self, record: Record) -> Record:
        return record

    def finish(self) -> list[object]:
        return []


def live_throughput(messages: list[can.Message], floor: bool = False) -> float:
    """Frames/s through the live loop; ``floor``: with no pipeline (bus and recorder only)."""
    config = load_config()
    rx = can.Bus(interface="virtual", channel="bench", preserve_timestamps=True)
    tx = can.Bus(interface="virtual", channel="bench", preserve_timestamps=True)
    for message in messages:
        tx.send(message)
    finished = threading.Event()
    finished.set()  # everything is on the bus already: end when it is drained
    pipeline = PartedPipeline(config)  # c2n live's
    with tempfile.TemporaryDirectory() as tmp:
        recorder = SessionRecorder(Path(tmp) / "session", config)
        start = time.perf_counter()
        run(
            BusSource([rx], threading.Event(), finished, idle_s=0.01),
            _NoPipeline() if floor else pipeline,  # type: ignore[arg-type]
            [recorder],
        )
        elapsed = time.perf_counter() - start
        with recorder.raw_path.open() as recording:
            assert sum(1 for _ in recording) == len(messages)
    for bus in (rx, tx):
        bus.shutdown()
    assert floor or pipeline.decoder.counts.total == len(messages)
    return len(messages) / elapsed


# -- 2, 3. real time: CPU share and latency -------------------------------------------------------


def _feed(bus: can.BusABC, messages: list[can.Message], cpu: list[float], done: threading.Event) -> None:
    """Deliver each frame when it is due (in 1-ms batches), stamped on arrival as a driver would
    stamp it. The frames go straight onto the receiving virtual bus's queue: python-can's ``send``
    deep-copies every frame, which would cost this thread more than the whole live loop."""
    arrivals = bus.queue  # type: ignore[attr-defined]  # python-can's VirtualBus
    begin = time.perf_counter()
    t0 = messages[0].timestamp
    thread_start = time.thread_time()
    k = 0
    while k < len(messages):
        now = time.perf_counter() - begin
        while k < len(messages) and messages[k].timestamp - t0 <= now:
            message = messages[k]
            message.timestamp = time.time()
            arrivals.put(message)
            k += 1
        time.sleep(0.001)
    cpu.append(time.thread_time() - thread_start)
    done.set()


def _drain(fd: int) -> None:
    with contextlib.suppress(OSError):
        while os.read(fd, 65536):
            pass


def real_time(messages: list[can.Message]) -> tuple[float, list[float]]:
    """(CPU share of the process less the feeder thread — the live loop, python-can's receive
    thread, the dashboard — and the latencies in s of the records with an estimate)."""
    config = load_config()
    master, slave = pty.openpty()
    threading.Thread(target=_drain, args=(master,), daemon=True).start()
    terminal = open(slave, "w", buffering=1)  # noqa: SIM115 — closed below, after the run
    console = Console(file=terminal, force_terminal=True, width=120, height=50)
    rx = can.Bus(interface="virtual", channel="realtime")
    pipeline = PartedPipeline(config)  # c2n live's
    latencies: list[float] = []

    class Latency(Sink):
        def on_record(self, record: Record) -> None:
            if record.estimate is not None:
                latencies.append(time.time() - record.t)

    feeder_cpu: list[float] = []
    finished = threading.Event()
    feeder = threading.Thread(target=_feed, args=(rx, [m.__copy__() for m in messages], feeder_cpu, finished))
    with tempfile.TemporaryDirectory() as tmp:
        recorder = SessionRecorder(Path(tmp) / "session", config)
        wall, cpu = time.perf_counter(), time.process_time()
        feeder.start()
        run(
            BusSource([rx], threading.Event(), finished),
            pipeline,
            [recorder, Latency()],
            display=Dashboard("bench"),
            console=console,
        )
        feeder.join()
        elapsed = time.perf_counter() - wall
        share = (time.process_time() - cpu - feeder_cpu[0]) / elapsed
    terminal.close()
    os.close(master)
    rx.shutdown()
    print(f"   (the feeder thread, left out: {100 * feeder_cpu[0] / elapsed:.1f} % of a core)")
    return share, latencies


# -- 4. offline -------------------------------------------------------------------------------------


def write_logs(messages: list[can.Message], folder: Path) -> tuple[Path, Path]:
    blf, mf4 = folder / "drive.blf", folder / "drive.mf4"
    for path in (blf, mf4):
        with can.Logger(path) as writer:
            for message in messages:
                writer.on_message_received(message)
    return blf, mf4


def bare_read(log: Path) -> float:
    start = time.perf_counter()
    frames = sum(1 for _ in can.LogReader(log))
    return frames / (time.perf_counter() - start)


def analyze(log: Path, frames: int) -> float:
    out = io.StringIO()
    start = time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        code = c2n(["analyze", str(log), "--json", str(log.with_suffix(".json"))])
    elapsed = time.perf_counter() - start
    assert code == 0, out.getvalue()
    return frames / elapsed


# -- 5. memory --------------------------------------------------------------------------------------


def lengthened(seconds: float) -> Iterator[can.Message]:
    """A simulated drive (optical sensor and vehicle bus at 50 Hz, 450 frames/s) repeated for
    ``seconds``, made as it is consumed: what grows with the session, not with the rate."""
    sensors = {"optical_hz": 50.0, "vehicle_hz": 50.0}
    drive = simulate_drive(load_config(), DriveOptions(seed=2, sensor=sensors))
    period = drive.truth["duration_s"] + 0.01
    start = drive.messages[0].timestamp
    k = 0
    while True:
        for m in drive.messages:
            t = m.timestamp + k * period
            if t - start >= seconds:
                return
            yield can.Message(timestamp=t, arbitration_id=m.arbitration_id, data=m.data, channel=m.channel)
        k += 1


def session_memory(seconds: float) -> None:
    """Child process: one accelerated session; prints frames and peak RSS (MiB)."""
    config = load_config()
    pipeline = Pipeline(config)
    with tempfile.TemporaryDirectory() as tmp:
        recorder = SessionRecorder(Path(tmp) / "session", config)
        run(lengthened(seconds), pipeline, [recorder])
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(pipeline.decoder.counts.total, f"{peak:.1f}")


def memory(seconds: float) -> tuple[int, float]:
    out = subprocess.run(
        [sys.executable, __file__, "--session-memory", str(seconds)],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    return int(out[0]), float(out[1])


# -- 6. startup -------------------------------------------------------------------------------------

C2N = Path(sys.executable).with_name("c2n")


# Started from a small process: a child's peak RSS counts the pages of the process that spawned
# it (Linux keeps the high-water mark across exec), and this benchmark's are ~240 MiB.
_TIMER = """
import json, os, sys, time
argv, runs = json.loads(sys.argv[1]), int(sys.argv[2])
null = os.open(os.devnull, os.O_WRONLY)
actions = [(os.POSIX_SPAWN_DUP2, null, 1), (os.POSIX_SPAWN_DUP2, null, 2)]
out = []
for _ in range(runs):
    start = time.perf_counter()
    pid = os.posix_spawn(argv[0], argv, os.environ, file_actions=actions)
    _, status, usage = os.wait4(pid, 0)
    out.append((time.perf_counter() - start, usage.ru_maxrss / 1024, os.waitstatus_to_exitcode(status)))
print(json.dumps(out))
"""


def startup(argv: list[str], runs: int) -> list[tuple[float, float]]:
    """Wall time (s) and peak RSS (MiB) of ``runs`` fresh ``c2n`` processes, one after another."""
    timer = [sys.executable, "-c", _TIMER, json.dumps(argv), str(runs)]
    child = subprocess.run(timer, capture_output=True, text=True, check=True)
    results = json.loads(child.stdout)
    assert all(code == 0 for _, _, code in results), f"{argv}: {results}"
    return [(wall, rss) for wall, rss, _ in results]


# A fresh `c2n live` on a virtual bus that a thread of the same process fills from the start:
# the time from the launch to the first frame the pipeline takes (the numba cache warm).
_FIRST_FRAME = """
import os, sys, threading, time
channel = sys.argv[1]

def send():
    import can  # as c2n live imported it
    with can.Bus(interface="virtual", channel=channel) as bus:
        frame = can.Message(arbitration_id=0x7E5, is_extended_id=False, data=bytes(8))
        while True:
            bus.send(frame)
            time.sleep(0.002)

from app.cli import main
import app.cli.live as live
own = live.import_python_can

def then_send():  # the sender starts once c2n live has imported python-can its way
    own()
    import app.pipeline
    def first(self, record):
        print(time.time(), flush=True)
        os._exit(0)
    app.pipeline.Pipeline.take = first
    threading.Thread(target=send, daemon=True).start()

live.import_python_can = then_send
main(["live", "-i", "virtual", "-c", channel, "--no-record", "--duration", "30"])
"""


def first_frame(runs: int) -> list[float]:
    """Seconds from launching ``c2n live`` to the first frame through its pipeline."""
    out = []
    for k in range(runs):
        start = time.time()
        child = subprocess.run(
            [sys.executable, "-c", _FIRST_FRAME, f"bench-first-{os.getpid()}-{k}"],
            capture_output=True,
            text=True,
            check=True,
            timeout=60,
        )
        out.append(float(child.stdout.split()[-1]) - start)
    return out


def _installed_mb(name: str) -> float:
    files = metadata.distribution(name).files or []
    paths = (Path(str(f.locate())) for f in files)
    return sum(p.stat().st_size for p in paths if p.is_file()) / 1e6


def _closure(name: str, extras: frozenset[str] = frozenset()) -> set[str]:
    """The installed distributions ``name[extras]`` needs, itself included (normalised names)."""
    need, todo = set(), [(name, extras)]
    while todo:
        dist, wanted = todo.pop()
        key = canonicalize_name(dist)
        if (key, wanted) in need:
            continue
        need.add((key, wanted))
        for text in metadata.requires(dist) or []:
            req = Requirement(text)
            if req.marker is None or any(req.marker.evaluate({"extra": e}) for e in {"", *wanted}):
                todo.append((req.name, frozenset(req.extras)))
    return {key for key, _ in need}


def install_sizes() -> dict[str, float | None]:
    """MB installed for c2n alone and with each extra, from this venv's package records (None:
    the extra is not installed here)."""
    extras = metadata.metadata("c2n").get_all("Provides-Extra") or []
    sizes: dict[str, float | None] = {}
    for label, wanted in [("core", frozenset()), *((e, frozenset({e})) for e in extras)]:
        try:
            sizes[label] = sum(_installed_mb(n) for n in _closure("c2n", wanted))
        except metadata.PackageNotFoundError:
            sizes[label] = None
    return sizes


# -- the motion filter -------------------------------------------------------------------------------


def kernel_rates(runs: int) -> dict[str, list[float]]:
    from app.decode.decoder import Decoder
    from app.estimate.compiled import CompiledMotionFilter
    from app.estimate.reference import MotionFilter

    config = load_config()
    drive = simulate_drive(config, DriveOptions(seed=3))
    decoder = Decoder(config)
    records = [r for r in map(decoder.decode, drive.messages) if r is not None]
    rates: dict[str, list[float]] = {"fast": [], "filterpy": []}
    for _ in range(runs):
        for name, kind in (("fast", CompiledMotionFilter), ("filterpy", MotionFilter)):
            motion = kind(config.filter, 0.0, frozenset(config.roles))
            start = time.perf_counter()
            for record in records:
                motion.step(record)
            rates[name].append(len(records) / (time.perf_counter() - start))
    return rates


# -- where a frame's time goes ---------------------------------------------------------------------


_REFRESH = "dashboard refresh, 120×50"


def part_costs(messages: list[can.Message]) -> dict[str, float]:
    """µs a frame for each stage, on the frames that reach it."""
    from app.decode.decoder import Decoder
    from app.pipeline import _FILTER_ROLES

    config = load_config()
    background = [m for m in messages if m.arbitration_id in BACKGROUND_IDS]
    relevant = [m for m in messages if m.arbitration_id not in BACKGROUND_IDS]

    def per_frame(frames: list[Any], step: Callable[[Any], object]) -> float:
        start = time.perf_counter()
        for frame in frames:
            step(frame)
        return 1e6 * (time.perf_counter() - start) / len(frames)

    decoder = Decoder(config)
    costs = {"decode, background frame": per_frame(background, decoder.decode)}
    decoder = Decoder(config)
    records = [decoder.decode(m) for m in relevant]
    costs["decode, relevant frame"] = per_frame(relevant, Decoder(config).decode)
    steps = [r for r in records if r is not None and not _FILTER_ROLES.isdisjoint(r.signals)]
    costs["filter step"] = per_frame(steps, Pipeline(config).filter.step)
    pipeline = Pipeline(config)
    costs["whole pipeline, relevant frame"] = per_frame(relevant, pipeline.process)
    for message in background:
        pipeline.decoder.decode(message)  # the frame counts the dashboard shows
    console = Console(file=io.StringIO(), force_terminal=True, width=120, height=50)
    dashboard = Dashboard("bench")
    dashboard.on_snapshot(pipeline.snapshot())
    costs[_REFRESH] = per_frame(list(range(50)), lambda _: console.print(dashboard))  # µs a refresh
    costs.update(refit_costs(config))
    for name, writer in (
        ("candump line, c2n", _CandumpWriter),
        ("candump line, python-can", can.CanutilsLogWriter),
    ):
        lines: list[str] = []
        sink = type("Sink", (), {"write": lines.append, "flush": lambda self: None})()
        costs[name] = per_frame(messages, writer(sink).on_message_received)
    rx = can.Bus(interface="virtual", channel="parts", preserve_timestamps=True)
    tx = can.Bus(interface="virtual", channel="parts", preserve_timestamps=True)
    for message in messages:
        tx.send(message)
    costs["python-can virtual bus recv"] = per_frame(messages, lambda _: rx.recv(0))
    rx.shutdown()
    tx.shutdown()
    return costs


def refit_costs(config: Config) -> dict[str, float]:
    """µs a refit of the every-sample regression at the end of a whole simulated session (the
    demo's: 13,600 steady samples), each estimator: the median of 15 after one that imports what it
    needs, the two estimators' refits taken in turn, so that a busy spell of the machine falls on
    both. A refit runs every few seconds of a live session, never per frame; the saturated mix's
    20 s hold too few samples to stand for one (there the cascade's few solves take 0.8 ms, the
    marginal fit's two priors' passes 15 ms whatever the samples)."""
    drive = simulate_drive(config, DriveOptions(seed=1))
    pipeline = Pipeline(config)
    for message in drive.messages:
        pipeline.process(message)
    fits = {}
    for name, chosen in (("cascade", None), ("marginal", replace(config.priors, estimator="marginal"))):
        fitted = copy.copy(pipeline.regression)
        fitted.priors = chosen
        fitted.fit()
        fits[name] = fitted
    times: dict[str, list[float]] = {name: [] for name in fits}
    for _ in range(15):
        for name, fitted in fits.items():
            start = time.perf_counter()
            fitted.fit()
            times[name].append(time.perf_counter() - start)
    costs = {f"regression refit, {name}": 1e6 * statistics.median(taken) for name, taken in times.items()}
    return costs


def repeat(runs: int, fn: Callable[[], float]) -> list[float]:
    return [fn() for _ in range(runs)]


# -- 7. campaign ------------------------------------------------------------------------------------


def campaign_figures(sessions: int) -> dict[str, float]:
    """One measurement of ``c2n campaign`` on ``sessions`` simulated drives: a lone analysis of
    each file in this process, then the campaign on 1 and on 2 local workers (fresh each), and a
    re-run with nothing changed; the children's peak RSS."""
    from app.campaign import work
    from app.campaign.analysis import Job, analyse
    from app.campaign.manifest import read_manifest
    from app.sim.tyre_programme import write_campaign

    figures: dict[str, float] = {}
    with tempfile.TemporaryDirectory() as tmp:
        manifest_path = write_campaign(Path(tmp) / "programme", sessions, 5, workers=2)
        manifest = read_manifest(manifest_path)
        started = time.perf_counter()
        frames = sum(analyse(Job(e.log, None)).frames for e in manifest.entries)
        figures["lone analyze, frames/s"] = frames / (time.perf_counter() - started)
        for n in (1, 2):
            out = Path(tmp) / f"out{n}"
            started = time.perf_counter()
            rows = work.run_campaign(manifest, None, out, lambda n=n: work.local_workers(n))  # type: ignore[misc]
            elapsed = time.perf_counter() - started
            figures[f"{n} worker(s), sessions/s"] = sessions / elapsed
            figures[f"{n} worker(s), frames/s per worker"] = frames / elapsed / n
            figures[f"{n} worker(s), first run s"] = elapsed
            if n == 1:  # one worker analysed them all, in order: its peak after half and after all
                peaks = [row.worker_peak_mib or 0.0 for row in rows]
                figures["worker peak RSS after half, MiB"] = max(peaks[: len(peaks) // 2])
                figures["worker peak RSS after all, MiB"] = max(peaks)
        started = time.perf_counter()
        work.run_campaign(manifest, None, Path(tmp) / "out2", lambda: work.local_workers(2))
        figures["re-run with nothing changed, s"] = time.perf_counter() - started
    return figures


# -- 8. gap -----------------------------------------------------------------------------------------


def gap_figures(runs: int) -> dict[str, list[float]]:
    """``c2n gap`` on one simulated standard session (written once): the whole command per 10
    minutes of driving, the log read alone (into the pipeline's FrameBlocks, nothing decoded) and
    the diagnosis alone, ``runs`` times each."""
    from app.config import load_config
    from app.gap.diagnose import diagnose
    from app.gap.measured import measure
    from app.sim.standard import StandardOptions, simulate_standard
    from app.sources.logs import LogSource

    config = load_config()
    drive = simulate_standard(config, StandardOptions(seed=8))
    with tempfile.TemporaryDirectory() as tmp:
        log = Path(tmp) / "session.blf"
        with can.Logger(str(log)) as writer:
            for message in drive.messages:
                writer.on_message_received(message)
        minutes = float(drive.messages[-1].timestamp - drive.messages[0].timestamp) / 60.0
        whole = []
        for _ in range(runs):
            started = time.perf_counter()
            subprocess.run([str(C2N), "gap", str(log)], check=True, capture_output=True)
            whole.append((time.perf_counter() - started) * 10.0 / minutes)
        read = []
        for _ in range(runs):
            started = time.perf_counter()
            for _item in LogSource([log], triage=Pipeline(config).decoder).items(blocks=True):
                pass
            read.append((time.perf_counter() - started) * 10.0 / minutes)
        measured = measure([log], config)
        alone = []
        for _ in range(runs):
            started = time.perf_counter()
            diagnose(measured, config, workers=os.cpu_count() or 1)
            alone.append((time.perf_counter() - started) * 10.0 / minutes)
    return {
        "c2n gap, s per 10 min": whole,
        "the log read alone, s per 10 min": read,
        "diagnosis alone, s per 10 min": alone,
    }


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--only", default="kernel,parts,live,cpu,offline,memory,startup")
    parser.add_argument("--hours", type=float, default=8.0, help="the long session's length")
    parser.add_argument("--campaign-sessions", type=int, default=8, help="drives of the campaign figures")
    parser.add_argument("--session-memory", type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.session_memory is not None:
        session_memory(args.session_memory)
        return
    only = set(args.only.split(","))
    print(f"median (min, max) of {args.runs} runs; saturated mix = {SATURATED_FPS:,} frames/s")
    if "kernel" in only:
        kernels = kernel_rates(args.runs)
        print(f"motion filter, compiled      {summary(kernels['fast'], 'records/s')}")
        print(f"motion filter, on filterpy   {summary(kernels['filterpy'], 'records/s')}")
        ratios = [f / r for f, r in zip(kernels["fast"], kernels["filterpy"], strict=True)]
        print(f"  compiled / filterpy        {summary(ratios, '×', digits=1)}")
    if "parts" in only:
        messages = saturated_mix(20.0)
        costs = [part_costs(messages) for _ in range(args.runs)]
        for name in costs[0]:
            values = [c[name] for c in costs]
            per_frame = name != _REFRESH and not name.startswith("regression refit")
            shown = summary(values, "µs a frame", digits=2) if per_frame else summary(values, "ms", 1e-3, 2)
            print(f"   {name:31s}{shown}")
        ratios = [c["regression refit, marginal"] / c["regression refit, cascade"] for c in costs]
        print(f"   {'refit, marginal / cascade':31s}{summary(ratios, '×', digits=2)}  (goal ≤ 2×)")
    if "live" in only:
        messages = saturated_mix(20.0)
        rates = repeat(args.runs, lambda: live_throughput(messages))
        print(f"1. live throughput           {summary(rates, 'frames/s')}")
        print(
            f"   × {SATURATED_FPS:,} frames/s       {summary(rates, '×', 1 / SATURATED_FPS, 1)}  (goal ≥ 20×)"
        )
        floors = repeat(args.runs, lambda: live_throughput(messages, floor=True))
        print(f"   floor: bus + recorder only {summary(floors, 'frames/s')}")
        print(f"   × {SATURATED_FPS:,} frames/s       {summary(floors, '×', 1 / SATURATED_FPS, 1)}")
    if "cpu" in only:
        messages = saturated_mix(10.0)
        shares, p50, p99 = [], [], []
        for _ in range(args.runs):
            share, latencies = real_time(messages)
            shares.append(share)
            p50.append(float(np.percentile(latencies, 50)))
            p99.append(float(np.percentile(latencies, 99)))
        print(f"2. CPU, real time + dashboard {summary(shares, '% of a core', 100, 1)}  (goal ≤ 25 %)")
        print(f"3. latency p50               {summary(p50, 'ms', 1000, 2)}")
        print(f"   latency p99               {summary(p99, 'ms', 1000, 2)}  (goal < 5 ms)")
    if "offline" in only:
        messages = saturated_mix(1_000_000 / SATURATED_FPS)[:1_000_000]
        with tempfile.TemporaryDirectory() as tmp:
            blf, mf4 = write_logs(messages, Path(tmp))
            for log in (blf, mf4):
                bare = repeat(args.runs, lambda log=log: bare_read(log))  # type: ignore[misc]
                piped = repeat(args.runs, lambda log=log: analyze(log, len(messages)))  # type: ignore[misc]
                kind = log.suffix[1:].upper()
                print(f"4. {kind} bare python-can read {summary(bare, 'frames/s')}")
                print(f"   {kind} c2n analyze         {summary(piped, 'frames/s')}")
                ratio = [p / b for p, b in zip(piped, bare, strict=True)]
                print(f"   {kind} analyze / bare      {summary(ratio, '×', digits=2)}")
    if "memory" in only:
        short_frames, short = memory(600.0)
        long_frames, long = memory(args.hours * 3600.0)
        print(f"5. peak RSS, 10 min          {short:.1f} MiB ({short_frames:,} frames)")
        print(f"   peak RSS, {args.hours:g} h            {long:.1f} MiB ({long_frames:,} frames)")
        print(f"   growth                    {100 * (long / short - 1):+.1f} %  (goal within 10 %)")
    if "campaign" in only:
        runs = [campaign_figures(args.campaign_sessions) for _ in range(max(1, min(args.runs, 3)))]
        drives = f"{args.campaign_sessions} simulated drives (two circles, 100 Hz)"
        print(f"7. campaign of {drives}, {len(runs)} runs:")
        for name in runs[0]:
            print(f"   {name:38s}{summary([r[name] for r in runs], '', digits=2)}")
        lone = [r["lone analyze, frames/s"] for r in runs]
        for n in (1, 2):
            ratio = [r[f"{n} worker(s), frames/s per worker"] / x for r, x in zip(runs, lone, strict=True)]
            print(
                f"   {n} worker(s) per worker / lone analyze {summary(ratio, '×', digits=2)}  (goal ≥ 0.8×)"
            )
        scale = [r["2 worker(s), sessions/s"] / r["1 worker(s), sessions/s"] for r in runs]
        print(f"   2 workers / 1 worker                 {summary(scale, '×', digits=2)}  (goal ≥ 1.7×)")
        rerun = [r["re-run with nothing changed, s"] / r["2 worker(s), first run s"] for r in runs]
        print(f"   re-run / first run                   {summary(rerun, '%', 100, 1)}  (goal ≤ 5 %)")
    if "gap" in only:
        for name, values in gap_figures(max(args.runs, 3)).items():
            goal = "  (goal ≤ 10 s on 2 cores)" if name.startswith("c2n gap") else ""
            print(f"8. {name:34s}{summary(values, 's', digits=2)}{goal}")
    if "startup" in only:
        for argv in ([str(C2N), "--help"], [str(C2N), "analyze", "--help"]):
            starts = startup(argv, max(args.runs, 3))
            shown = " ".join(["c2n", *argv[1:]])
            print(f"6. {shown:26s}{summary([r[0] for r in starts], 's', digits=2)}")
            print(f"   {'peak RSS':26s}{summary([r[1] for r in starts], 'MiB', digits=0)}")
        first_frame(1)  # the numba cache warm, as on a laptop that ran c2n before
        firsts = first_frame(max(args.runs, 3))
        print(f"   c2n live, first frame      {summary(firsts, 's', digits=2)}  (goal ≤ 1.5 s)")
        for label, size in install_sizes().items():
            name = "c2n" if label == "core" else f"c2n[{label}]"
            shown = "not installed in this venv" if size is None else f"{size:,.0f} MB"
            print(f"   installed, {name:19s}{shown}")


if __name__ == "__main__":
    main()
