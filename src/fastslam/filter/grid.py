"""Per-particle log-odds occupancy grids sharing one geometry.

logodds has shape (N, H, W) and is indexed [n, iy, ix]; cell (0, 0) has its lower-left
corner at origin, rows go along +y, exactly like nav_msgs/OccupancyGrid's data.
Log-odds are stored quantised in int8 (log-odds = value * scale): one byte a cell,
since the N grids are the memory and the memory traffic of the filter. The clamp
limits set the scale, so l_min..l_max always fit in -127..127.
"""
from __future__ import annotations

import functools
import math
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike, NDArray


LOGODDS_DTYPE = np.int8
QMAX = 127


class LogOddsSteps(NamedTuple):
    """The map update's increments and clamps in a grid's int8 units."""

    free: int   # added to a cell a beam crosses (< 0)
    occ: int    # added to the cell a beam ends in (> 0)
    lo: int     # clamps
    hi: int


class GridMaps:
    """N log-odds grids on a common lattice that can grow.

    Args:
        n: particles.
        shape: (H, W) cells.
        resolution: cell size [m].
        origin: (x, y) world coordinates of the lower-left corner of cell (0, 0) [m].
        l_limit: largest |log-odds| to represent; sets the quantisation step.
    """

    def __init__(self, n: int, shape: tuple[int, int], resolution: float,
                 origin: tuple[float, float], l_limit: float = 5.0) -> None:
        self.resolution = float(resolution)
        self.origin = np.array(origin, dtype=float)
        self.scale = float(l_limit) / QMAX  # log-odds of one quantisation step
        self.logodds: NDArray[np.int8] = np.zeros((n,) + tuple(shape), dtype=LOGODDS_DTYPE)

    def quantise(self, value: float) -> int:
        """A log-odds value in grid units, never rounded to zero."""
        q = int(np.clip(np.rint(value / self.scale), -QMAX, QMAX))
        return q if q != 0 else int(np.sign(value))

    def steps(self, l_free: float, l_occ: float, l_min: float, l_max: float) -> LogOddsSteps:
        """Log-odds increments and clamps in grid units."""
        return LogOddsSteps(self.quantise(l_free), self.quantise(l_occ), self.quantise(l_min), self.quantise(l_max))

    @property
    def shape(self) -> tuple[int, int]:
        return self.logodds.shape[1], self.logodds.shape[2]

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) [m]."""
        h, w = self.shape
        x0, y0 = self.origin
        return x0, y0, x0 + w * self.resolution, y0 + h * self.resolution

    def world_to_cell(self, xy: ArrayLike) -> NDArray[np.int64]:
        """(..., 2) world points -> (..., 2) integer (ix, iy), possibly outside the grid."""
        return np.floor((np.asarray(xy) - self.origin) / self.resolution).astype(np.int64)

    def cell_to_world(self, ixy: ArrayLike) -> NDArray[np.float64]:
        """(..., 2) integer (ix, iy) -> (..., 2) world coordinates of the cell centres."""
        return self.origin + (np.asarray(ixy) + 0.5) * self.resolution

    def covers(self, xmin: float, ymin: float, xmax: float, ymax: float) -> bool:
        gx0, gy0, gx1, gy1 = self.extent
        return xmin >= gx0 and ymin >= gy0 and xmax < gx1 and ymax < gy1

    def grow_to(self, xmin: float, ymin: float, xmax: float, ymax: float, *, fraction: float = 0.5) -> bool:
        """Enlarges every grid so it holds the box, keeping content at its world place.

        Each side that must move grows by at least `fraction` of the current size (half
        by default), so a robot exploring steadily pays for a copy only a logarithmic
        number of times; a smaller fraction keeps the maps (copied at every
        resampling) closer to the explored area.
        Returns whether anything changed.
        """
        if self.covers(xmin, ymin, xmax, ymax):
            return False
        h, w = self.shape
        left, right, down, up = self._padding(xmin, ymin, xmax, ymax, fraction)
        n = self.logodds.shape[0]
        grown = np.zeros((n, h + down + up, w + left + right), dtype=LOGODDS_DTYPE)
        grown[:, down:down + h, left:left + w] = self.logodds
        self.logodds = grown
        self.origin = self.origin - np.array([left, down]) * self.resolution
        return True

    def _padding(self, xmin: float, ymin: float, xmax: float, ymax: float,
                 fraction: float) -> tuple[int, int, int, int]:
        """Cells grow_to adds on the left, right, bottom and top."""
        h, w = self.shape
        r = self.resolution
        gx0, gy0, gx1, gy1 = self.extent

        def need(short: float, size: int) -> int:
            return 0 if short <= 0 else max(math.ceil(short / r), int(size * fraction))

        return need(gx0 - xmin, w), need(xmax - gx1 + r, w), need(gy0 - ymin, h), need(ymax - gy1 + r, h)

    # -- memory (the node's budget; a tiled grid counts what it allocated) ---------------
    @staticmethod
    def bytes_for(n: int, shape: tuple[int, int]) -> int:
        """Bytes n maps of shape (H, W) take when every cell is held."""
        return int(n) * int(shape[0]) * int(shape[1]) * np.dtype(LOGODDS_DTYPE).itemsize

    @property
    def nbytes(self) -> int:
        """Bytes the maps hold now."""
        return int(self.logodds.nbytes)

    def grown_shape(self, xmin: float, ymin: float, xmax: float, ymax: float, *,
                    fraction: float = 0.5) -> tuple[int, int]:
        """(H, W) after grow_to with these arguments."""
        left, right, down, up = self._padding(xmin, ymin, xmax, ymax, fraction)
        h, w = self.shape
        return h + down + up, w + left + right

    def growth_bytes(self, xmin: float, ymin: float, xmax: float, ymax: float, *, fraction: float = 0.5) -> int:
        """Bytes grow_to with these arguments allocates: the whole grown maps, since the
        old ones are freed only after the copy (0 when the box is covered)."""
        if self.covers(xmin, ymin, xmax, ymax):
            return 0
        return self.bytes_for(len(self.logodds), self.grown_shape(xmin, ymin, xmax, ymax, fraction=fraction))

    def reorder(self, parent: NDArray[np.intp]) -> None:
        """Slot s takes the map of slot parent[s]; only slots that change are copied."""
        moved = np.flatnonzero(parent != np.arange(len(parent)))
        if np.isin(parent[moved], moved).any():
            self.logodds[moved] = self.logodds[parent[moved]]  # read every source first
            return
        # Sources keep their own map (as slot_parents assigns them): copy map by map,
        # without a temporary the size of all moved maps.
        for slot in moved:
            np.copyto(self.logodds[slot], self.logodds[parent[slot]])

    def view(self, n: int) -> GridMaps:
        """A GridMaps of particle n's map alone, sharing its cells (no copy): what reads
        it (the matcher tracking one particle between updates) sees that map only."""
        one = GridMaps.__new__(GridMaps)
        one.resolution, one.origin, one.scale = self.resolution, self.origin.copy(), self.scale
        one.logodds = self.logodds[n:n + 1]
        return one

    def cells_flat(self) -> NDArray[np.int8]:
        """Every map's cells as one flat array (a view), index (n * H + iy) * W + ix:
        for gathers of many cells of many maps at once."""
        return self.logodds.reshape(-1)

    def probability(self, n: int) -> NDArray[np.float64]:
        """(H, W) occupancy probability of particle n's map."""
        return 1.0 / (1.0 + np.exp(-self.logodds[n] * self.scale))

    def occupancy(self, n: int) -> NDArray[np.int8]:
        """(H, W) int8 in ROS OccupancyGrid convention for particle n's map."""
        return logodds_to_occupancy(self.logodds[n], self.scale)

    def known_cells(self) -> NDArray[np.int64]:
        """(N,) number of cells each particle has observed."""
        return np.count_nonzero(self.logodds.reshape(len(self.logodds), -1), axis=1)


def logodds_to_occupancy(logodds: NDArray[np.integer[Any]], scale: float = 1.0) -> NDArray[np.int8]:
    """Log-odds (any shape, times scale) -> int8 occupancy: -1 unknown (exactly 0), else 0..100."""
    if logodds.dtype == np.int8:   # the grids: a table of the 256 values, no float temporaries
        return _occupancy_table(scale).take(logodds.view(np.uint8))
    return _occupancy(logodds, scale)


@functools.lru_cache(maxsize=8)
def _occupancy_table(scale: float) -> NDArray[np.int8]:
    """Occupancy of each int8 log-odds, indexed by its byte (0..255)."""
    return _occupancy(np.arange(256, dtype=np.uint8).view(np.int8), scale)


def _occupancy(logodds: NDArray[np.integer[Any]], scale: float) -> NDArray[np.int8]:
    p = 1.0 / (1.0 + np.exp(-logodds.astype(np.float64) * scale))
    occ = np.rint(p * 100.0).astype(np.int8)
    occ[logodds == 0] = -1
    return occ
