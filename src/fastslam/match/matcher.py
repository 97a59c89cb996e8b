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
from typing import TYPE_CHECKING, Any, Optional, Protocol, Tuple

import numpy as np

from fastslam.config import SlamConfig
from fastslam.filter.grid import GridMaps
from fastslam.filter.scan import Beams, end_points, spread_returns
from fastslam.geometry import inv3, transform_points
from fastslam.match.refine import (
    ICP_ITERATIONS,
    hill_climb,
    icp_fit,
    prior_information,
    prior_on_bearing,
    surface_normals,
)
from fastslam.match.search import POOL, POOL_CELLS, grid_search, pick, pool_occupied, pool_signed, search_area, window

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray

    from fastslam.filter.motion import OdometryArc

    # _match_some's result: poses, trusted, covariance, score, scan information, free share
    MatchPart = Tuple[NDArray[np.float64], NDArray[np.bool_], Optional[NDArray[np.float64]], NDArray[np.float64],
                      Optional[NDArray[np.float64]], Optional[NDArray[np.float64]]]


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
    icp_beams: int = 0           # ICP (refine "icp") on at most this many returns; 0: beams
    icp_from_prior: bool = False  # ICP also from the prior's centre, the better fit kept
    icp_iterations: int = ICP_ITERATIONS  # the ICP's Gauss-Newton steps
    short_free: float = 0.0      # [m] free end points in runs spanning less than this do not count
    search_gain: float = 1.0     # nats per end point on a wall in the searches, against the prior
    prior_bearing: float = 0.0   # [rad] the ICP's prior along the searched bearing (prior_on_bearing); 0 = off

    @classmethod
    def from_config(cls, cfg: SlamConfig) -> MatchParams:
        return cls(beams=cfg.match_beams, xy_range=cfg.match_xy_range, theta_range=cfg.match_theta_range,
                   min_score=cfg.match_min_score, min_known=cfg.match_min_known, refine=cfg.match_refine,
                   covariance=cfg.match_spread == "match", free_space=cfg.match_max_free < 1.0,
                   max_free=cfg.match_max_free, icp_beams=cfg.match_icp_beams,
                   icp_from_prior=cfg.match_icp_from_prior, icp_iterations=cfg.match_icp_iterations,
                   short_free=cfg.match_short_free,
                   search_gain=cfg.match_search_gain, prior_bearing=cfg.match_prior_bearing)


@dataclass(frozen=True)
class Match:
    """The result of match_poses for N particles.

    poses: (N, 3) matched poses, map frame (the input poses where nothing was matched).
    trusted: (N,) bool, whether each match passed the checks.
    covariance: (N, 3, 3) of each match (ICP with covariance=True), else None.
    score: (N,) share of the matched end points on occupied 2x2 blocks (None: no match).
    scan_information: (N, 3, 3) what the ICP's end points alone know of each pose (its
    Hessian less the prior), over icp_points end points (ICP only, else None).
    free: (N,) share of the matched end points on known free cells with nothing occupied
    near (free_space only, else None; short runs left out: free_share).
    beyond_gate: (N,) the trusted matches farther from their motion prediction than the
    filter's gate, trusted for their score (set by the filter's gate, else None; the
    recovery's share rule keeps them all or withdraws every match).
    """

    poses: NDArray[np.float64]
    trusted: NDArray[np.bool_]
    covariance: NDArray[np.float64] | None = None
    score: NDArray[np.float64] | None = None  # (N,) share of the end points on occupied cells
    scan_information: NDArray[np.float64] | None = None
    icp_points: int = 0
    free: NDArray[np.float64] | None = None
    beyond_gate: NDArray[np.bool_] | None = None


class Helper(Protocol):
    """Another process that matches some particles (filter/pipeline.py): the same
    _match_some on the same window, so the same results to the bit."""

    def share(self, n: int) -> int:
        """How many of n particles (the last ones) to hand over now."""

    def submit(self, grid: GridMaps, args: tuple[Any, ...], size: int) -> None:
        """Starts _match_some(grid, *args) in chunks of size particles."""

    def result(self, grid: GridMaps, args: tuple[Any, ...], size: int) -> MatchPart:
        """Its result (computed here with the same arguments if the helper failed)."""


def match_poses(grid: GridMaps, poses: NDArray[np.float64], beams: Beams, params: MatchParams,
                prior: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
                arc: OdometryArc | None = None, origin: NDArray[np.float64] | None = None, *,
                helper: Helper | None = None) -> Match:
    """Matches the beams of one scan from each pose (N, 3) against that particle's map.

    prior: (centre (N, 3), std-devs (3,) along, across, heading) of the odometry prior;
    None: centred on poses with half the search window as std-devs. arc: the searches
    weigh candidates by the step's odometry model in its own terms about the centre
    instead (the ICP keeps the Gaussian: it starts from the searches' pick). origin: (N, 2)
    where each particle's step began, for params.prior_bearing (None: off). helper: matches
    the last particles meanwhile (each particle's result is its own: the same to the bit).
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
    far = far_range(local)
    dth = min(coarse / max(far, coarse), 0.1)                      # turn moving far points one pooled cell
    ka = math.ceil(params.theta_range / dth)
    reach = float(np.hypot(local[:, 0], local[:, 1]).max()) + params.xy_range + 2 * coarse
    x0, y0, x1, y1 = search_area(grid, poses, local, ka * dth, k0 * coarse, window(grid, poses, reach))
    if x1 - x0 < 4 * POOL or y1 - y0 < 4 * POOL:
        return nothing
    centre, spread = _prior(poses, params, prior)
    icp_points = None   # (end points, surface normals) for ICP: its own, more, returns if asked
    if params.refine == "icp":
        fine = sel if params.icp_beams <= params.beams else spread_returns(beams, params.icp_beams)
        icp_points = (end_points(beams, fine), surface_normals(beams, fine))
    # Particles in chunks whose pooled maps stay within MATCH_BYTES: a window across a
    # large building would otherwise take tens of MB.
    size = max(1, MATCH_BYTES // ((x1 - x0) * (y1 - y0) * 5 // 16))     # pooled maps (half, quarter) per particle
    every = (poses, centre, spread, local, icp_points, (x0, y0, x1, y1), k0, ka, dth, params, arc, origin)
    here = n - (helper.share(n) if helper is not None else 0)    # particles matched in this process
    if helper is not None and here < n:
        helper.submit(grid.view(here, n), _sliced(every, here, n), size)
    parts = [match_some(grid.view(0, here), _sliced(every, 0, here), size)] if here > 0 else []
    if helper is not None and here < n:
        parts.append(helper.result(grid.view(here, n), _sliced(every, here, n), size))
    pose, trusted, cov, score, info, free = _joined(parts)
    return Match(poses=pose, trusted=trusted, covariance=cov, score=score, scan_information=info,
                 icp_points=0 if icp_points is None else len(icp_points[0]), free=free)


def match_some(grid: GridMaps, args: tuple[Any, ...], size: int) -> MatchPart:
    """_match_some(grid, *args) in chunks of size particles, joined (a helper's share)."""
    n = grid.particles
    return _joined([_match_some(grid.view(a, min(n, a + size)), *_sliced(args, a, min(n, a + size)))
                    for a in range(0, n, size)])


def _joined(parts: list[MatchPart]) -> MatchPart:
    """The parts' results, particle after particle."""
    return tuple(None if parts[0][i] is None else np.concatenate([p[i] for p in parts])   # type: ignore[return-value]
                 for i in range(6))


def _sliced(args: tuple[Any, ...], a: int, b: int) -> tuple[Any, ...]:
    """_match_some's arguments for its particles a..b-1 (poses, centre, origin are per particle)."""
    poses, centre, *rest, origin = args
    return (poses[a:b], centre[a:b], *rest, None if origin is None else origin[a:b])


# numpy >= 1.22 interpolates a quantile as far_range does (numpy.lib.function_base._lerp);
# older numpy otherwise, and keeps np.percentile itself
_LERP_QUANTILES = tuple(int(p) for p in np.__version__.split(".")[:2]) >= (1, 22)


def far_range(local: NDArray[np.float64]) -> float:
    """The 90th percentile of the ranges of the end points local (M, 2), the value
    np.percentile gives, without its Python cost (0.1 ms, most of a small match's)."""
    r = np.hypot(local[:, 0], local[:, 1])
    if not _LERP_QUANTILES or len(r) < 2 or np.isnan(r).any():
        return float(np.percentile(r, 90))
    at = (len(r) - 1) * (90 / 100)        # numpy's "linear" method: between two order statistics
    below = math.floor(at)
    a, b = np.partition(r, (below, below + 1))[[below, below + 1]]
    t = at - below
    diff = b - a
    return float(b - diff * (1 - t) if t >= 0.5 else a + diff * t)


def _match_some(grid: GridMaps, poses: NDArray[np.float64], centre: NDArray[np.float64], spread: NDArray[np.float64],
                local: NDArray[np.float64], icp_points: tuple[NDArray[np.float64], NDArray[np.float64]] | None,
                box: tuple[int, int, int, int],
                k0: int, ka: int, dth: float, params: MatchParams, arc: OdometryArc | None,
                origin: NDArray[np.float64] | None
                ) -> tuple[NDArray[np.float64], NDArray[np.bool_], NDArray[np.float64] | None, NDArray[np.float64],
                           NDArray[np.float64] | None, NDArray[np.float64] | None]:
    """match_poses for the particles of grid (a view): (poses, trusted, covariance, score,
    scan information: the ICP's Hessian less the prior, or None, share on free cells or None)."""
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
                poses, turns, k0, coarse, centre, spread, m, params.search_gain, arc)
    # 2. the best coarse cell again on 2x2 cells, then on the map's own cells
    turns = np.array([-0.5, 0.0, 0.5]) * dth
    pose = pick(grid_search(half, w_origin, 2 * res, pose, turns, local, 2, flags=True),
                pose, turns, 2, 2 * res, centre, spread, m, params.search_gain, arc)
    turns = np.array([-0.25, 0.0, 0.25]) * dth
    scores = grid_search(grid, grid.origin, res, pose, turns, local, 1)
    pose = pick(scores, pose, turns, 1, res, centre, spread, m, params.search_gain, arc)
    # 3. finer than a cell
    cov = scan_info = None
    if icp_points is not None:
        if origin is not None and params.prior_bearing > 0:
            centre = prior_on_bearing(centre, origin, pose, params.prior_bearing)
        pose, info = _icp(grid, pose, icp_points[0], icp_points[1], centre, spread, params)
        scan_info = info - prior_information(centre, spread)
        if params.covariance:
            cov = inv3(info)
    else:
        pose = hill_climb(grid, pose, local, dth)
    flags = _flags_at(pose, local, half, w_origin, res)
    score = (flags > 0).mean(axis=1)
    trusted = (score >= params.min_score) & (known >= params.min_known)
    free = None
    if params.free_space:
        free = free_share(flags < 0, local, params)
        trusted &= free <= params.max_free
    return pose, trusted, cov, score, scan_info, free


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
        pool(grid.crop(y0, y1, x0, x1, a, b), out=(half[a:b], quarter[a:b]))
    return half, quarter


def _prior(poses: NDArray[np.float64], params: MatchParams,
           prior: tuple[NDArray[np.float64], NDArray[np.float64]] | None
           ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """(centre (N, 3), std-devs (3,)) of a match's odometry prior: the one given, its
    std-devs at least PRIOR_FLOOR; None: round poses, half the search window."""
    if prior is None:
        return poses, np.array([params.xy_range, params.xy_range, params.theta_range]) / 2
    return prior[0], np.maximum(prior[1], PRIOR_FLOOR)


def refine_poses(grid: GridMaps, poses: NDArray[np.float64], beams: Beams, params: MatchParams,
                 prior: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None) -> Match:
    """A short search, then the last stage of match_poses (ICP), from poses (N, 3) within
    a few cells of the match: tracking a pose from scan to scan between updates, where
    the odometry of one scan errs by centimetres but its heading by a degree or two
    (CSAIL), which moves far end points beyond ICP's reach.

    The search turns each pose by up to params.theta_range in steps that move the far
    end points two cells, and keeps the heading with the most end points within one
    cell of an occupied one (the smallest turn among equals). Trusted as match_poses
    trusts: min_score of the end points within one cell of an occupied one, and
    (free_space) at most max_free of them on known free cells with none occupied near.
    prior: (centre (N, 3), std-devs (3,)) or None, as for match_poses.
    """
    n = len(poses)
    if np.count_nonzero(beams.hit) < MIN_BEAMS:
        return Match(poses=poses.copy(), trusted=np.zeros(n, dtype=bool))
    few = spread_returns(beams, params.beams)
    coarse = end_points(beams, few)
    far = far_range(coarse)
    step = 2 * grid.resolution / max(far, 2 * grid.resolution)
    turns = np.arange(-1, 2) * step if params.theta_range <= 0 else \
        np.arange(-math.ceil(params.theta_range / step), math.ceil(params.theta_range / step) + 1) * step
    cand = np.repeat(poses[:, None, :], len(turns), axis=1)
    cand[..., 2] += turns
    on_wall, _ = neighbourhood_flags(grid, cand, coarse)                 # (N, A, M)
    best = np.argmax(on_wall.sum(axis=2) - 1e-3 * np.abs(turns) / step, axis=1)
    start = cand[np.arange(n), best]
    sel = few if params.icp_beams <= params.beams else spread_returns(beams, params.icp_beams)
    local = coarse if sel is few else end_points(beams, sel)
    centre, spread = _prior(poses, params, prior)
    pose, info = _icp(grid, start, local, surface_normals(beams, sel), centre, spread, params)
    occupied, free = neighbourhood_flags(grid, pose, local)
    score = occupied.mean(axis=1)
    trusted = score >= params.min_score
    share = free_share(free, local, params) if params.free_space else None
    if share is not None:
        trusted &= share <= params.max_free
    return Match(poses=pose, trusted=trusted, covariance=inv3(info) if params.covariance else None, score=score,
                 scan_information=info - prior_information(centre, spread), icp_points=len(sel), free=share)


def _icp(grid: GridMaps, start: NDArray[np.float64], local: NDArray[np.float64], normals: NDArray[np.float64],
         centre: NDArray[np.float64], spread: NDArray[np.float64], params: MatchParams
         ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """ICP (params.icp_iterations steps) from the searched poses start (N, 3); (params.icp_from_prior)
    also from the prior's centre, each particle keeping the start whose result fits better.

    The searches score end points on occupied cells, which a blurred wall a few cells
    thick makes flat in heading over a degree or two, while the ICP's basin is about
    half a degree (ACES: a search turned a prediction 0.5 degrees off to 0.7 degrees
    off, and the ICP settled on the ghost of a wall drawn at that turn); the motion's
    own prediction is often the better start."""
    steps = params.icp_iterations
    if not params.icp_from_prior:
        pose, info, _ = icp_fit(grid, start, local, normals, centre, spread, iterations=steps)
        return pose, info
    n = len(start)
    both = np.arange(2 * n) % n
    pose, info, fit = icp_fit(grid, np.concatenate([start, centre]), local, normals, centre[both], spread, maps=both,
                              iterations=steps)
    second = fit[n:] < fit[:n]
    return np.where(second[:, None], pose[n:], pose[:n]), np.where(second[:, None, None], info[n:], info[:n])


def free_share(free: NDArray[np.bool_], local: NDArray[np.float64], params: MatchParams) -> NDArray[np.float64]:
    """(N,) share of the end points local (M, 2) in known free space (free (N, M)),
    leaving out those in runs spanning less than params.short_free: people and doors put a
    quarter of a right match's end points in free space on the ACES bag, in short runs; a
    turned or shifted copy of a room puts whole walls there."""
    if params.short_free <= 0:
        return free.mean(axis=1)
    return in_long_runs(free, local, params.short_free).mean(axis=1)


def in_long_runs(flags: NDArray[np.bool_], local: NDArray[np.float64], length: float) -> NDArray[np.bool_]:
    """(N, M) whether each flagged end point (flags (N, M), returns in scan order at
    local (M, 2)) lies in a run of consecutive flagged ones whose first and last are at
    least length apart: a wall put where the map is free makes a long run, a person a
    short one."""
    m = flags.shape[1]
    k = np.arange(m)
    before = np.zeros_like(flags)
    before[:, 1:] = flags[:, :-1]
    after = np.zeros_like(flags)
    after[:, :-1] = flags[:, 1:]
    first = np.maximum.accumulate(np.where(flags & ~before, k, 0), axis=1)    # its run's first return
    last = np.minimum.accumulate(np.where(flags & ~after, k, m - 1)[:, ::-1], axis=1)[:, ::-1]
    span = local[last] - local[first]
    return flags & (np.hypot(span[..., 0], span[..., 1]) >= length)


_AROUND = np.array([-1, 0, 1])
_AROUND_Y, _AROUND_X = np.repeat(_AROUND, 3), np.tile(_AROUND, 3)   # the 3 x 3 cells, rows first


def neighbourhood_flags(grid: GridMaps, pose: NDArray[np.float64], local: NDArray[np.float64]
                        ) -> tuple[NDArray[np.bool_], NDArray[np.bool_]]:
    """(N, ..., M) each, for the end points local (M, 2) seen from the poses (N, ..., 3)
    on map n: whether an occupied cell lies within one cell of the end point's, and
    whether its cell is known free with none occupied near (outside the grid: neither)."""
    h, w = grid.shape
    x, y = transform_points(pose, local)
    # a cast truncates towards zero: floor's cell from 0 up, and below 1 either way (outside)
    ix = ((x - grid.origin[0]) / grid.resolution).astype(np.intp)
    iy = ((y - grid.origin[1]) / grid.resolution).astype(np.intp)
    inside = (ix >= 1) & (ix < w - 1) & (iy >= 1) & (iy < h - 1)
    maps = np.arange(len(pose)).reshape((-1,) + (1,) * (x.ndim - 1))
    np.minimum(np.maximum(ix, 1, out=ix), w - 2, out=ix)              # clamped inside
    np.minimum(np.maximum(iy, 1, out=iy), h - 2, out=iy)
    cells = grid.values_around(maps, iy, ix, _AROUND_Y, _AROUND_X)
    near = cells.max(axis=0) > 0                                       # the 3 x 3 cells, first axis
    free = inside & ~near & (cells[4] < 0)                             # the end point's own cell
    return inside & near, free


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
