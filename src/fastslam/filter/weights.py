"""Particle weights: the assignment's 1/(||d - z|| + 1) and a likelihood beam model,
both as log-weights so that weights can carry over between updates without underflow."""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from fastslam.filter.grid import GridMaps
from fastslam.filter.scan import Beams, end_points
from fastslam.geometry import transform_points

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


def assignment_log_weights(expected: NDArray[np.float64], measured: NDArray[np.float64],
                           valid: NDArray[np.bool_]) -> NDArray[np.float64]:
    """log of 1/(||d - z|| + 1) per particle over the valid beams only.

    Args:
        expected: (N, M) expected ranges d from each particle's map [m].
        measured: (M,) measured ranges z [m].
        valid: (M,) beams that count; the others are left out of both d and z.
    """
    diff = np.where(valid, expected - measured, 0.0)
    return -np.log1p(np.sqrt(np.sum(diff * diff, axis=1)))


def likelihood_log_weights(distances: NDArray[np.float64], valid: NDArray[np.bool_],
                           sigma: float, max_dist: float, gain: float) -> NDArray[np.float64]:
    """Endpoint model: sum over valid beams of -dist^2 / (2 sigma^2), dist capped.

    Args:
        distances: (N, M) distance from each beam's end point to the nearest occupied
            cell of the particle's map [m] (capped: an unexplained beam costs a constant).
        valid: (M,) beams with a real return.
        gain: exponent on the whole likelihood (< 1 flattens it, gmapping's smoothing).
    """
    d = np.minimum(distances, max_dist)
    return gain * np.sum(np.where(valid, -0.5 * (d / sigma) ** 2, 0.0), axis=1)


def normalise_log(log_w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Normalised weights from log-weights, subtracting the max before exp.

    Non-finite log-weights get weight 0; if none is finite the weights are uniform.
    """
    finite = np.isfinite(log_w)
    if not finite.any():
        return np.full(len(log_w), 1.0 / len(log_w))
    w = np.zeros(len(log_w))
    w[finite] = np.exp(log_w[finite] - log_w[finite].max())
    return w / w.sum()


class Weighing(NamedTuple):
    """What the likelihood weights of one scan need: each particle's pose (N, 3), the end
    points (the matcher's returns), and the model (config: likelihood_*)."""

    poses: NDArray[np.float64]
    beams: Beams
    sigma: float
    max_dist: float
    gain: float
    free: float    # likelihood_free: an end point in known free space, no wall near, costs this much again

    def some(self, a: int, b: int) -> Weighing:
        """The same for particles a..b-1."""
        return self._replace(poses=self.poses[a:b])


def scan_log_weights(grid: GridMaps, weighing: Weighing) -> NDArray[np.float64]:
    """(N,) each particle's log-likelihood of the end points against its map (before the scan is written)."""
    w = weighing
    dist = endpoint_distances(grid, w.poses, w.beams, max_dist=w.max_dist)
    log_w = likelihood_log_weights(dist, w.beams.hit, w.sigma, w.max_dist, w.gain)
    if w.free > 0:
        # end points in known free space with no wall near: the scan contradicts the map there
        wrong = (dist >= w.max_dist) & w.beams.hit & ends_in_free_space(grid, w.beams, w.poses)
        log_w = log_w - w.gain * w.free * wrong.sum(axis=1)
    return log_w


def ends_in_free_space(grid: GridMaps, beams: Beams, poses: NDArray[np.float64]) -> NDArray[np.bool_]:
    """(N, M) whether each beam's end point seen from each pose (N, 3) falls on a cell
    its particle's map holds free (log-odds below zero); outside the grid: no."""
    h, w = grid.shape
    x, y = transform_points(poses, end_points(beams, np.arange(len(beams.ranges))))
    ix = np.floor((x - grid.origin[0]) / grid.resolution).astype(np.intp)
    iy = np.floor((y - grid.origin[1]) / grid.resolution).astype(np.intp)
    inside = (ix >= 0) & (ix < w) & (iy >= 0) & (iy < h)
    cells = grid.values(np.arange(len(poses))[:, None], np.clip(iy, 0, h - 1), np.clip(ix, 0, w - 1))
    return inside & (cells < 0)


def endpoint_distances(grid: GridMaps, poses: NDArray[np.float64], beams: Beams, *,
                       max_dist: float = 0.3) -> NDArray[np.float64]:
    """(N, M) distance from each beam's end point to the nearest occupied cell centre
    of each particle's map, searched up to max_dist and capped there [m].

    Beams without a return (not beams.hit) have no end point: they get max_dist and
    are left out of the weight by its valid mask.
    """
    n = len(poses)
    m = len(beams.ranges)
    out = np.full((n, m), float(max_dist))
    sel = np.flatnonzero(beams.hit)
    if len(sel) == 0:
        return out
    res = grid.resolution
    h, w = grid.shape
    r = max(1, math.ceil(max_dist / res))
    d = np.arange(-r, r + 1)
    ox, oy = np.meshgrid(d, d)
    near = np.hypot(np.abs(ox) - 0.5, np.abs(oy) - 0.5) <= r   # cells that can be within reach
    ox, oy = ox[near], oy[near]                                 # (O,)
    x, y = transform_points(poses, end_points(beams, sel))               # (N, S)
    u = (x - grid.origin[0]) / res
    v = (y - grid.origin[1]) / res
    ix = np.floor(u).astype(np.int64)
    iy = np.floor(v).astype(np.int64)
    fx = (u - ix - 0.5).astype(np.float32)
    fy = (v - iy - 0.5).astype(np.float32)
    if ix.min() - r >= 0 and iy.min() - r >= 0 and ix.max() + r < w and iy.max() + r < h:
        # Every searched cell is inside (the usual case): no bounds to check.
        occupied = np.moveaxis(grid.values_around(np.arange(n)[:, None], iy, ix, oy, ox) > 0, 0, -1)  # (N, S, O)
    else:
        cx = ix[..., None] + ox                                 # (N, S, O)
        cy = iy[..., None] + oy
        inside = (cx >= 0) & (cx < w) & (cy >= 0) & (cy < h)
        cells = grid.values(np.arange(n)[:, None, None], np.clip(cy, 0, h - 1), np.clip(cx, 0, w - 1))
        occupied = (cells > 0) & inside
    # Distances to the occupied cells only (few of them), the least per end point by
    # a reduction over runs: the same float64 values as over the full (N, S, O) array.
    found = np.flatnonzero(occupied)
    point, j = np.divmod(found, len(ox))                        # end point (n * S + s), offset
    # float64 before the gathers (exact): no mixed int64 - float32 arithmetic after.
    dx = ox.astype(np.float64).take(j) - fx.astype(np.float64).reshape(-1).take(point)
    dy = oy.astype(np.float64).take(j) - fy.astype(np.float64).reshape(-1).take(point)
    d2 = np.square(dx, out=dx) + np.square(dy, out=dy)
    least = np.full(ix.size, np.inf)
    if len(found):
        runs = np.flatnonzero(np.concatenate(([True], point[1:] != point[:-1])))
        least[point[runs]] = np.minimum.reduceat(d2, runs)
    nearest = np.sqrt(least.reshape(ix.shape)) * res
    out[:, sel] = np.minimum(nearest, max_dist)
    return out
