"""The sideslip at the sensor against speed, drawn in the terminal: the paper's Fig. 9 as it grows.

Each steady sample's speed bin is a point, left turns ``•`` and right turns ``∘`` (``◆`` where
both fall in one cell), the sideslip counted positive towards the turn's inside so both
directions fall on one curve (a yawed head parts them), over the zero line; each crossing found
is a ``×`` on the zero line at its u0. The engineer watches a sweep run down towards zero
and sees u0 coming.
"""

import itertools
from collections.abc import Iterator, Sequence

import numpy as np
from rich.console import Console, ConsoleOptions
from rich.text import Text

from app.records import Crossing
from app.results.sideslip_profile import ProfileView

LEFT, RIGHT, BOTH, CROSSING, ZERO = "•", "∘", "◆", "×", "─"
_STYLE = {LEFT: "cyan", RIGHT: "magenta", BOTH: "bold", CROSSING: "bold yellow", ZERO: "dim"}
_MARGIN = 8  # the y labels: " +0.50°┤"
MIN_HEIGHT = 5


class SideslipPlot:
    def __init__(self, profile: ProfileView | None, crossings: Sequence[Crossing], height: int) -> None:
        self.profile = profile
        self.crossings = crossings
        self.height = max(height, MIN_HEIGHT)

    def __rich_console__(self, console: Console, options: ConsoleOptions) -> Iterator[Text]:
        width = options.max_width
        yield Text(
            f"sideslip β [°, + to the turn's inside] against speed: "
            f"{LEFT} left  {RIGHT} right  {CROSSING} crossing",
            style="bold",
            no_wrap=True,
            overflow="ellipsis",
        )
        profile = self.profile
        if profile is None or profile.empty or width < _MARGIN + 10:
            yield Text("no steady samples yet", style="dim")
            return
        yield from self._grid(profile, width - _MARGIN, self.height - 2)

    def _grid(self, profile: ProfileView, columns: int, rows: int) -> Iterator[Text]:
        speeds = np.concatenate([profile.left[0], profile.right[0]])
        slips = np.degrees(np.concatenate([profile.left[1], -profile.right[1]]))
        u_lo, u_hi = float(speeds.min()), float(speeds.max())
        for crossing in self.crossings:
            u_lo, u_hi = min(u_lo, crossing.u0_mps), max(u_hi, crossing.u0_mps)
        u_hi = max(u_hi, u_lo + 1.0)
        b_lo, b_hi = min(float(slips.min()), 0.0), max(float(slips.max()), 0.0)
        pad = 0.05 * (b_hi - b_lo) or 0.1
        b_lo, b_hi = b_lo - pad, b_hi + pad

        def column(u: float) -> int:
            return min(columns - 1, max(0, round((u - u_lo) / (u_hi - u_lo) * (columns - 1))))

        def row(beta_deg: float) -> int:  # row 0 at the top
            return min(rows - 1, max(0, round((b_hi - beta_deg) / (b_hi - b_lo) * (rows - 1))))

        cells = [[" "] * columns for _ in range(rows)]
        zero = row(0.0)
        cells[zero] = [ZERO] * columns
        for (u, beta), mark, inward in ((profile.left, LEFT, 1.0), (profile.right, RIGHT, -1.0)):
            for uk, bk in zip(u.tolist(), np.degrees(inward * beta).tolist(), strict=True):
                r, k = row(bk), column(uk)
                here = cells[r][k]
                cells[r][k] = BOTH if here in (LEFT, RIGHT) and here != mark else mark
        for crossing in self.crossings:
            cells[zero][column(crossing.u0_mps)] = CROSSING
        labels = {0: b_hi, zero: 0.0, rows - 1: b_lo}
        for r, chars in enumerate(cells):
            line = Text(
                f"{labels[r]:+6.2f}°┤" if r in labels else " " * (_MARGIN - 1) + "│",
                style="dim",
                no_wrap=True,
                overflow="crop",
            )
            for char, run in itertools.groupby(chars):  # a run of one mark, appended at once
                line.append(char * len(list(run)), style=_STYLE.get(char))
            yield line
        low, high = f"{u_lo:.1f}", f"{u_hi:.1f} m/s"
        axis = " " * _MARGIN + low + " " * max(1, columns - len(low) - len(high)) + high
        yield Text(axis, style="dim", no_wrap=True, overflow="crop")
