"""The heading: the filtered yaw rate integrated since the start of the run.

A slope on the test pad pulls the car sideways by g·s·sin(D − ψ), so the regression needs ψ at
every steady sample. Only differences of heading matter (the slope's direction is given from the
start heading), and a gyro bias of 0.05 °/s turns it by 30° in ten minutes: enough to fit a slope,
not to navigate by. The block form adds the same numbers in the same order as frame by frame.
"""

import numpy as np


class Heading:
    def __init__(self) -> None:
        self.value = 0.0  # rad, left turns positive
        self._t: float | None = None

    def step(self, t: float, r: float | None) -> float:
        """The heading at ``t`` after a yaw rate ``r`` (None: not observed, the heading holds)."""
        if r is not None:
            if self._t is not None:
                self.value += r * (t - self._t)
            self._t = t
        return self.value

    def steps(self, t: np.ndarray, r: np.ndarray) -> np.ndarray:
        """``step`` over arrays (NaN: not observed): the heading after each."""
        seen = np.flatnonzero(~np.isnan(r))
        out = np.full(len(t), self.value)
        if not len(seen):
            return out
        times, rates = t[seen], r[seen]
        before = np.empty(len(seen))
        before[0] = times[0] if self._t is None else self._t
        before[1:] = times[:-1]
        turned = np.cumsum(np.concatenate([[self.value], rates * (times - before)]))[1:]
        # a row without a yaw rate holds the heading of the last row with one
        last = np.maximum.accumulate(np.where(np.isnan(r), -1, np.arange(len(t))))
        known = last >= 0
        position = np.searchsorted(seen, last[known])
        out[known] = turned[position]
        self.value, self._t = float(turned[-1]), float(times[-1])
        return out
