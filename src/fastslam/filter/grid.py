"""Per-particle log-odds occupancy grids sharing one geometry.

Cell (iy, ix) of particle n: its lower-left corner lies at origin + (ix, iy) * resolution,
rows go along +y, exactly like nav_msgs/OccupancyGrid's data. Log-odds are stored
quantised in int8 (log-odds = value * scale, 0 = unknown): one byte a cell, since the
maps are the memory and the memory traffic of the filter. The clamp limits set the
scale, so l_min..l_max always fit in -127..127.

Every read and write of cell values goes through this small API, so that a storage
other than one dense (N, H, W) array (the tiles of fastslam.filter.tiles) can
implement it; code outside this module and the backends never touches the storage:

- ``values(n, iy, ix)``: the cells at integer arrays (broadcast together) of particles
  and cells, all inside the grid (callers clamp or mask first); ``values_around(n, iy,
  ix, dy, dx)`` the same cells moved by each of K offsets (kernels, searches);
- ``particle_map(n)``: particle n's whole map as an (H, W) array, read only (for
  publishing, saving, evaluating);
- ``crop(y0, y1, x0, x1, first, stop)``: a dense (k, y1 - y0, x1 - x0) window of
  particles first..stop-1, read only (the matcher pools it);
- ``cells(first, stop, lo, hi)``: a CellSpace, the flat addressing the ray tracer reads
  and writes a box of cells of particles first..stop-1 through (``close()`` it after
  writing);
- ``put(n, iy, ix, values)``: writes cells (tests, tools);
- ``view(first, stop)``: the maps of some particles, sharing their cells (reads); ``copy()``;
- ``reorder(parent)`` after resampling, ``grow_to`` keeping world coordinates,
  ``known_cells()``, ``occupancy(n)``, ``probability(n)``;
- memory: ``nbytes`` (allocated now), ``growth_bytes(...)`` (what a growth adds),
  ``grown_shape(...)``, ``bytes_for(n, shape)`` (a fresh grid).
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
FEW_CELLS = 8192   # values_around: up to this many cells per offset, one gather for all offsets


class LogOddsSteps(NamedTuple):
    """The map update's increments and clamps in a grid's int8 units."""

    free: int   # added to a cell a beam crosses (< 0)
    occ: int    # added to the cell a beam ends in (> 0)
    lo: int     # clamps
    hi: int


class CellSpace:
    """The ray tracer's flat addressing of a box of cells of particles first..stop-1.

    Cell (iy, ix) of the i-th of them (i = 0 .. stop - first - 1) has the index
    ((lead + i) * rows + iy - y0) * stride + ix - x0, a step of one row adds stride,
    and its value lies at values[resolve(index)]. Cells to write become indices into
    values through writable(indices); close() after writing (a backend may keep the
    box apart from its storage until then). This one addresses a dense (N, H, W)
    array directly: resolve and writable return their indices.
    """

    def __init__(self, grid: GridMaps, values: NDArray[np.int8], *, rows: int, stride: int, y0: int, x0: int,
                 lead: int, size: int) -> None:
        self.grid = grid
        self._values = values
        self.rows, self.stride, self.y0, self.x0, self.lead = rows, stride, y0, x0, lead
        # int32 indices are cheaper to compute and to keep; int64 past 2**31 cells
        self.index_type: type = np.int32 if size < np.iinfo(np.int32).max else np.int64
        self.write_type: type = np.intp   # of the cells to write, for writable: numpy indexes fastest with intp

    @property
    def values(self) -> NDArray[np.int8]:
        """The flat array the positions index."""
        return self._values

    def base(self, i: NDArray[np.integer[Any]], iy: NDArray[np.integer[Any]],
             ix: NDArray[np.integer[Any]]) -> NDArray[np.integer[Any]]:
        """Indices of cells (iy, ix) of the i-th particles (arrays broadcast together)."""
        flat = ((self.lead + np.asarray(i, dtype=np.int64)) * self.rows + (iy - self.y0)) * self.stride + (ix - self.x0)
        return np.asarray(flat).astype(self.index_type)

    def resolve(self, flat: NDArray[np.integer[Any]]) -> NDArray[np.integer[Any]]:
        """Positions in values of the cells at these indices."""
        return flat

    def writable(self, flat: NDArray[np.integer[Any]]) -> NDArray[np.integer[Any]]:
        """Positions in values to write the cells at these indices to (re-read values after)."""
        return flat

    def close(self) -> None:
        """Done writing."""


class GridMaps:
    """N log-odds grids on a common lattice that can grow: the dense backend, one
    (N, H, W) int8 array `logodds` (fastslam.filter.tiles: the tiled one).

    Args:
        n: particles.
        shape: (H, W) cells.
        resolution: cell size [m].
        origin: (x, y) world coordinates of the lower-left corner of cell (0, 0) [m].
        l_limit: largest |log-odds| to represent; sets the quantisation step.
    """

    def __init__(self, n: int, shape: tuple[int, int], resolution: float,
                 origin: tuple[float, float], l_limit: float = 5.0) -> None:
        self._init_geometry(n, shape, resolution, origin, l_limit)
        self.logodds: NDArray[np.int8] = np.zeros((n,) + tuple(shape), dtype=LOGODDS_DTYPE)

    def _init_geometry(self, n: int, shape: tuple[int, int], resolution: float, origin: tuple[float, float],
                       l_limit: float) -> None:
        self.resolution = float(resolution)
        self.origin = np.array(origin, dtype=float)
        self.scale = float(l_limit) / QMAX  # log-odds of one quantisation step
        self.particles = int(n)
        self._shape = (int(shape[0]), int(shape[1]))

    def quantise(self, value: float) -> int:
        """A log-odds value in grid units, never rounded to zero."""
        q = int(np.clip(np.rint(value / self.scale), -QMAX, QMAX))
        return q if q != 0 else int(np.sign(value))

    def steps(self, l_free: float, l_occ: float, l_min: float, l_max: float) -> LogOddsSteps:
        """Log-odds increments and clamps in grid units."""
        return LogOddsSteps(self.quantise(l_free), self.quantise(l_occ), self.quantise(l_min), self.quantise(l_max))

    @property
    def shape(self) -> tuple[int, int]:
        return self._shape

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
        left, right, down, up = self._padding(xmin, ymin, xmax, ymax, fraction)
        self._grow_storage(left, right, down, up)
        h, w = self.shape
        self._shape = (h + down + up, w + left + right)
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

    def _grow_storage(self, left: int, right: int, down: int, up: int) -> None:
        h, w = self.shape
        grown = np.zeros((self.particles, h + down + up, w + left + right), dtype=LOGODDS_DTYPE)
        grown[:, down:down + h, left:left + w] = self.logodds
        self.logodds = grown

    def grown_shape(self, xmin: float, ymin: float, xmax: float, ymax: float, *,
                    fraction: float = 0.5) -> tuple[int, int]:
        """(H, W) after grow_to with these arguments."""
        if self.covers(xmin, ymin, xmax, ymax):
            return self.shape
        left, right, down, up = self._padding(xmin, ymin, xmax, ymax, fraction)
        h, w = self.shape
        return h + down + up, w + left + right

    # -- memory (the node's budget) ---------------------------------------------------
    @staticmethod
    def bytes_for(n: int, shape: tuple[int, int]) -> int:
        """Bytes n dense maps of shape (H, W) take (every cell held)."""
        return int(n) * int(shape[0]) * int(shape[1]) * np.dtype(LOGODDS_DTYPE).itemsize

    @property
    def nbytes(self) -> int:
        """Bytes the maps hold now."""
        return int(self.logodds.nbytes)

    def growth_bytes(self, xmin: float, ymin: float, xmax: float, ymax: float, *, fraction: float = 0.5) -> int:
        """Bytes grow_to with these arguments allocates: the whole grown maps, since the
        old ones are freed only after the copy (0 when the box is covered)."""
        if self.covers(xmin, ymin, xmax, ymax):
            return 0
        return self.bytes_for(self.particles, self.grown_shape(xmin, ymin, xmax, ymax, fraction=fraction))

    # -- cells ------------------------------------------------------------------------
    def values(self, n: ArrayLike, iy: ArrayLike, ix: ArrayLike) -> NDArray[np.int8]:
        """int8 cells (iy, ix) of particles n, integer arrays broadcast together; every
        cell must lie inside the grid (clamp or mask first)."""
        h, w = self.shape
        flat = (np.asarray(n, dtype=np.intp) * h + np.asarray(iy, dtype=np.intp)) * w + np.asarray(ix, dtype=np.intp)
        return self.logodds.reshape(-1).take(flat)

    def values_around(self, n: ArrayLike, iy: ArrayLike, ix: ArrayLike, dy: ArrayLike, dx: ArrayLike, *,
                      out: NDArray[np.int8] | None = None) -> NDArray[np.int8]:
        """(K,) + shape int8 cells (iy + dy[k], ix + dx[k]) of particles n: n, iy, ix
        broadcast together to shape, offsets dy, dx (K,) in ascending order of
        dy * W + dx; every cell must lie inside the grid. out: where to write them."""
        h, w = self.shape
        base = (np.asarray(n, dtype=np.intp) * h + np.asarray(iy, dtype=np.intp)) * w + np.asarray(ix, dtype=np.intp)
        shifts = (np.asarray(dy, dtype=np.intp) * w + np.asarray(dx, dtype=np.intp)).tolist()
        if out is None:
            out = np.empty((len(shifts),) + base.shape, dtype=LOGODDS_DTYPE)
        cells = self.logodds.reshape(-1)
        if base.size < FEW_CELLS:   # one gather: the calls would cost more than the cells
            np.take(cells, base + np.array(shifts, dtype=np.intp).reshape((-1,) + (1,) * base.ndim), out=out)
            return out
        lo = shifts[0]
        at = base + lo                                  # >= 0: every cell is inside
        for k, sh in enumerate(shifts):                 # cells at + (sh - lo): no index array per offset
            np.take(cells[sh - lo:], at, out=out[k], mode="clip")
        return out

    def particle_map(self, n: int) -> NDArray[np.int8]:
        """(H, W) particle n's map, read only (here a view: copy it to keep it)."""
        return _read_only(self.logodds[n])

    def crop(self, y0: int, y1: int, x0: int, x1: int, first: int = 0, stop: int | None = None) -> NDArray[np.int8]:
        """(k, y1 - y0, x1 - x0) cells y0 <= iy < y1, x0 <= ix < x1 of particles
        first..stop-1 (default all), inside the grid; read only."""
        return _read_only(self.logodds[first:stop, y0:y1, x0:x1])

    def put(self, n: ArrayLike, iy: ArrayLike, ix: ArrayLike, values: ArrayLike) -> None:
        """Writes cells (iy, ix) of particles n (as values reads them)."""
        self.logodds[n, iy, ix] = values

    def copy(self) -> GridMaps:
        """Independent maps with the same cells and geometry."""
        other = GridMaps.__new__(GridMaps)
        other.__dict__.update(self.__dict__)
        other.origin = self.origin.copy()
        other.logodds = self.logodds.copy()
        return other

    def view(self, first: int, stop: int | None = None) -> GridMaps:
        """A GridMaps of the maps of particles first..stop-1 (default particle first
        alone), sharing their cells (no copy): for reads of those maps only."""
        stop = first + 1 if stop is None else stop
        some = GridMaps.__new__(GridMaps)
        some._init_geometry(stop - first, self.shape, self.resolution, (float(self.origin[0]), float(self.origin[1])),
                            1.0)
        some.scale = self.scale
        some.logodds = self.logodds[first:stop]
        return some

    def cells(self, first: int, stop: int, lo: tuple[int, int] | None = None, hi: tuple[int, int] | None = None,
              *, traced: int = 0) -> CellSpace:
        """The ray tracer's addressing of cells lo <= (ix, iy) < hi (default the whole
        grid) of particles first..stop-1; traced: about how many cells it will visit
        (a backend may pick its way from it). Here: the dense array itself."""
        h, w = self.shape
        return CellSpace(self, self.logodds.reshape(-1), rows=h, stride=w, y0=0, x0=0, lead=first,
                         size=self.logodds.size)

    def clear(self) -> None:
        """Every map back to unknown (the geometry stays)."""
        self.logodds.fill(0)

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

    def probability(self, n: int) -> NDArray[np.float64]:
        """(H, W) occupancy probability of particle n's map."""
        return 1.0 / (1.0 + np.exp(-self.particle_map(n) * self.scale))

    def occupancy(self, n: int) -> NDArray[np.int8]:
        """(H, W) int8 in ROS OccupancyGrid convention for particle n's map."""
        return logodds_to_occupancy(self.particle_map(n), self.scale)

    def known_cells(self) -> NDArray[np.int64]:
        """(N,) number of cells each particle has observed."""
        return np.count_nonzero(self.logodds.reshape(len(self.logodds), -1), axis=1)


def _read_only(a: NDArray[Any]) -> NDArray[Any]:
    v = a.view()
    v.flags.writeable = False
    return v


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
