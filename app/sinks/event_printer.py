"""The event printer: one line per event, the same on a terminal and in a pipe (plain text there),
and the run's result line."""

import math
from collections.abc import Sequence

from rich.console import Console
from rich.text import Text

from app.records import Crossing, CrossingRejected, Event
from app.results.combine import bracket
from app.results.headline import Method
from app.sinks.sink import Sink
from app.snapshot import Snapshot


def crossing_line(c: Crossing, t0: float) -> str:
    lo, hi = c.ci95
    return (
        f"{c.t - t0:8.1f} s  {c.direction:<5} {c.sweep:<4}  "
        f"u0 {c.u0_mps:6.3f} m/s = {c.u0_kmh:6.2f} km/h  a_y {c.ay_mps2:4.2f} m/s²  "
        f"C2n {c.c2n:6.3f} [{lo:.3f}, {hi:.3f}] 1/rad"
    )


def rejected_line(r: CrossingRejected, t0: float) -> str:
    direction = r.direction or "?"
    return (
        f"{r.t - t0:8.1f} s  {direction:<5} {r.sweep:<4}  "
        f"sign change near {r.u_mps * 3.6:.1f} km/h not used: {r.reason}"
    )


def result_line(snapshot: Snapshot) -> str:
    """The run's result: the headline C2n and how it was found, and the crossings beside it."""
    headline, u0 = snapshot.headline, snapshot.u0_mps
    if headline is None:
        return f"C2n: no result ({snapshot.refusal})"
    lo, hi = headline.ci95
    how = headline.method.value
    fit = snapshot.fit
    if fit is not None and headline.method is Method.QUASI_STEADY:
        samples = fit.samples
        how = (
            f"quasi-steady cornering: {samples.duration_s:.0f} s, {samples.count:,} samples at "
            f"{samples.speed_range_mps[0]:.1f}–{samples.speed_range_mps[1]:.1f} m/s, a_y "
            f"{samples.ay_range_mps2[0]:.1f}–{samples.ay_range_mps2[1]:.1f} m/s²"
        )
        if samples.logs > 1:
            how += f", {samples.logs} drives pooled"
        if not fit.models.resolved:
            how += "; interval widened: the a_y range cannot rule out softening tyres"
    elif fit is not None:
        how = f"regression over {fit.samples.count:,} steady samples"
        if fit.models.chosen == "softening":
            how += ", extrapolated to zero a_y"
        elif not fit.models.resolved:
            how += "; interval widened: the a_y range cannot rule out softening tyres"
    if fit is not None and fit.scale_se > 0 and headline.method.is_fit:
        how += f"; the sensors' scale counted, σ {100 * fit.scale_se:.2f} %"
    text = f"C2n = {headline.c2n:.3f} 1/rad [{lo:.3f}, {hi:.3f}] (95 %, {how}); "
    text += f"u0 = {u0:.3f} m/s = {u0 * 3.6:.2f} km/h" if u0 is not None else "u0: none (C2n is not positive)"
    crossings = snapshot.paired or snapshot.combined
    if crossings is not None and headline.method is Method.REGRESSION:
        paired = " paired" if snapshot.paired is not None else ""
        count = f"{crossings.n}{paired} crossing{'s' if crossings.n != 1 else ''}"
        text += f"; {count}: {crossings.c2n:.3f} {bracket(crossings.ci95)}"
    return text


def fit_line(snapshot: Snapshot) -> str | None:
    """What the fits found besides C2n, with their 95 % intervals: the regression's sensor
    position d and the head's misalignment ψ0, and the pairing's misalignment and lag."""
    parts = []
    fit = snapshot.fit
    if fit is not None and snapshot.sign_problem is None:
        lo, hi = fit.d.ci95_m
        parts.append(f"d = {fit.d.m:.3f} m [{lo:.3f}, {hi:.3f}] (config {snapshot.d_m:g})")
        if fit.psi0 is not None:
            plo, phi = (math.degrees(x) for x in fit.psi0.ci95_rad)
            parts.append(f"ψ0 = {math.degrees(fit.psi0.rad):+.3f}° [{plo:+.3f}, {phi:+.3f}]")
    paired = snapshot.paired
    yawed, lag = (paired.misalignment_ci95_rad, paired.lag_ci95_s) if paired is not None else (None, None)
    if paired is not None and paired.misalignment_rad is not None and yawed is not None:
        half = math.degrees(yawed[1] - yawed[0]) / 2
        parts.append(f"pairing: misalignment {math.degrees(paired.misalignment_rad):+.3f}° ± {half:.3f}")
    if paired is not None and paired.lag_s is not None and lag is not None:
        parts.append(f"lag {paired.lag_s:+.3f} s ± {(lag[1] - lag[0]) / 2:.3f}")
    return "  " + "; ".join(parts) + " (95 %)" if parts else None


def print_result(console: Console, snapshot: Snapshot) -> None:
    """The result line, and under it what the fits found besides C2n."""
    console.print(Text(result_line(snapshot), style="bold"))
    fit = fit_line(snapshot)
    if fit is not None:
        console.print(Text(fit))


class EventPrinter(Sink):
    """Prints each crossing (and each sign change not used) as one line."""

    def __init__(self, console: Console) -> None:
        self.console = console

    def on_events(self, events: Sequence[Event], t0: float) -> None:
        for event in events:
            if isinstance(event, Crossing):
                self.console.print(Text(crossing_line(event, t0), style="bold green"), soft_wrap=True)
            elif isinstance(event, CrossingRejected):
                self.console.print(Text(rejected_line(event, t0), style="dim"), soft_wrap=True)
