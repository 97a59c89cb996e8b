"""Batched ray tracing through the particles' grids: no loop over beams or particles.

Every beam of every particle is traced once per update, as a digital line from the
cell of the beam's origin to the cell of its max-range end point: step k of a beam
with n steps is cell start + round(k * (end - start) / n), which is 8-connected and
equals Bresenham's line on axis and diagonal beams. The expected scan and the grid
update both read these cells: a measured range z ends at step round(z / R * n).
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Iterator

import numpy as np

from fastslam.filter.grid import CellSpace, GridMaps, LogOddsSteps
from fastslam.filter.scan import Beams
from fastslam.filter.scratch import scratch

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


CHUNK_ELEMENTS = 1 << 17  # samples per chunk: keeps temporaries small and in cache
SPACE_CELLS = 1 << 20     # cells of a space shared by consecutive chunks (see _spaces)
# The trimmed update (likelihood mode) is faster in larger chunks (fewer, longer passes);
# these keep its work arrays at a few MB (the Intel log in 66 MB, docs/benchmarks.md).
TRIM_CHUNK_ELEMENTS = 3 << 16


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
        return _step_of_range(self.steps, self.max_range, ranges)

    def range_of_step(self, k: NDArray[np.float64]) -> NDArray[np.float64]:
        """(n, M) distance from the origin of step k (n, M) of each beam [m]."""
        return np.minimum(k / np.maximum(self.steps, 1), 1.0) * self.max_range

    def first_step_at(self, distance: float) -> NDArray[np.int64]:
        """(n, M) first step of each beam at least this far from its origin."""
        return np.ceil(distance / self.max_range * self.steps).astype(np.int64)


def _step_of_range(steps: NDArray[np.int64], max_range: float | NDArray[np.float64],
                   ranges: NDArray[np.float64]) -> NDArray[np.int64]:
    k = np.rint(np.asarray(ranges) / max_range * steps)
    return np.minimum(k, steps).astype(np.int64)


@dataclass
class _Lines:
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

    def beams(self, sel: slice) -> _Lines:
        """The lines of the beams sel."""
        return _Lines(start=self.start, steps=self.steps[:, sel], slope=self.slope[:, sel],
                      shape=self.shape, base=self.base, space=self.space)

    def box(self) -> tuple[tuple[int, int], tuple[int, int]]:
        """Cell bounds lo <= (ix, iy) < hi of every traced cell inside the grid."""
        k, (h, w) = self.k_max, self.shape
        lo = np.maximum(self.start.min(axis=0) - k, 0)
        hi = np.minimum(self.start.max(axis=0) + k + 1, (w, h))
        return (int(lo[0]), int(lo[1])), (int(hi[0]), int(hi[1]))

    def in_space(self, space: CellSpace, first: int = 0) -> _Lines:
        """The same lines with the indices of their start cells in space (the lines'
        particles being the space's first .. first + n - 1)."""
        base = space.base(first + np.arange(len(self.start)), self.start[:, 1], self.start[:, 0])
        return _Lines(start=self.start, steps=self.steps, slope=self.slope, shape=self.shape, base=base,
                      space=space)


def _lines(grid: GridMaps, origins: NDArray[np.float64], angles: NDArray[np.float64],
           max_range: float | NDArray[np.float64]) -> _Lines:
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
    return _Lines(start=start, steps=steps, slope=slope, shape=(h, w))


def _to_cell(v: NDArray[np.float64], origin: float, resolution: float) -> NDArray[np.int64]:
    """GridMaps.world_to_cell of one coordinate."""
    return np.floor((v - origin) / resolution).astype(np.int64)


def _flat_inside(lines: _Lines, w: int, out: NDArray[np.integer[Any]]) -> NDArray[np.integer[Any]]:
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
    lines = _lines(maps, origins, angles, max_range)
    if isinstance(grid, CellSpace):
        space = grid
    else:
        lo, hi = lines.box()
        space = grid.cells(first, first + len(origins), lo, hi, traced=lines.steps.size * lines.k_max)
    return _trace(lines.in_space(space), float(max_range))


def _trace(lines: _Lines, max_range: float) -> Rays:
    """Cells along each beam of lines (in their space), every beam max_range long."""
    assert lines.base is not None and lines.space is not None
    space = lines.space
    h, w = lines.shape
    start, slope, base, steps = lines.start, lines.slope, lines.base, lines.steps
    index_type = base.dtype
    stride = space.stride
    k = np.arange(lines.k_max, dtype=np.float32)
    if lines.inside:
        flat = _flat_inside(lines, stride, np.empty(steps.shape + (len(k),), dtype=index_type))
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


def expected_ranges(grid: GridMaps, rays: Rays, min_range: float = 0.0) -> NDArray[np.float64]:
    """(n, M) distance to the first occupied cell (log-odds > 0) along each beam.

    Cells nearer than min_range (on the shortest beam's count of steps) are not looked
    at: the sensor cannot see them. A beam that meets nothing returns max_range.
    The cells are read through rays.space (grid: the same maps).
    """
    space = rays.space
    cells = space.values
    k0 = int(rays.first_step_at(min_range).min()) if min_range > 0 else 0
    flat = rays.flat[..., k0:]
    if rays.inside:
        occupied = cells.take(space.resolve(flat)) > 0
    else:
        occupied = (cells.take(space.resolve(np.maximum(flat, 0))) > 0) & (flat >= 0)
    first = occupied.argmax(axis=2)
    hit = np.take_along_axis(occupied, first[..., None], axis=2)[..., 0]
    return np.where(hit, rays.range_of_step(first + k0), rays.max_range)


def update_logodds(grid: GridMaps, rays: Rays, free_until: NDArray[np.int64],
                   hit_step: NDArray[np.int64], *, first_step: NDArray[np.int64], steps: LogOddsSteps) -> None:
    """Applies one scan to the traced particles' grids, each cell at most once.

    Args:
        free_until: (n, M) steps k with first_step <= k < free_until become more free.
        hit_step: (n, M) step of the cell the beam ended in, -1 for no hit; it becomes
            more occupied, and only occupied, even if another beam crossed it.
        first_step: (n, M) steps before it (the sensor's minimum range) are left alone.
        steps: increments and clamps in the grid's int8 units.
    """
    free, hit = _cells_to_update(rays, free_until, hit_step, first_step)
    _apply(rays.space, free, hit, steps)


def _cells_to_update(rays: Rays, free_until: NDArray[np.int64], hit_step: NDArray[np.int64],
                     first_step: NDArray[np.int64]) -> tuple[NDArray[np.integer[Any]], NDArray[np.integer[Any]]]:
    """Flat indices of the cells to make more free and of the hit cells (see update_logodds)."""
    free = _free_of(rays.flat, free_until, first_step, valid=None if rays.inside else rays.flat >= 0)
    has_hit = hit_step >= 0
    hit = np.take_along_axis(rays.flat, np.where(has_hit, hit_step, 0)[..., None], axis=2)[..., 0]
    return free, hit[has_hit & (hit >= 0)]


def _apply(space: CellSpace, free: NDArray[np.integer[Any]], hit: NDArray[np.integer[Any]],
           steps: LogOddsSteps) -> None:
    """One scan's update of the cells free (repeats allowed) and hit of space."""
    l_free, l_occ, l_min, l_max = steps
    free, hit = space.writable(free), space.writable(hit)
    cells = space.values
    lo, hi = np.iinfo(cells.dtype).min, np.iinfo(cells.dtype).max
    if l_free <= 0 <= l_occ and l_min <= l_max and lo <= l_min - l_free <= hi and lo <= l_max - l_occ <= hi:
        # The same sums and clamps in int8 without overflow: clamp first, then add.
        # Indexing with intp indices is much faster than with int32 ones or put.
        free = free.astype(np.intp, copy=False)
        hit = hit.astype(np.intp, copy=False)
        before = cells[hit]  # hit cells take l_occ alone: read them first
        # take with mode="wrap" reads what cells[free] reads, a little faster.
        f = np.take(cells, free, mode="wrap")
        np.maximum(f, l_min - l_free, out=f)
        f += np.int8(l_free)
        # Assigning through repeated indices writes once: one update per cell per scan.
        cells[free] = f
        np.minimum(before, l_max - l_occ, out=before)
        before += np.int8(l_occ)
        np.maximum(before, l_min, out=before)
        cells[hit] = before
        return
    before = cells[hit].astype(np.int16)  # hit cells take l_occ alone: read them first
    # Assigning through repeated indices writes once: one update per cell per scan.
    cells[free] = np.maximum(cells[free].astype(np.int16) + l_free, l_min)
    cells[hit] = np.clip(before + l_occ, l_min, l_max)


def update_trimmed(grid: GridMaps, origins: NDArray[np.float64], angles: NDArray[np.float64], beams: Beams,
                   steps: LogOddsSteps, *, max_range: float, groups: int, free_step: int = 1) -> None:
    """The grid update of observe without expected ranges (faster): beams are traced in
    groups of similar length, each only as far as its longest beam reaches, not to
    max_range (the cells of a beam's line then depend on its group's length).

    Args:
        origins: (N, 2) beam origins; angles: (N, M) beam directions, map frame.
        beams: the M beams (ranges, hits, the range each clears).
        groups: number of groups of beams of similar length.
        free_step: only every free_step-th beam (in angle) clears free space; the
            others only mark the cell of their end point.
    """
    ranges, hit, free_range, range_min = beams.ranges, beams.hit, beams.free_range, beams.range_min
    n_p, m = angles.shape
    reach = np.where(hit, ranges, free_range)
    order = np.argsort(reach, kind="stable")
    order = order[reach[order] > 0]                          # beams that clear nothing are skipped
    if len(order) == 0:
        return
    # Only every free_step-th beam (in angle) is traced; the others only mark their
    # end cells, computed directly from the end points.
    marked = np.zeros(0, dtype=np.intp)
    if free_step > 1:
        traced = (np.arange(m) % free_step) == 0
        marked = np.flatnonzero(hit & ~traced)
        order = order[traced[order]]
    parts = [p for p in np.array_split(order, min(groups, len(order))) if len(p)]
    cols = np.concatenate(parts)
    # each beam traced to its group's length (all groups at once: fewer, small, numpy calls)
    r = np.concatenate([np.full(len(sel), float(min(reach[sel].max(), max_range)) + grid.resolution)
                        for sel in parts])
    # a chunk's work arrays: the cells of its longest group, and the cells it frees (about)
    longest = max(len(sel) * (int(float(r[i]) / grid.resolution) + 2)
                  for i, sel in zip(np.cumsum([0] + [len(sel) for sel in parts])[:-1], parts))
    per_particle = max(longest, int(len(order) * (float(np.mean(reach[order])) / grid.resolution + 2)))
    per_chunk = max(1, TRIM_CHUNK_ELEMENTS // per_particle)
    h, w = grid.shape
    for a in range(0, n_p, per_chunk):
        b = min(n_p, a + per_chunk)
        lines = _lines(grid, origins[a:b], angles[a:b][:, cols], r)
        lo, hi = lines.box()
        marked_cells = np.zeros((b - a, 0, 2), dtype=np.int64)
        ok = np.zeros((b - a, 0), dtype=bool)
        if len(marked):
            a_m = angles[a:b][:, marked]
            ends = origins[a:b, None, :] + ranges[marked, None] * np.stack([np.cos(a_m), np.sin(a_m)], -1)
            marked_cells = grid.world_to_cell(ends)                           # (n, K, 2)
            ok = ((marked_cells[..., 0] >= 0) & (marked_cells[..., 0] < w) & (marked_cells[..., 1] >= 0)
                  & (marked_cells[..., 1] < h))
            if ok.any():
                inside = marked_cells[ok]
                lo = (min(lo[0], int(inside[:, 0].min())), min(lo[1], int(inside[:, 1].min())))
                hi = (max(hi[0], int(inside[:, 0].max()) + 1), max(hi[1], int(inside[:, 1].max()) + 1))
        space = grid.cells(a, b, lo, hi, traced=per_particle * (b - a))
        free_cells, hit_cells = _group_cells(lines.in_space(space), parts, r, ranges[cols], hit[cols],
                                             free_range[cols], range_min=range_min)
        if ok.any():
            i = np.broadcast_to(np.arange(b - a)[:, None], ok.shape)[ok]
            hit_cells.append(space.base(i, marked_cells[ok][:, 1], marked_cells[ok][:, 0]))
        _apply(space, free_cells, np.concatenate(hit_cells) if hit_cells else np.zeros(0, np.int64), steps)
        space.close()


def _group_cells(lines: _Lines, parts: list[NDArray[np.intp]], r: NDArray[np.float64],
                 ranges: NDArray[np.float64], hit: NDArray[np.bool_], free_range: NDArray[np.float64], *,
                 range_min: float) -> tuple[NDArray[np.intp], list[NDArray[np.integer[Any]]]]:
    """The cells to free (one intp array, repeats allowed) and the hit cells (per group)
    of the beams of lines (the groups `parts` one after the other, traced r long; ranges,
    hit, free_range in the same order)."""
    assert lines.base is not None and lines.space is not None
    hit_step = np.where(hit, _step_of_range(lines.steps, r, ranges), -1)
    until = np.where(hit, hit_step, _step_of_range(lines.steps, r, free_range) + 1)
    first_step = np.ceil(range_min / r * lines.steps).astype(np.int64)
    bounds = np.cumsum([0] + [len(sel) for sel in parts])
    groups = [lines.beams(slice(i, j)) for i, j in zip(bounds[:-1], bounds[1:])]
    free, hit_cells = [], []
    for i, ln in enumerate(groups):
        g = slice(bounds[i], bounds[i + 1])
        if ln.inside:
            assert ln.base is not None
            flat = _flat_inside(ln, lines.space.stride,
                                scratch("raycast_flat", ln.steps.shape + (ln.k_max,), ln.base.dtype))
            free.append(_free_of(flat, until[:, g], first_step[:, g]))
            cells = np.take_along_axis(flat, np.maximum(hit_step[:, g], 0)[..., None], axis=2)[..., 0]
            hit_cells.append(cells[hit_step[:, g] >= 0])
        else:
            rays = _trace(ln, float(r[bounds[i]]))
            f, h = _cells_to_update(rays, until[:, g], hit_step[:, g], first_step[:, g])
            free.append(f)
            hit_cells.append(h)
    # _apply indexes faster with intp (space.write_type); the narrow type made the passes above cheaper.
    out = scratch("raycast_free", (sum(len(f) for f in free),), lines.space.write_type)
    return np.concatenate(free, out=out), hit_cells


def _free_of(flat: NDArray[np.integer[Any]], until: NDArray[np.int64], first_step: NDArray[np.int64],
             valid: NDArray[np.bool_] | None = None) -> NDArray[np.integer[Any]]:
    """The cells of steps first_step <= k < until of flat (n, M, K), where valid."""
    # Row u of the table is the mask k < u: one row copied per beam, cheaper than a
    # comparison broadcast over every step ("clip" clips u to 0 .. K).
    table = _prefix_masks(flat.shape[2])
    mask = np.take(table, until, axis=0, out=scratch("raycast_mask", flat.shape, np.bool_), mode="clip")
    if first_step.any():
        mask &= ~np.take(table, first_step, axis=0, mode="clip")
    if valid is not None:
        mask &= valid
    return flat[mask]  # boolean indexing: much faster than np.compress with out


@functools.lru_cache(maxsize=64)
def _prefix_masks(k_max: int) -> NDArray[np.bool_]:
    """(K + 1, K) table whose row u is arange(K) < u."""
    table = np.greater.outer(np.arange(k_max + 1), np.arange(k_max))
    table.flags.writeable = False
    return table


def observe(grid: GridMaps, origins: NDArray[np.float64], angles: NDArray[np.float64], beams: Beams,
            steps: LogOddsSteps, *, max_range: float, expected: bool) -> NDArray[np.float64] | None:
    """Expected scan from each particle's map as it was, then the scan written into it,
    every beam traced to max_range.

    Runs over particles in chunks so the (n, M, K) temporaries stay small and in cache.

    Args:
        origins: (N, 2) beam origins; angles: (N, M) beam directions, map frame.
        beams: the M beams (ranges, hits, the range each clears, the sensor's minimum).
        expected: whether to compute the expected ranges.
    Returns:
        (N, M) expected ranges, or None.
    """
    ranges, hit, free_range, range_min = beams.ranges, beams.hit, beams.free_range, beams.range_min
    n_p, m = angles.shape
    if m == 0:  # no beam in the field of view: nothing to trace
        return np.empty((n_p, 0)) if expected else None
    k_guess = int(max_range / grid.resolution) + 2
    per_chunk = max(1, CHUNK_ELEMENTS // (m * k_guess))
    out = np.empty((n_p, m)) if expected else None
    for group in _spaces(grid, [(a, min(n_p, a + per_chunk)) for a in range(0, n_p, per_chunk)],
                         lambda a, b: _lines(grid, origins[a:b], angles[a:b], max_range)):
        for a, b, lines in group.chunks:
            rays = _trace(lines, max_range)
            if out is not None:
                out[a:b] = expected_ranges(grid, rays, range_min)
            hit_step = np.where(hit, rays.step_of_range(ranges), -1)
            until = np.where(hit, hit_step, rays.step_of_range(free_range) + 1)
            until = np.where(free_range > 0, until, 0)
            update_logodds(grid, rays, until, hit_step, first_step=rays.first_step_at(range_min), steps=steps)
        group.space.close()
    return out


@dataclass
class _Group:
    """Chunks of particles (first, stop, their lines in space) sharing one space."""

    space: CellSpace
    chunks: list[tuple[int, int, _Lines]]


def _spaces(grid: GridMaps, chunks: list[tuple[int, int]], lines_of: Callable[[int, int], _Lines],
            cells: int = SPACE_CELLS) -> Iterator[_Group]:
    """The chunks (first, stop) in groups, each with the space of the cells their lines
    reach: consecutive chunks share one while its box holds at most `cells` cells (a
    space costs some calls to open and close: fewer, larger ones for many small chunks)."""
    h, w = grid.shape
    i = 0
    while i < len(chunks):
        first = chunks[i][0]
        members: list[tuple[int, int, _Lines]] = []
        lo, hi = (w, h), (0, 0)
        traced = 0
        while i < len(chunks):
            a, b = chunks[i]
            lines = lines_of(a, b)
            l_lo, l_hi = lines.box()
            n_lo = (min(lo[0], l_lo[0]), min(lo[1], l_lo[1]))
            n_hi = (max(hi[0], l_hi[0]), max(hi[1], l_hi[1]))
            if members and (b - first) * (n_hi[0] - n_lo[0]) * (n_hi[1] - n_lo[1]) > cells:
                break
            members.append((a, b, lines))
            lo, hi, traced = n_lo, n_hi, traced + lines.steps.size * lines.k_max
            i += 1
        stop = members[-1][1]
        space = grid.cells(first, stop, lo, hi, traced=traced)
        yield _Group(space, [(a, b, ln.in_space(space, a - first)) for a, b, ln in members])
