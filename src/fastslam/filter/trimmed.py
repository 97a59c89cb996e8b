"""The likelihood mode's grid update: no expected ranges, so beams are traced in groups
of similar length, each group only as far as its longest beam reaches.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from fastslam.filter.grid import GridMaps, LogOddsSteps
from fastslam.filter.raycast import apply_update, cells_to_update, free_of
from fastslam.filter.rays import Lines, beam_lines, flat_inside, range_step, trace_lines
from fastslam.filter.scan import Beams
from fastslam.filter.scratch import scratch
from fastslam.filter.weights import Weighing, scan_log_weights

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


# The trimmed update (likelihood mode) is faster in larger chunks (fewer, longer passes);
# these keep its work arrays at a few MB (the Intel log in 66 MB, docs/benchmarks.md).
TRIM_CHUNK_ELEMENTS = 3 << 16


def clearing_step(angles: NDArray[np.float64], step: int, spacing: float) -> int:
    """The k of "every k-th beam clears free space": step, or the least k that puts the
    clearing beams (evenly spread angles, rad) at least spacing [deg] apart (0: step)."""
    if spacing <= 0 or len(angles) < 2:
        return step
    between = abs(math.remainder(float(angles[1] - angles[0]), 2 * math.pi))
    if between <= 0:
        return step
    # a laser's 0.5 degrees, stored in float32, may be a hair under: 1.5 degrees is 3 of them, not 4
    return max(step, math.ceil(math.radians(spacing) / between - 0.01))


class Writer(Protocol):
    """Another process that weighs some particles and writes the scan into their maps
    (filter/pipeline.py): the same write_some on the same arguments, so the same to the bit."""

    def write_share(self, n: int) -> int:
        """How many of n particles (the last ones) to hand over now."""

    def submit_writes(self, grid: GridMaps, first: int, args: tuple[Any, ...], origins: NDArray[np.float64],
                      reach: float) -> None:
        """Starts write_some(grid.view(first, N), args); origins (N, 2): every particle's beams
        start there and reach at most reach [m]."""

    def written(self, grid: GridMaps, first: int, args: tuple[Any, ...]) -> NDArray[np.float64] | None:
        """Takes its writes into grid (or writes them here if the helper failed); its weights."""


def update_trimmed(grid: GridMaps, origins: NDArray[np.float64], angles: NDArray[np.float64], beams: Beams,
                   steps: LogOddsSteps, *, max_range: float, groups: int, free_step: int = 1,
                   weighing: Weighing | None = None, writer: Writer | None = None) -> NDArray[np.float64] | None:
    """The grid update of raycast.observe without expected ranges (faster): beams are traced in
    groups of similar length, each only as far as its longest beam reaches, not to
    max_range (the cells of a beam's line then depend on its group's length).

    Args:
        origins: (N, 2) beam origins; angles: (N, M) beam directions, map frame.
        beams: the M beams (ranges, hits, the range each clears).
        groups: number of groups of beams of similar length.
        free_step: only every free_step-th beam (in angle) clears free space; the
            others only mark the cell of their end point.
        weighing: each particle is weighed first, against its map before the scan.
        writer: weighs and writes the last particles meanwhile (each particle's are its own).

    Returns:
        (N,) the log-likelihoods (weighing), else None.
    """
    n = grid.particles
    args = (origins, angles, beams, steps, {"max_range": max_range, "groups": groups, "free_step": free_step},
            weighing)
    here = n - (writer.write_share(n) if writer is not None else 0)
    if writer is None or here == n:
        return write_some(grid, args)
    theirs = _part(args, here, n)
    reach = max(max_range, float(beams.ranges[beams.hit].max(initial=0.0))) + 2 * grid.resolution
    writer.submit_writes(grid, here, theirs, origins, reach)
    mine = write_some(grid.view(0, here), _part(args, 0, here)) if here > 0 else None
    there = writer.written(grid, here, theirs)
    if weighing is None:
        return None
    return there if mine is None else np.concatenate([mine, there])


def write_some(grid: GridMaps, args: tuple[Any, ...]) -> NDArray[np.float64] | None:
    """update_trimmed(grid, *args[:4], **args[4], weighing=args[5]) in this process (a writer's share)."""
    origins, angles, beams, steps, options, weighing = args
    log_w = None if weighing is None else scan_log_weights(grid, weighing)
    _write(grid, origins, angles, beams, steps, **options)
    return log_w


def _part(args: tuple[Any, ...], a: int, b: int) -> tuple[Any, ...]:
    """write_some's arguments for particles a..b-1."""
    origins, angles, beams, steps, options, weighing = args
    return (origins[a:b], angles[a:b], beams, steps, options, None if weighing is None else weighing.some(a, b))


def _write(grid: GridMaps, origins: NDArray[np.float64], angles: NDArray[np.float64], beams: Beams,
           steps: LogOddsSteps, *, max_range: float, groups: int, free_step: int) -> None:
    ranges, hit, free_range, range_min = beams.ranges, beams.hit, beams.free_range, beams.range_min
    n_p, m = angles.shape
    far = hit & (ranges > free_range)    # past max_range (mark_range): marked like an untraced beam, traced as free
    hit = hit & ~far
    reach = np.where(hit, ranges, free_range)
    order = np.argsort(reach, kind="stable")
    order = order[reach[order] > 0]                          # beams that clear nothing are skipped
    if len(order) == 0:
        return
    # Only every free_step-th beam (in angle) is traced; the others only mark their
    # end cells, computed directly from the end points.
    marks = far
    if free_step > 1:
        traced = (np.arange(m) % free_step) == 0
        marks = marks | (hit & ~traced)
        order = order[traced[order]]
    marked = np.flatnonzero(marks)
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
    # the lines and the marked end cells of every particle at once (small arrays: fewer calls)
    every_line = beam_lines(grid, origins, angles[:, cols], r)
    every_marked = np.zeros((n_p, 0, 2), dtype=np.int64)
    every_ok = np.zeros((n_p, 0), dtype=bool)
    if len(marked):
        a_m = angles[:, marked]
        ends = origins[:, None, :] + ranges[marked, None] * np.stack([np.cos(a_m), np.sin(a_m)], -1)
        every_marked = grid.world_to_cell(ends)                                   # (N, K, 2)
        every_ok = ((every_marked[..., 0] >= 0) & (every_marked[..., 0] < w) & (every_marked[..., 1] >= 0)
                    & (every_marked[..., 1] < h))
    for a in range(0, n_p, per_chunk):
        b = min(n_p, a + per_chunk)
        lines = every_line.particles(a, b)
        lo, hi = lines.box()
        marked_cells, ok = every_marked[a:b], every_ok[a:b]
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
        apply_update(space, free_cells, np.concatenate(hit_cells) if hit_cells else np.zeros(0, np.int64), steps)
        space.close()


def _group_cells(lines: Lines, parts: list[NDArray[np.intp]], r: NDArray[np.float64],
                 ranges: NDArray[np.float64], hit: NDArray[np.bool_], free_range: NDArray[np.float64], *,
                 range_min: float) -> tuple[NDArray[np.intp], list[NDArray[np.integer[Any]]]]:
    """The cells to free (one intp array, repeats allowed) and the hit cells (per group)
    of the beams of lines (the groups `parts` one after the other, traced r long; ranges,
    hit, free_range in the same order)."""
    assert lines.base is not None and lines.space is not None
    hit_step = np.where(hit, range_step(lines.steps, r, ranges), -1)
    until = np.where(hit, hit_step, range_step(lines.steps, r, free_range) + 1)
    first_step = np.ceil(range_min / r * lines.steps).astype(np.int64)
    bounds = np.cumsum([0] + [len(sel) for sel in parts])
    groups = [lines.beams(slice(i, j)) for i, j in zip(bounds[:-1], bounds[1:])]
    free, hit_cells = [], []
    for i, ln in enumerate(groups):
        g = slice(bounds[i], bounds[i + 1])
        if ln.inside:
            assert ln.base is not None
            flat = flat_inside(ln, lines.space.stride,
                                scratch("raycast_flat", ln.steps.shape + (ln.k_max,), ln.base.dtype))
            free.append(free_of(flat, until[:, g], first_step[:, g]))
            # each beam's cell at its hit step: one take (take_along_axis builds index grids)
            k = np.maximum(hit_step[:, g], 0)
            cells = flat.reshape(-1).take(np.arange(0, flat.size, flat.shape[2]).reshape(k.shape) + k)
            hit_cells.append(cells[hit_step[:, g] >= 0])
        else:
            rays = trace_lines(ln, float(r[bounds[i]]))
            f, h = cells_to_update(rays, until[:, g], hit_step[:, g], first_step[:, g])
            free.append(f)
            hit_cells.append(h)
    # apply_update indexes faster with intp (space.write_type); the narrow type made the passes above cheaper.
    out = scratch("raycast_free", (sum(len(f) for f in free),), lines.space.write_type)
    return np.concatenate(free, out=out), hit_cells
