"""Do the crossings support a C2n at all? A check on the method's own premise, not a size floor.

A crossing counts only after the steady-state gate has held for ``settle_s`` (the config's
``[detector] settle_s``): the method assumes the sideslip has settled to its steady value by then
(paper §2–3). The up/down pairing measures how far the sideslip lags the speed (``Paired.lag_s``,
τ in C2n_i = C2n·(1 − ψ·R_i/d + 2·τ·u̇_i/u0)). A lag longer than the settling time, at the
pairing's own 95 %, contradicts that premise: what moved the sign change between the sweeps was no
sensor's latency but a car that never reached steady linear cornering — tyres at their grip
limit (a drive on ice: a_y never above 1 m/s², crossings 7.3 and 12.1 sweeping up and down, a
"lag" of −5.5 s), or a manoeuvre too fast for its radius. No C2n is then printed from the
crossings; the reason is.

Nor where the crossings cannot bound C2n at all (``unbounded_crossings``): crossings on one
radius turning one way cannot tell a head's yaw from C2n, and on a wide circle a yaw within the
head's tolerance moves the sign change by as much as C2n itself (``combine.ratio_ci95``).
"""

from app.results.combine import Combined
from app.results.headline import positive
from app.results.pairing import Paired
from app.units import Z95


def unsteady_crossings(paired: Paired | None, settle_s: float) -> str | None:
    """Why the crossings give no C2n: the up and down sweeps disagree by more than any lag the
    steady-state gate lets settle (None: they agree, or only one sweep direction was driven)."""
    if paired is None or paired.lag_s is None or paired.lag_se is None:
        return None
    nearest = abs(paired.lag_s) - Z95 * paired.lag_se  # the lag's 95 % bound nearest zero
    if nearest <= settle_s:
        return None
    up = [c2n for cell, c2n in paired.cells.items() if cell.endswith(" up")]
    down = [c2n for cell, c2n in paired.cells.items() if cell.endswith(" down")]
    cells = (
        f", {min(up):.2f}–{max(up):.2f} up against {min(down):.2f}–{max(down):.2f} down"
        if up and down
        else ""
    )
    return (
        f"the crossings sweeping up and down disagree{cells} — a lag of {paired.lag_s:+.1f} s "
        f"± {Z95 * paired.lag_se:.1f} between speed and sideslip, longer than the {settle_s:g} s the "
        "steady-state gate lets the car settle: the car was not in steady linear cornering at the "
        "sign change (tyres near their grip limit on a slippery surface, or sweeps too fast); drive "
        "steady circles on a dry surface at 2–4 m/s² with the speed swept slowly through the sign change"
    )


def unbounded_crossings(paired: Paired | None, combined: Combined | None) -> str | None:
    """Why the crossings give no C2n: their 95 % interval has no upper end (None: it has, or
    there is no positive reading to speak of). Says what held it open: the head's yaw where
    the crossings could not place it, the lag where one sweep direction was driven."""
    crossings = paired if paired is not None else combined
    if crossings is None or not positive(crossings.c2n) or crossings.bounded:
        return None
    held = []
    if paired is not None and paired.misalignment_rad is None:
        held.append(
            "a head yawed within its tolerance ([priors] head_yaw_deg) moves every crossing alike, "
            "as the crossings turn one way on one radius"
        )
    if paired is not None and paired.lag_s is None:
        held.append("a lag between speed and sideslip, as one sweep direction was driven")
    why = "; ".join(held) if held else "the crossings scatter as widely as C2n itself"
    count = f"{crossings.n} crossings read" if crossings.n != 1 else "1 crossing reads"
    bind = "do" if crossings.n != 1 else "does"
    own = (
        "each crossing's own line counts its u0"
        if crossings.n != 1
        else "the crossing's own line counts its u0"
    )
    return (
        f"{count} C2n {crossings.c2n:.2f} but {bind} not bound it: its 95 % interval runs from "
        f"{crossings.ci95[0]:.2f} with no upper end, where {own} alone ({why}) — drive circles both "
        "ways with the speed "
        "swept up and down through the sign change, or long enough for the regression (200 steady "
        "samples over 0.5 m/s² of a_y)"
    )
