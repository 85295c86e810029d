"""A log whose timestamps are not in seconds: the optical sensor's frames far apart in its time.

A sensor sends every 4–20 ms (50–250 Hz). A timestamp column in milliseconds (or microseconds)
read as seconds lays its frames 1000× (10⁶×) as far apart: the drive reads 1000× too long and
too slow, the filter restarts at every frame, and the run's refusal would blame the cornering.
The test needs no constant of its own: where the median spacing of the sensor's frames is beyond
the config's ``gap_reset_s`` the filter restarts at most of them, whatever the cause, and no
sensor sends that slowly. The unit named in the fix is the power of 1000 nearest to the spacing
over the sensor's cycle (the DBC's ``GenMsgCycleTime`` of its message, else 50–250 Hz), where the
spacing is within 10× of it (else no unit is named: a log thinned to a frame a second is not
one in milliseconds); a spacing nearer the cycle itself is the sensor's own, in seconds (a
config whose gap_reset_s is shorter than it restarts the filter too, but its clock is right).
"""

import math
from collections.abc import Sequence

from app.config import OPTICAL_ROLES, Config
from app.sources.logs import LogReport
from app.sources.spacing import Spacing

SENSOR_HZ = (50.0, 250.0)  # what an optical sensor sends at (S-Motion: up to 250 Hz)
_UNITS = {1: ("milliseconds", "1000"), 2: ("microseconds", "1,000,000"), 3: ("nanoseconds", "10⁹")}


def sensor_messages(config: Config) -> dict[int, float | None]:
    """The frame id of each message that carries an optical role (vx, vy, beta), with its cycle
    in seconds where its DBC gives one (GenMsgCycleTime)."""
    names = {config.roles[role].message for role in OPTICAL_ROLES if role in config.roles}
    found: dict[int, float | None] = {}
    for dbc in config.dbcs:
        for message in dbc.database.messages:
            if message.name in names and message.frame_id not in found:
                cycle_ms = message.cycle_time
                found[message.frame_id] = cycle_ms / 1000.0 if cycle_ms else None
    return found


# A pause the filter restarts on is longer than a frame lost: two of the sensor's cycles, and a
# third for the timestamps' jitter. gap_reset_s equal to the cycle restarted it at half the frames.
BRIDGED_CYCLES = 3.0


def clock_problem(spacing: Spacing, gap_reset_s: float, cycle_s: float | None) -> str | None:
    """Why a log's timestamps are not in seconds: the optical sensor's frames (``spacing``, in
    the log's unit) lie beyond ``gap_reset_s`` apart (median), a power of 1000 or more of the
    sensor's cycle ``cycle_s`` (None: 4–20 ms). None where they do not."""
    if not (math.isfinite(spacing.median) and spacing.median > 0):  # no spacing's overflow
        return None
    expected = cycle_s if cycle_s else 1.0 / math.sqrt(SENSOR_HZ[0] * SENSOR_HZ[1])
    power = round(math.log(spacing.median / expected, 1000))
    shorter = gap_reset_s < spacing.median
    if not shorter and (power >= 1 or gap_reset_s >= BRIDGED_CYCLES * spacing.median):
        return None  # bridged, a lost frame and all (or a log thinned, not the setting's)
    if power < 1:  # the sensor's own spacing, in seconds: the setting is not above a lost frame's
        return (  # it said "the optical data stopped 10343 times" and blamed the driving
            f"[filter] gap_reset_s = {gap_reset_s:g} s is "
            f"{'shorter than' if shorter else 'within a lost frame of'} the optical "
            f"sensor's frame spacing (id 0x{spacing.frame_id:X}, {_amount(spacing.median * 1000)} ms "
            f"median): the filter restarts at every {'frame' if shorter else 'late or lost frame'} "
            f"— set it to {BRIDGED_CYCLES:g} of the sensor's cycles or more (the default is 1 s)"
        )
    sends = (
        f"{cycle_s * 1000:g} ms (its DBC's cycle)"
        if cycle_s
        else f"{1000 / SENSOR_HZ[1]:g}–{1000 / SENSOR_HZ[0]:g} ms"
    )
    seen = (
        f"the optical sensor's frames (id 0x{spacing.frame_id:X}) are {_amount(spacing.median)} s apart "
        f"(median), where a sensor sends one every {sends}"
    )
    restarts = f"past gap_reset_s ({gap_reset_s:g} s) the filter restarts at every frame"
    near = abs(math.log(spacing.median / expected, 1000) - power) < 1 / 3  # within 10× of that power
    unit = _UNITS.get(power) if near else None
    if unit is None:
        return f"{seen}: are the timestamps in seconds? {restarts} — if not, convert them to seconds"
    name, factor = unit
    return (
        f"{seen}: timestamps in {name} read as seconds, {factor}× too slow — {restarts}; convert the "
        f"timestamp column to seconds (÷ {factor})"
    )


def clock_notes(reports: Sequence[LogReport], config: Config) -> list[LogReport]:
    """A note for each log whose timestamps are not in seconds, its ``stopped`` saying why
    (``clock_problem`` of the optical sensor's frames: those ``LogSource`` was told to space,
    ``sensor_messages``)."""
    cycles = sensor_messages(config)
    notes = []
    for report in reports:
        spacing = report.spacing.busiest()
        if spacing is None:
            continue
        why = clock_problem(spacing, config.filter.gap_reset_s, cycles.get(spacing.frame_id))
        if why is not None:
            notes.append(LogReport(report.path, stopped=why, done=True))
    return notes


def _amount(value: float) -> str:
    """Three significant digits, in thousands (20,000 and 10, not 2e+04 and 10.0005)."""
    rounded = float(f"{value:.3g}")
    return f"{rounded:,.0f}" if abs(rounded) >= 100 else f"{rounded:g}"
