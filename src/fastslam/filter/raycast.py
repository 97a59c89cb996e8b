"""The expected scan and the grid update along traced beams (rays.py), in chunks of
particles, no loop over beams or particles.

A measured range z ends at step round(z / R * n) of a beam traced R long in n steps;
each cell changes at most once per scan, and a hit cell only by the hit.
"""
from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable, Iterator

import numpy as np

from fastslam.filter.grid import CellSpace, GridMaps, LogOddsSteps
from fastslam.filter.rays import Lines, Rays, beam_lines, trace_lines
from fastslam.filter.scan import Beams
from fastslam.filter.scratch import scratch

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


CHUNK_ELEMENTS = 1 << 17  # samples per chunk: keeps temporaries small and in cache
SPACE_CELLS = 1 << 20     # cells of a space shared by consecutive chunks (see _spaces)


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
    free, hit = cells_to_update(rays, free_until, hit_step, first_step)
    apply_update(rays.space, free, hit, steps)


def cells_to_update(rays: Rays, free_until: NDArray[np.int64], hit_step: NDArray[np.int64],
                     first_step: NDArray[np.int64]) -> tuple[NDArray[np.integer[Any]], NDArray[np.integer[Any]]]:
    """Flat indices of the cells to make more free and of the hit cells (see update_logodds)."""
    free = free_of(rays.flat, free_until, first_step, valid=None if rays.inside else rays.flat >= 0)
    has_hit = hit_step >= 0
    hit = np.take_along_axis(rays.flat, np.where(has_hit, hit_step, 0)[..., None], axis=2)[..., 0]
    return free, hit[has_hit & (hit >= 0)]


def apply_update(space: CellSpace, free: NDArray[np.integer[Any]], hit: NDArray[np.integer[Any]],
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


def free_of(flat: NDArray[np.integer[Any]], until: NDArray[np.int64], first_step: NDArray[np.int64],
             valid: NDArray[np.bool_] | None = None) -> NDArray[np.integer[Any]]:
    """The cells of steps first_step <= k < until of flat (n, M, K), where valid."""
    # Row u of the table is the mask k < u: one row copied per beam, cheaper than a
    # comparison broadcast over every step ("clip" clips u to 0 .. K).
    table = _prefix_masks(flat.shape[2])
    mask = np.take(table, until, axis=0, out=scratch("raycast_mask", flat.shape, np.bool_), mode="clip")
    if first_step.any():
        # less the rows k < min(first_step, until): inside the first, so one xor drops them
        below = np.take(table, np.minimum(first_step, until), axis=0, mode="clip",
                        out=scratch("raycast_mask_below", flat.shape, np.bool_))
        np.bitwise_xor(mask, below, out=mask)
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
                         lambda a, b: beam_lines(grid, origins[a:b], angles[a:b], max_range)):
        for a, b, lines in group.chunks:
            rays = trace_lines(lines, max_range)
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
    chunks: list[tuple[int, int, Lines]]


def _spaces(grid: GridMaps, chunks: list[tuple[int, int]], lines_of: Callable[[int, int], Lines],
            cells: int = SPACE_CELLS) -> Iterator[_Group]:
    """The chunks (first, stop) in groups, each with the space of the cells their lines
    reach: consecutive chunks share one while its box holds at most `cells` cells (a
    space costs some calls to open and close: fewer, larger ones for many small chunks)."""
    h, w = grid.shape
    i = 0
    while i < len(chunks):
        first = chunks[i][0]
        members: list[tuple[int, int, Lines]] = []
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
