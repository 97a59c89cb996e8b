"""Batched digital lines through the particles' grids: the cells each beam crosses, no
loop over beams or particles.

Every beam of every particle is traced once per update, as a digital line from the
cell of the beam's origin to the cell of its max-range end point: step k of a beam
with n steps is cell start + round(k * (end - start) / n), which is 8-connected and
equals Bresenham's line on axis and diagonal beams. The expected scan and the grid
update (raycast.py) both read these cells: a measured range z ends at step round(z / R * n).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from fastslam.filter.grid import CellSpace, GridMaps
from fastslam.filter.scratch import scratch

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


@dataclass
class Rays:
    """The traced cells of M beams for n particles.

    flat: (n, M, K) int32 (int64 for huge grids) indices of the cells in space (see
        CellSpace); steps past a beam's end continue along its line; -1 marks cells
        outside the grid (only when `inside` is False).
    steps: (n, M) number of steps of each beam (its max-range end cell is that step).
    max_range: R, the length every beam was traced to [m].
    inside: every traced cell lies in the grid, so no -1 needs checking.
    space: the cells the indices address.
    """

    flat: NDArray[np.integer[Any]]
    steps: NDArray[np.int64]
    max_range: float
    inside: bool
    space: CellSpace

    def step_of_range(self, ranges: NDArray[np.float64]) -> NDArray[np.int64]:
        """(n, M) step at which a range (M,) or (n, M) ends, clipped to the beam."""
        return range_step(self.steps, self.max_range, ranges)

    def range_of_step(self, k: NDArray[np.float64]) -> NDArray[np.float64]:
        """(n, M) distance from the origin of step k (n, M) of each beam [m]."""
        return np.minimum(k / np.maximum(self.steps, 1), 1.0) * self.max_range

    def first_step_at(self, distance: float) -> NDArray[np.int64]:
        """(n, M) first step of each beam at least this far from its origin."""
        return np.ceil(distance / self.max_range * self.steps).astype(np.int64)


def range_step(steps: NDArray[np.int64], max_range: float | NDArray[np.float64],
                   ranges: NDArray[np.float64]) -> NDArray[np.int64]:
    """Step at which each range ends on beams of `steps` steps traced max_range long, clipped to the beam."""
    k = np.rint(np.asarray(ranges) / max_range * steps)
    return np.minimum(k, steps).astype(np.int64)


@dataclass
class Lines:
    """The digital lines of M beams for n particles, before any cell is listed:
    step k of a beam is cell base + rint(slope_x k) + rint(slope_y k) * w."""

    start: NDArray[np.int64]      # (n, 2) cell of each origin
    steps: NDArray[np.int64]      # (n, M)
    slope: NDArray[np.float32]    # (n, M, 2)
    shape: tuple[int, int]        # (H, W) of the grid
    base: NDArray[np.integer[Any]] | None = None   # (n,) index of each start cell in space
    space: CellSpace | None = None

    @property
    def k_max(self) -> int:
        """Steps 0 .. k_max - 1 are traced."""
        return int(self.steps.max()) + 1

    @property
    def inside(self) -> bool:
        """Every traced cell lies in the grid."""
        # Cells of step k lie within k cells (Chebyshev) of the start: a box of k_max
        # cells around every start decides whether any cell can fall outside.
        k, (h, w) = self.k_max, self.shape
        return bool(self.start.min() >= k and self.start[:, 0].max() + k < w and self.start[:, 1].max() + k < h)

    def particles(self, first: int, stop: int) -> Lines:
        """The lines of particles first..stop-1 (not yet in a space)."""
        return Lines(start=self.start[first:stop], steps=self.steps[first:stop], slope=self.slope[first:stop],
                     shape=self.shape)

    def beams(self, sel: slice) -> Lines:
        """The lines of the beams sel."""
        return Lines(start=self.start, steps=self.steps[:, sel], slope=self.slope[:, sel],
                      shape=self.shape, base=self.base, space=self.space)

    def box(self) -> tuple[tuple[int, int], tuple[int, int]]:
        """Cell bounds lo <= (ix, iy) < hi of every traced cell inside the grid."""
        k, (h, w) = self.k_max, self.shape
        lo = np.maximum(self.start.min(axis=0) - k, 0)
        hi = np.minimum(self.start.max(axis=0) + k + 1, (w, h))
        return (int(lo[0]), int(lo[1])), (int(hi[0]), int(hi[1]))

    def in_space(self, space: CellSpace, first: int = 0) -> Lines:
        """The same lines with the indices of their start cells in space (the lines'
        particles being the space's first .. first + n - 1)."""
        base = space.base(first + np.arange(len(self.start)), self.start[:, 1], self.start[:, 0])
        return Lines(start=self.start, steps=self.steps, slope=self.slope, shape=self.shape, base=base,
                      space=space)


def beam_lines(grid: GridMaps, origins: NDArray[np.float64], angles: NDArray[np.float64],
           max_range: float | NDArray[np.float64]) -> Lines:
    """The lines of trace, not yet in a space; max_range: one length, or one per beam (M,)."""
    n_p, m = angles.shape
    h, w = grid.shape
    start = grid.world_to_cell(origins)                                   # (n, 2)
    # x and y apart: the same values as on stacked (..., 2) arrays, without the
    # slow reductions over an axis of two.
    dx = _to_cell(origins[:, 0, None] + max_range * np.cos(angles), grid.origin[0], grid.resolution)
    dy = _to_cell(origins[:, 1, None] + max_range * np.sin(angles), grid.origin[1], grid.resolution)
    dx -= start[:, 0, None]
    dy -= start[:, 1, None]
    steps = np.maximum(np.abs(dx), np.abs(dy))                            # (n, M)
    div = np.maximum(steps, 1)
    slope = np.empty((n_p, m, 2), dtype=np.float32)
    np.divide(dx, div, out=slope[..., 0], casting="unsafe")  # float64 quotient, then float32
    np.divide(dy, div, out=slope[..., 1], casting="unsafe")
    return Lines(start=start, steps=steps, slope=slope, shape=(h, w))


def _to_cell(v: NDArray[np.float64], origin: float, resolution: float) -> NDArray[np.int64]:
    """GridMaps.world_to_cell of one coordinate."""
    return np.floor((v - origin) / resolution).astype(np.int64)


def flat_inside(lines: Lines, w: int, out: NDArray[np.integer[Any]]) -> NDArray[np.integer[Any]]:
    """out (n, M, K): index of every step of lines that lie inside the grid (w: the
    space's stride)."""
    assert lines.base is not None
    k = np.arange(out.shape[2], dtype=np.float32)
    fx = np.multiply(lines.slope[..., 0, None], k, out=scratch("raycast_fx", out.shape, np.float32))
    np.rint(fx, out=fx)
    fy = np.multiply(lines.slope[..., 1, None], k, out=scratch("raycast_fy", out.shape, np.float32))
    np.rint(fy, out=fy)
    fy *= np.float32(w)
    fx += fy  # exact: |value| < 2**24
    np.copyto(out, fx, casting="unsafe")
    np.add(out, lines.base[:, None, None], out=out)
    return out


def trace(grid: GridMaps | CellSpace, origins: NDArray[np.float64], angles: NDArray[np.float64],
          max_range: float, first: int = 0) -> Rays:
    """Cells along each beam.

    Args:
        grid: the particles' maps, or the space of them to address (a GridMaps gives
            the space of the cells these beams reach: close() rays.space after writing).
        origins: (n, 2) beam origins in the map frame [m].
        angles: (n, M) beam directions in the map frame [rad].
        max_range: beam length [m].
        first: the particles traced are first .. first + n - 1 (with a GridMaps).
    """
    maps = grid.grid if isinstance(grid, CellSpace) else grid
    lines = beam_lines(maps, origins, angles, max_range)
    if isinstance(grid, CellSpace):
        space = grid
    else:
        lo, hi = lines.box()
        space = grid.cells(first, first + len(origins), lo, hi, traced=lines.steps.size * lines.k_max)
    return trace_lines(lines.in_space(space), float(max_range))


def trace_lines(lines: Lines, max_range: float) -> Rays:
    """Cells along each beam of lines (in their space), every beam max_range long."""
    assert lines.base is not None and lines.space is not None
    space = lines.space
    h, w = lines.shape
    start, slope, base, steps = lines.start, lines.slope, lines.base, lines.steps
    index_type = base.dtype
    stride = space.stride
    k = np.arange(lines.k_max, dtype=np.float32)
    if lines.inside:
        flat = flat_inside(lines, stride, np.empty(steps.shape + (len(k),), dtype=index_type))
        return Rays(flat=flat, steps=steps, max_range=max_range, inside=True, space=space)
    fx = np.multiply(slope[..., 0, None], k)                              # (n, M, K) float32
    np.rint(fx, out=fx)
    fy = np.multiply(slope[..., 1, None], k)
    np.rint(fy, out=fy)
    ix = start[:, 0, None, None] + fx.astype(index_type)
    iy = start[:, 1, None, None] + fy.astype(index_type)
    flat = base[:, None, None] + (ix - start[:, 0, None, None]) + (iy - start[:, 1, None, None]) * stride
    flat[(ix < 0) | (ix >= w) | (iy < 0) | (iy >= h)] = -1
    return Rays(flat=flat.astype(index_type), steps=steps, max_range=max_range, inside=False, space=space)
