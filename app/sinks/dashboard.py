"""The in-car dashboard: a display sink that renders the last snapshot of the run.

Nothing here reads a clock or the bus: it renders what the pipeline had seen (frame time), so a
test feeds it a snapshot, renders it into ``Console(record=True)`` and reads the text.
"""

import heapq
import math
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field

from rich.console import Console, ConsoleOptions, Group, RenderableType, RenderResult
from rich.panel import Panel
from rich.segment import Segment
from rich.table import Table
from rich.text import Text

from app.config import OPTICAL_ROLES
from app.errors import printable
from app.records import Reason, SteadyState
from app.results.headline import Method
from app.sinks.event_printer import result_line
from app.sinks.sideslip_plot import MIN_HEIGHT as PLOT_MIN_LINES
from app.sinks.sideslip_plot import SideslipPlot
from app.sinks.sink import Display
from app.sinks.summary import format_id
from app.snapshot import FilterState, Snapshot

WIDE, TALL = 100, 40  # below either, the compact layout (an 80×24 laptop terminal)

_ADVICE: Mapping[Reason, str] = {
    Reason.AY_HIGH: "Too much lateral acceleration: slow down or widen the circle",
    Reason.SWEEP_FAST: "Change speed more gently",
    Reason.SPEED_LOW: "Speed up",
    Reason.STRAIGHT: "Turn onto the circle",
    Reason.TIGHT: "Widen the circle",
    Reason.TRANSIENT: "Hold the steering wheel steady",
    Reason.SETTLING: "Hold it steady…",
    Reason.SENSOR: "Sensor status bad",
}


def guidance(steady: SteadyState) -> list[str]:
    """Advice for the driver, one line per reason the steady-state gate gave (the sensor's with
    its words: which status is bad)."""
    return [
        f"{_ADVICE[cause]} ({words})" if cause is Reason.SENSOR else _ADVICE[cause]
        for cause, words in zip(steady.causes, steady.reasons, strict=True)
    ]


@dataclass
class _RateMeter:
    """Frames per second per (channel, id), in frame time, between two renders."""

    last_t: float | None = None
    last_counts: dict[tuple[object, int, bool], int] = field(default_factory=dict)
    rates: dict[tuple[object, int, bool], float] = field(default_factory=dict)

    def update(self, t: float | None, counts: dict[tuple[object, int, bool], int]) -> None:
        if t is None:
            return
        if self.last_t is not None and t < self.last_t:
            self.last_t = None  # time went backwards: start again from here
        if self.last_t is not None and t - self.last_t >= 0.5:
            dt = t - self.last_t
            self.rates = {key: (n - self.last_counts.get(key, 0)) / dt for key, n in counts.items()}
        elif self.last_t is not None:
            return
        self.last_t = t
        self.last_counts = dict(counts)


def columns(rows: Sequence[Sequence[str]], left: frozenset[int] | set[int] = frozenset()) -> Text:
    """A table as aligned text: the header row bold, columns right-aligned except ``left``.

    rich's Table measures every cell on every refresh (tens of ms at 10 Hz on a slow laptop,
    tools/bench.py); these tables are a few short strings, so plain padding does.
    """
    widths = [max(len(row[i]) for row in rows) for i in range(len(rows[0]))]
    lines = [
        "  ".join(
            cell.ljust(w) if i in left else cell.rjust(w)
            for i, (cell, w) in enumerate(zip(row, widths, strict=True))
        )
        for row in rows
    ]
    text = Text()
    text.append(lines[0], style="bold")
    for line in lines[1:]:
        text.append("\n" + line)
    return text


def _waiting(snapshot: Snapshot) -> Text:
    """What the status says before the first optical sample: why there is none yet."""
    frames = snapshot.frames
    if not frames.total:
        text = "no frames on the bus yet: check the interface, the channel and the bitrate"
        return Text(text, style="bold red")
    if not any(frames.role_frames[role] for role in OPTICAL_ROLES):
        text = f"no optical sensor frames among the bus's {frames.total:,}: is the sensor on this bus?"
        return Text(text, style="bold red")
    return Text("waiting for optical sensor frames", style="yellow")


def _lost(state: FilterState) -> str:
    """In how many samples C2n is measured on the filter lost the car so far (its gate rejected a
    sensor that insisted), as the summary's warning says it; a loss elsewhere (a hard stop, a
    lap's braking) touches no sample and is not shown."""
    if not state.lost_in_samples:
        return ""
    return f"  lost the car in {state.lost_in_samples:,} samples ({', '.join(state.counts.lost)})"


def _pairs(rows: list[tuple[str, str]]) -> Text:
    """Label (bold) and value (right-aligned) per line."""
    label_width = max(len(label) for label, _ in rows)
    value_width = max(len(value) for _, value in rows)
    text = Text()
    for k, (label, value) in enumerate(rows):
        text.append(("\n" if k else "") + label.ljust(label_width + 1), style="bold")
        text.append(value.rjust(value_width))
    return text


def _segments(lines: list[list[Segment]]) -> Iterator[Segment]:
    for line in lines:
        yield from line
        yield Segment.line()


class Dashboard(Display):
    """``bus_problem`` says which buses are lost, bus-off or error-passive (None while all are
    well): it comes from the source, not the pipeline."""

    def __init__(
        self,
        title: str,
        max_ids: int = 10,
        max_crossings: int = 8,
        bus_problem: Callable[[], str | None] = lambda: None,
    ) -> None:
        self.title = title
        self.max_ids = max_ids
        self.max_crossings = max_crossings
        self.bus_problem = bus_problem
        self._snapshot: Snapshot | None = None
        self._rates = _RateMeter()

    def on_snapshot(self, snapshot: Snapshot) -> None:
        self._snapshot = snapshot
        self._rates.update(snapshot.t_last, snapshot.frames.by_id)

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> RenderResult:
        """The layout for the terminal's size: below ``WIDE`` columns or ``TALL`` lines, the compact
        one (the C2n line, the latest crossing, the steady state and sensor, the motion in a line,
        then the sideslip plot in what is left); above, the panels, the plot where it fits."""
        width, height = options.max_width, options.height or options.size.height
        heading = Text(no_wrap=True, overflow="ellipsis")
        heading.append(f" c2n live — {printable(self.title)}", style="bold")
        snapshot = self._snapshot
        if snapshot is None:
            heading.append("   waiting for the first frames")
            yield heading
            return
        heading.append(f"   t = {snapshot.elapsed_s:.1f} s")
        if width < WIDE or height < TALL:
            yield from self._compact(snapshot, heading, console, options, height)
            return
        top = Table.grid(expand=True, padding=(0, 2))
        top.add_column(ratio=1)
        top.add_column(ratio=1)
        top.add_row(self._motion(snapshot), self._status(snapshot))
        # No panel around the whole: every panel inside would be cut into lines once more, which
        # doubled the cost of a refresh (tools/bench.py --only parts: dashboard refresh).
        # laid out once: their height tells how much the plot may take
        above = console.render_lines(Group(heading, top, self._crossings(snapshot)), options, pad=False)
        below = console.render_lines(self._frames(snapshot), options, pad=False)
        yield from _segments(above)
        room = height - len(above) - len(below) - 2  # the plot's panel has two border lines
        if room >= PLOT_MIN_LINES:
            plot = SideslipPlot(snapshot.profile, snapshot.crossings, room)
            yield Panel(plot, title="Sideslip against speed")
        yield from _segments(below)

    def _compact(
        self, snapshot: Snapshot, heading: Text, console: Console, options: ConsoleOptions, height: int
    ) -> RenderResult:
        """Every line cut to the width but the C2n line, which wraps rather than lose a digit."""
        lines: list[Text] = [heading, Text(result_line(snapshot), style="bold")]
        if snapshot.crossings:
            c = snapshot.crossings[-1]
            lo, hi = c.ci95
            lines.append(
                Text(
                    f"last: {c.t - snapshot.t0:.1f} s {c.direction} {c.sweep}  u0 {c.u0_mps:.3f} m/s  "
                    f"a_y {c.ay_mps2:.2f}  C2n {c.c2n:.3f} [{lo:.3f}, {hi:.3f}]"
                )
            )
        lines.extend(self._status_lines(snapshot))
        record = snapshot.last
        e = record.estimate if record else None
        if e is not None:
            beta = math.degrees(e.sideslip_rad)
            motion = f"{e.u_mps * 3.6:.1f} km/h  sweep {e.u_dot_mps2:+.2f} m/s²  β {beta:+.3f}°"
            if e.ay_mps2 is not None:
                motion += f"  a_y {e.ay_mps2:+.2f} m/s²"
            if e.r_radps is not None:
                motion += f"  r {math.degrees(e.r_radps):+.1f} °/s"
            lines.append(Text(motion))
        counts = snapshot.frames
        bad = counts.total - counts.used - counts.unused
        lines.append(Text(f"frames {counts.total:,}  used {counts.used:,}  not decoded {bad:,}", style="dim"))
        for line in lines[2:]:
            line.no_wrap, line.overflow = True, "ellipsis"
        used = sum(len(console.render_lines(line, options, pad=False)) for line in lines)
        yield from lines
        if height - used >= PLOT_MIN_LINES:
            yield SideslipPlot(snapshot.profile, snapshot.crossings, height - used)

    def _motion(self, snapshot: Snapshot) -> RenderableType:
        record = snapshot.last
        e = record.estimate if record else None
        if e is None:
            return Panel(_pairs([("speed", "—")]), title="Motion")
        sigma = math.degrees(e.sideslip_sigma_rad)
        steer = snapshot.latest.get("steer")
        noise = snapshot.filter.noise_sigma
        rows = [
            ("speed", f"{e.u_mps * 3.6:6.1f} km/h  {e.u_mps:6.2f} m/s"),
            ("sweep", f"{e.u_dot_mps2:+6.2f} m/s²"),
            ("sideslip", f"{math.degrees(e.sideslip_rad):+7.3f}° ± {sigma:.3f}"),
            ("lat. acc.", f"{e.ay_mps2:+6.2f} m/s²" if e.ay_mps2 is not None else "—"),
            ("yaw rate", f"{math.degrees(e.r_radps):+6.2f} °/s" if e.r_radps is not None else "—"),
            ("steering", f"{math.degrees(steer):+6.1f}°" if steer is not None else "—"),
            ("filter health", f"{e.health:5.2f}" + _lost(snapshot.filter)),
            ("optical noise", f"σ {noise['vx_mps'] * 1000:.0f} / {noise['lateral_mps'] * 1000:.0f} mm/s"),
        ]
        return Panel(_pairs(rows), title="Motion")

    def _status(self, snapshot: Snapshot) -> RenderableType:
        return Panel(Group(*self._status_lines(snapshot)), title="Steady state")

    def _status_lines(self, snapshot: Snapshot) -> list[Text]:
        lines: list[Text] = []
        bus_problem = self.bus_problem()
        if bus_problem:
            lines.append(Text(f"bus: {bus_problem}", style="bold red"))
        steady = snapshot.last.steady if snapshot.last else None
        if steady is None:
            lines.append(_waiting(snapshot))
        elif steady.steady:
            turn = f"{steady.direction} turn" if steady.direction else "turning"
            lines.append(Text(f"● STEADY — {turn}", style="bold green"))
        else:
            lines.append(Text("○ not steady", style="yellow"))
            lines.extend(Text(f"→ {advice}", style="yellow") for advice in guidance(steady))
        if snapshot.sensor_problem:
            lines.append(Text(f"sensor: {snapshot.sensor_problem}", style="bold red"))
        if snapshot.replay_hint:
            lines.append(Text(snapshot.replay_hint, style="bold red"))
        if snapshot.status:
            shown = ", ".join(
                f"{printable(name.partition('.')[2])} {value:g}"
                for name, value in sorted(snapshot.status.items())
            )
            lines.append(Text(f"status: {shown}"))
        for pending in snapshot.pending:
            lines.append(
                Text(
                    f"sign change {pending.direction or ''} at {pending.u_mps * 3.6:.1f} km/h: fitting…",
                    style="cyan",
                )
            )
        return lines

    def _crossings(self, snapshot: Snapshot) -> RenderableType:
        rows = [("t [s]", "dir", "sweep", "u0 [m/s]", "u0 [km/h]", "a_y [m/s²]", "C2n [1/rad]", "95 %")]
        t0 = snapshot.t0
        for c in snapshot.crossings[-self.max_crossings :]:
            lo, hi = c.ci95
            rows.append(
                (
                    f"{c.t - t0:.1f}",
                    c.direction,
                    c.sweep,
                    f"{c.u0_mps:.3f}",
                    f"{c.u0_kmh:.2f}",
                    f"{c.ay_mps2:.2f}",
                    f"{c.c2n:.3f}",
                    f"{lo:.3f}–{hi:.3f}",
                )
            )
        table = columns(rows)
        result = Text(result_line(snapshot), style="bold")
        lines: list[RenderableType] = [table, result]
        fit = snapshot.fit
        if fit is not None:
            psi0 = f"ψ0 {math.degrees(fit.psi0.rad):+.3f}°" if fit.psi0 is not None else "ψ0 —"
            model = "softening tyre model" if fit.models.chosen == "softening" else "linear"
            if not fit.models.resolved:
                model += " (softening not ruled out: interval widened)"
            name = Method.QUASI_STEADY if fit is snapshot.quasi else Method.REGRESSION
            lines.append(
                Text(
                    f"{name}: d {fit.d.m:.3f} m [{fit.d.ci95_m[0]:.3f}, {fit.d.ci95_m[1]:.3f}] "
                    f"(config {snapshot.d_m:g}), {psi0}, {model}, "
                    f"a_y {fit.samples.ay_range_mps2[0]:.1f}–{fit.samples.ay_range_mps2[1]:.1f} m/s²"
                )
            )
        paired = snapshot.paired
        if paired is not None:
            parts = []
            if paired.misalignment_rad is not None:
                parts.append(f"head misalignment {math.degrees(paired.misalignment_rad):+.2f}°")
            else:
                parts.append("misalignment not removed yet (turn the other way too)")
            if paired.lag_s is not None:
                parts.append(f"lag {paired.lag_s * 1000:+.0f} ms")
            else:
                parts.append("lag not removed yet (sweep the other way too)")
            lines.append(Text("pairing: " + ", ".join(parts)))
        rejected = len(snapshot.rejections)
        if rejected:
            lines.append(Text(f"{rejected} sign change(s) not used", style="dim"))
        return Panel(Group(*lines), title="Crossings")

    def _frames(self, snapshot: Snapshot) -> RenderableType:
        counts = snapshot.frames
        rows = [("channel", "id", "message", "frames", "rate [1/s]")]
        busiest = heapq.nlargest(self.max_ids, counts.by_id.items(), key=lambda kv: kv[1])
        for key, n in sorted(busiest, key=lambda kv: (str(kv[0][0]), kv[0][1], kv[0][2])):
            channel, frame_id, extended = key
            rate = self._rates.rates.get(key)
            name = snapshot.message_names.get((frame_id, extended), "(unknown)")
            rate_text = f"{rate:.0f}" if rate is not None else "—"
            rows.append(
                (printable(str(channel)), format_id(frame_id, extended), printable(name), str(n), rate_text)
            )
        table = columns(rows, left={2})
        bad = (
            f"total {counts.total}  used {counts.used}  unknown id {counts.unknown_id}  "
            f"bad length {counts.bad_length}  undecodable {counts.undecodable}  error {counts.error_frames}  "
            f"remote {counts.remote_frames}  other channel {counts.other_channel}  CAN FD {counts.fd_frames}"
        )
        lines: list[RenderableType] = [table, Text(bad)]
        lines.extend(
            Text(f"values dropped from {n} frames: {reason}", style="yellow")
            for reason, n in counts.rejected.most_common(3)
        )
        return Panel(Group(*lines), title="Frames")
