"""Scan matching of every particle against its own map, all particles at once: a pure
function of plain values (maps, poses, beams, parameters, prior) that moves nothing.

1. a correlative search over a grid of candidate poses around each pose, on the map
   max-pooled to 4x4 cells (0.2 m at 0.05 m), so that a wall within a coarse cell of
   an end point counts and a wide window (translation and heading) is cheap;
2. the same search, narrower, on the map pooled to 2x2 cells and then on the map
   itself, each level around the previous level's best pose (search.py);
3. hill climbing with halving steps (gmapping's optimiser) on the bilinearly
   interpolated log-odds of occupied cells, for a pose finer than a cell; or (`icp`)
   a few Gauss-Newton steps pulling each end point towards the weighted mean of the
   occupied cell centres near it, along the scan's surface normal, weighed against
   the odometry prior; its inverse Hessian is the match's covariance (refine.py).

The odometry prior keeps a particle where odometry put it along directions the scan
cannot tell (a corridor): either half the search window around the given poses, or
a given centre and spread (the motion model's for this step, much tighter for short
steps).

A match is trusted when enough of the matched end points lie on occupied cells
(`min_score`) of a map that knows enough cells near the robot (`min_known`). The
filter decides what to do with it (it samples around trusted matches).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from fastslam.config import SlamConfig
from fastslam.filter.grid import GridMaps
from fastslam.filter.scan import Beams, end_points, spread_returns
from fastslam.geometry import inv3, transform_points
from fastslam.match.refine import hill_climb, icp, surface_normals
from fastslam.match.search import POOL, POOL_CELLS, grid_search, pick, pool_occupied, pool_signed, search_area, window

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


MIN_BEAMS = 10         # fewer returns than this: nothing to match
# The motion prior never gets narrower than this: odometry of a standing robot still
# errs by about half a cell, and the heading by a few tenths of a degree.
PRIOR_FLOOR = np.array([0.025, 0.025, 0.01])    # along, across [m], heading [rad]
MATCH_BYTES = 3 << 20   # pooled maps of one chunk of particles (see match_poses)


@dataclass(frozen=True)
class MatchParams:
    """What the matcher needs of the configuration (see SlamConfig's match_* fields)."""

    beams: int = 60              # at most this many returns, evenly spread
    xy_range: float = 0.2        # [m] search half-width in x and y
    theta_range: float = 0.1     # [rad] search half-width in heading
    min_score: float = 0.5       # share of matched end points on occupied cells to trust a match
    min_known: int = 100         # occupied 4x4-cell blocks in reach needed to trust a match
    refine: str = "hill"         # "hill" or "icp"
    covariance: bool = False     # return the ICP's covariance (refine "icp" only)
    free_space: bool = False     # end points in known free space count against a candidate, and
    max_free: float = 1.0        # a match with a larger share of them is not trusted

    @classmethod
    def from_config(cls, cfg: SlamConfig) -> MatchParams:
        return cls(beams=cfg.match_beams, xy_range=cfg.match_xy_range, theta_range=cfg.match_theta_range,
                   min_score=cfg.match_min_score, min_known=cfg.match_min_known, refine=cfg.match_refine,
                   covariance=cfg.match_spread == "match", free_space=cfg.match_max_free < 1.0,
                   max_free=cfg.match_max_free)


@dataclass(frozen=True)
class Match:
    """The result of match_poses for N particles.

    poses: (N, 3) matched poses, map frame (the input poses where nothing was matched).
    trusted: (N,) bool, whether each match passed the checks.
    covariance: (N, 3, 3) of each match (ICP with covariance=True), else None.
    score: (N,) share of the matched end points on occupied 2x2 blocks (None: no match).
    """

    poses: NDArray[np.float64]
    trusted: NDArray[np.bool_]
    covariance: NDArray[np.float64] | None = None
    score: NDArray[np.float64] | None = None  # (N,) share of the end points on occupied cells


def match_poses(grid: GridMaps, poses: NDArray[np.float64], beams: Beams, params: MatchParams,
                prior: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None) -> Match:
    """Matches the beams of one scan from each pose (N, 3) against that particle's map.

    prior: (centre (N, 3), std-devs (3,) along, across, heading) of the odometry prior;
    None: centred on poses with half the search window as std-devs.
    """
    n = len(poses)
    nothing = Match(poses=poses.copy(), trusted=np.zeros(n, dtype=bool))
    if np.count_nonzero(beams.hit) < MIN_BEAMS:
        return nothing
    sel = spread_returns(beams, params.beams)
    local = end_points(beams, sel)
    res = grid.resolution
    coarse = POOL * res
    k0 = max(1, math.ceil(params.xy_range / coarse))
    far = float(np.percentile(np.hypot(local[:, 0], local[:, 1]), 90))
    dth = min(coarse / max(far, coarse), 0.1)                      # turn moving far points one pooled cell
    ka = math.ceil(params.theta_range / dth)
    reach = float(np.hypot(local[:, 0], local[:, 1]).max()) + params.xy_range + 2 * coarse
    x0, y0, x1, y1 = search_area(grid, poses, local, ka * dth, k0 * coarse, window(grid, poses, reach))
    if x1 - x0 < 4 * POOL or y1 - y0 < 4 * POOL:
        return nothing
    if prior is None:
        centre = poses
        spread = np.array([params.xy_range, params.xy_range, params.theta_range]) / 2
    else:
        centre, spread = prior[0], np.maximum(prior[1], PRIOR_FLOOR)
    normals = surface_normals(beams, sel) if params.refine == "icp" else None
    # Particles in chunks whose pooled maps stay within MATCH_BYTES: a window across a
    # large building would otherwise take tens of MB.
    size = max(1, MATCH_BYTES // ((x1 - x0) * (y1 - y0) * 5 // 16))     # pooled maps (half, quarter) per particle
    found = [_match_some(grid.view(a, min(n, a + size)), poses[a:a + size], centre[a:a + size], spread, local,
                         normals, (x0, y0, x1, y1), k0, ka, dth, params)
             for a in range(0, n, size)]
    pose, trusted, score = (np.concatenate([f[i] for f in found]) for i in (0, 1, 3))
    cov = None if found[0][2] is None else np.concatenate([f[2] for f in found])
    return Match(poses=pose, trusted=trusted, covariance=cov, score=score)


def _match_some(grid: GridMaps, poses: NDArray[np.float64], centre: NDArray[np.float64], spread: NDArray[np.float64],
                local: NDArray[np.float64], normals: NDArray[np.float64] | None, box: tuple[int, int, int, int],
                k0: int, ka: int, dth: float, params: MatchParams
                ) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64] | None, NDArray[np.float64]]:
    """match_poses for the particles of grid (a view): (poses, trusted, covariance, score)."""
    res = grid.resolution
    coarse = POOL * res
    x0, y0, _, _ = box
    half, quarter = _pooled(grid, box, params.free_space)          # 2x2, 4x4 cells: occupied if any is
    known = np.count_nonzero(quarter > 0, axis=(1, 2))             # (N,) occupied 4x4 blocks in reach
    w_origin = grid.origin + np.array([x0, y0]) * res
    m = len(local)
    # 1. coarse: wide window on 4x4 cells
    turns = np.arange(-ka, ka + 1) * dth
    pose = pick(grid_search(quarter, w_origin, coarse, poses, turns, local, k0, flags=True),
                poses, turns, k0, coarse, centre, spread, m)
    # 2. the best coarse cell again on 2x2 cells, then on the map's own cells
    turns = np.array([-0.5, 0.0, 0.5]) * dth
    pose = pick(grid_search(half, w_origin, 2 * res, pose, turns, local, 2, flags=True),
                pose, turns, 2, 2 * res, centre, spread, m)
    turns = np.array([-0.25, 0.0, 0.25]) * dth
    scores = grid_search(grid, grid.origin, res, pose, turns, local, 1)
    pose = pick(scores, pose, turns, 1, res, centre, spread, m)
    # 3. finer than a cell
    cov = None
    if normals is not None:
        pose, info = icp(grid, pose, local, normals, centre, spread)
        if params.covariance:
            cov = inv3(info)
    else:
        pose = hill_climb(grid, pose, local, dth)
    flags = _flags_at(pose, local, half, w_origin, res)
    score = (flags > 0).mean(axis=1)
    trusted = (score >= params.min_score) & (known >= params.min_known)
    if params.free_space:
        trusted &= (flags < 0).mean(axis=1) <= params.max_free
    return pose, trusted, cov, score


def _pooled(grid: GridMaps, box: tuple[int, int, int, int], signed: bool) -> tuple[NDArray[np.int8], NDArray[np.int8]]:
    """The maps' cells x0 <= ix < x1, y0 <= iy < y1 pooled to 2x2 and 4x4 cells
    (pool_signed or pool_occupied), a few maps at a time (their crops stay small)."""
    x0, y0, x1, y1 = box
    n = grid.particles
    pool = pool_signed if signed else pool_occupied
    half = np.empty((n, (y1 - y0) // 2, (x1 - x0) // 2), dtype=np.int8)
    quarter = np.empty((n, (y1 - y0) // 4, (x1 - x0) // 4), dtype=np.int8)
    maps = max(1, POOL_CELLS // ((y1 - y0) * (x1 - x0)))
    for a in range(0, n, maps):
        b = min(n, a + maps)
        half[a:b], quarter[a:b] = pool(grid.crop(y0, y1, x0, x1, a, b))
    return half, quarter


def _flags_at(pose: NDArray[np.float64], local: NDArray[np.float64], half: NDArray[np.int8],
              w_origin: NDArray[np.float64], res: float) -> NDArray[np.int8]:
    """(N, M) flags of the 2x2-pooled maps half (N, h, w), lower-left corner w_origin,
    under the end points local (M, 2) seen from pose (N, 3): > 0 occupied (< 0 free
    with pool_signed)."""
    n = len(pose)
    x, y = transform_points(pose, local)
    cx = np.clip(((x - w_origin[0]) / (2 * res)).astype(np.int64), 0, half.shape[2] - 1)
    cy = np.clip(((y - w_origin[1]) / (2 * res)).astype(np.int64), 0, half.shape[1] - 1)
    return half[np.arange(n)[:, None], cy, cx]
