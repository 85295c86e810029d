"""The sideslip at the sensor against speed, per turn direction: the paper's Fig. 9, live.

Every steady sample adds its measured sideslip β = v/u to a bin of ``BIN_MPS`` of speed, so the
memory is fixed (two directions × ``MAX_MPS / BIN_MPS`` bins) however long the drive. On a
circle β falls through zero at u0 (eq. 6: β = d/R − u²/(R·g·C2n)); the dashboard draws the bins'
means with the zero line and the crossings found.
"""

from dataclasses import dataclass

import numpy as np

from app.records import Direction

BIN_MPS = 0.1
MAX_MPS = 80.0
_BINS = int(MAX_MPS / BIN_MPS)
_ROW: dict[Direction | None, int] = {"left": 0, "right": 1}


@dataclass(frozen=True)
class ProfileView:
    """The bins as they stand: speed [m/s] and mean sideslip [rad] of each filled bin, per direction."""

    left: tuple[np.ndarray, np.ndarray]
    right: tuple[np.ndarray, np.ndarray]

    @property
    def empty(self) -> bool:
        return not (len(self.left[0]) or len(self.right[0]))

    def __eq__(self, other: object) -> bool:  # arrays compare by value (a Snapshot compares its parts)
        if not isinstance(other, ProfileView):
            return NotImplemented
        return all(
            np.array_equal(a, b)
            for mine, theirs in ((self.left, other.left), (self.right, other.right))
            for a, b in zip(mine, theirs, strict=True)
        )

    __hash__ = None  # type: ignore[assignment]  # mutable arrays inside: no hash


class SideslipProfile:
    def __init__(self) -> None:
        self._sum = np.zeros((2, _BINS))
        self._n = np.zeros((2, _BINS), dtype=np.int64)

    def add(self, u_mps: float, v_mps: float, direction: Direction | None) -> None:
        """One steady sample: speed and the lateral velocity measured at the sensor."""
        row = _ROW.get(direction)
        if row is None or not 0 < u_mps < MAX_MPS or v_mps != v_mps:  # NaN: no sample
            return
        k = int(u_mps / BIN_MPS)
        self._sum[row, k] += v_mps / u_mps
        self._n[row, k] += 1

    def view(self) -> ProfileView:
        def side(row: int) -> tuple[np.ndarray, np.ndarray]:
            filled = np.flatnonzero(self._n[row])
            return (filled + 0.5) * BIN_MPS, self._sum[row, filled] / self._n[row, filled]

        return ProfileView(side(0), side(1))
