"""Scan-matching proposal and beam end-point distances (the improved mode, gmapping-like).

Every particle matches the scan against its own map, all particles at once:

1. a correlative search over a grid of candidate poses around the predicted pose, on
   the map max-pooled to 4x4 cells (0.2 m at 0.05 m), so that a wall within a coarse
   cell of an end point counts and a wide window (translation and heading) is cheap;
2. the same search, narrower, on the map pooled to 2x2 cells and then on the map
   itself, each level around the previous level's best pose;
3. hill climbing with halving steps (gmapping's optimiser) on the bilinearly
   interpolated log-odds of occupied cells, for a pose finer than a cell; or
   (`match_refine: icp`) a few Gauss-Newton steps pulling each end point towards the
   weighted mean of the occupied cell centres near it, along the scan's surface
   normal, weighed against the odometry prior; its covariance can set the spread of
   the sample (`match_spread: match`).

The odometry prior (`match_prior`) keeps a particle where odometry put it along
directions the scan cannot tell (a corridor): either half the search window around
the particle's own sample, or the motion model's spread for this step around the
noise-free prediction (much tighter for short steps).

A candidate's score is the sum over end points of the occupied evidence max(l, 0) of
the cell each end point falls in (log-odds in grid units). Translations of a level
are whole cells of that level, so a candidate's cells are the cells of its heading
plus a constant flat offset: one gather per end point and candidate, no trigonometry
per candidate. The pooled maps are built once per update, only in the window the
scans of all particles can reach.

A match is trusted when enough of the matched end points lie on occupied cells
(`match_min_score`) of a map that knows enough cells near the robot
(`match_min_known`); the particle is then drawn around the matched pose with
std-devs `match_sigma_xy` / `match_sigma_theta`. Untrusted particles keep their
odometry sample. The likelihood weight (slam.py) uses the same evenly spread
returns (`returns_subset`) at the matched pose.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import NDArray

from fastslam.geometry import cholesky3, cos_sin, inv3, solve3, wrap_angle
from fastslam.filter.grid import GridMaps, scratch
from fastslam.filter.scan import Beams

if TYPE_CHECKING:
    from fastslam.filter.slam import FastSlam

POOL = 4               # coarse level: cells per side of a pooled cell
FINE_ITERATIONS = 6    # hill-climbing steps (a step halves when no neighbour improves)
MIN_BEAMS = 10         # fewer returns than this: nothing to match
# The motion prior never gets narrower than this: odometry of a standing robot still
# errs by about half a cell, and the heading by a few tenths of a degree.
PRIOR_FLOOR = np.array([0.025, 0.025, 0.01])    # along, across [m], heading [rad]
SEARCH_MARGIN = 0.5    # [m] beyond the coarse search: the finer stages and ICP move a little further
ICP_ITERATIONS = 3
ICP_RADIUS = 2         # cells searched around each end point for occupied ones
ICP_SIGMA = 0.05       # [m] std-dev of an end point about its cell centre
ICP_SPREAD = 1.0       # [cells] std-dev of the weights of occupied centres around an end point
NORMAL_GAP = 0.3       # [m] neighbouring returns farther apart give no surface normal


def _spread_returns(beams: Beams, count: int) -> NDArray[np.intp]:
    """Indices of at most count returns (beams.hit), evenly spread over the scan."""
    sel = np.flatnonzero(beams.hit)
    if len(sel) <= count:
        return sel
    return sel[np.unique(np.linspace(0, len(sel) - 1, count).astype(np.intp))]


def returns_subset(beams: Beams, count: int) -> Beams:
    """The beams of at most count returns, evenly spread: the end points the matcher
    uses, and the likelihood weight with them (an end point costs a 2-D search)."""
    sel = _spread_returns(beams, count)
    return Beams(angles=beams.angles[sel], ranges=beams.ranges[sel], hit=beams.hit[sel],
                 free_range=beams.free_range[sel], range_min=beams.range_min, mount=beams.mount)


def _end_points(beams: Beams, sel: NDArray[np.intp]) -> NDArray[np.float64]:
    """(M, 2) end points of the selected beams in the robot frame [m]."""
    r = beams.ranges[sel]
    a = beams.angles[sel]
    return np.stack([beams.mount[0] + r * np.cos(a), beams.mount[1] + r * np.sin(a)], axis=1)


def _world(poses: NDArray[np.float64], local: NDArray[np.float64]) -> tuple[NDArray, NDArray]:
    """End points of local (M, 2) seen from poses (..., 3): x, y each (..., M)."""
    c, s = cos_sin(poses[..., 2, None])
    x = poses[..., 0, None] + c * local[:, 0] - s * local[:, 1]
    y = poses[..., 1, None] + s * local[:, 0] + c * local[:, 1]
    return x, y


def _cell_score(logodds: NDArray[np.int8]) -> NDArray[np.int8]:
    """1 for an occupied cell, else 0.

    Occupied or not, never how strongly: cells the robot saw many times (behind it)
    would otherwise pull the match backwards along a corridor.
    """
    return (logodds > 0).view(np.int8)


def _grid_search(level: NDArray[np.int8], origin: NDArray[np.float64], cell: float,
                 poses: NDArray[np.float64], turns: NDArray[np.float64], local: NDArray[np.float64],
                 k: int, flags: bool = False) -> NDArray[np.int64]:
    """Scores (N, A, (2k+1)^2) of poses turned by turns (A,) and shifted by -k..k cells.

    level: (N, Hv, Wv) log-odds (only max(l, 0) counts) with cells of size `cell` and
    lower-left corner `origin`, or (flags) already the 0/1 cell scores. Candidate
    t = (dy + k) * (2k + 1) + (dx + k).
    """
    n, hv, wv = level.shape
    cand = np.repeat(poses[:, None, :], len(turns), axis=1)
    cand[..., 2] += turns
    x, y = _world(cand, local)                                            # (N, A, M)
    # Cells near the edge are clamped so every shifted cell stays inside: end points
    # there are at most k cells off, in a part of the window nothing was seen in.
    cx = np.minimum(np.maximum(np.floor((x - origin[0]) / cell).astype(np.int64), k), wv - 1 - k)
    cy = np.minimum(np.maximum(np.floor((y - origin[1]) / cell).astype(np.int64), k), hv - 1 - k)
    flat = (np.arange(n)[:, None, None] * hv + cy) * wv + cx                # (N, A, M)
    d = np.arange(-k, k + 1)
    shifts = (d[:, None] * wv + d[None, :]).reshape(-1).tolist()            # (T,), ascending
    # End points first: one gather per shift, from the flat map offset by the shift
    # (no (N, A, T, M) index array), and the sum over end points adds whole (N, A)
    # slabs. Every shifted cell is inside (clamped above), so mode="clip" never clips.
    lo = shifts[0]
    at = np.ascontiguousarray(flat.transpose(2, 0, 1), dtype=np.intp)       # (M, N, A)
    at += lo                                                                # >= 0: cells are clamped k from the edge
    f = level.reshape(-1)
    vals = scratch("grid_search", (len(shifts),) + at.shape, level.dtype)  # (T, M, N, A), reused
    for i, s in enumerate(shifts):
        np.take(f[s - lo:], at, out=vals[i], mode="clip")                   # cells flat + s (s - lo >= 0)
    # Scores of 0/1 cells over M end points: M < 2**7 fits int8, M < 2**15 int16.
    acc = np.int8 if len(local) < 128 else np.int16
    sums = (vals if flags else _cell_score(vals)).sum(axis=1, dtype=acc)  # (T, N, A)
    return sums.transpose(1, 2, 0).astype(np.int64, order="C")


def _pick(scores: NDArray[np.int64], poses: NDArray[np.float64], turns: NDArray[np.float64],
          k: int, cell: float, start: NDArray[np.float64], prior: NDArray[np.float64], beams: int
          ) -> NDArray[np.float64]:
    """Best candidate of each particle as a pose (N, 3).

    Scores become log-likelihoods as in _nats; the odometry prediction `start` (N, 3)
    adds a Gaussian prior with std-devs prior (3,) along and across its heading and of
    the heading, so that along a corridor, where the scan cannot tell, the particle
    stays where odometry put it.
    """
    n, a, t = scores.shape
    d = np.arange(-k, k + 1)
    ox = (poses[:, 0] - start[:, 0])[:, None] + np.tile(d, 2 * k + 1)[None, :] * cell   # (N, T)
    oy = (poses[:, 1] - start[:, 1])[:, None] + np.repeat(d, 2 * k + 1)[None, :] * cell
    oa = wrap_angle(poses[:, 2] - start[:, 2])[:, None] + turns[None, :]                # (N, A)
    along, across = ox, oy  # an isotropic prior needs no turning
    if prior[0] != prior[1]:
        c, s_ = cos_sin(start[:, 2, None])
        along, across = c * ox + s_ * oy, c * oy - s_ * ox                               # start's frame
    log_prior = -0.5 * (((along / prior[0]) ** 2 + (across / prior[1]) ** 2)[:, None, :]
                        + ((oa / prior[2]) ** 2)[:, :, None])
    s = _nats(scores, beams) + log_prior
    best = s.reshape(n, -1).argmax(axis=1)
    ia, it = np.divmod(best, t)
    iy, ix = np.divmod(it, 2 * k + 1)
    out = poses.copy()
    out[:, 0] += d[ix] * cell
    out[:, 1] += d[iy] * cell
    out[:, 2] += turns[ia]
    return out


def _nats(scores: NDArray[np.int64], beams: int) -> NDArray[np.float64]:
    """Scores (N, ...) as log-likelihoods relative to each particle's best.

    A candidate that explains a fraction f less than the best leaves about f * beams
    end points unexplained and gets log-likelihood -f * beams.
    """
    top = scores.reshape(len(scores), -1).max(axis=1)
    top = np.maximum(top, 1).reshape((-1,) + (1,) * (scores.ndim - 1))
    return (scores - top) / top * beams


def _bilinear_scores(logodds: NDArray[np.int8], origin: NDArray[np.float64], cell: float,
                     cand: NDArray[np.float64], local: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N, C) sum over end points of the bilinearly interpolated evidence max(l, 0)
    of the maps (N, H, W), in grid units.

    Unlike the searches on whole cells (occupied or not), the log-odds magnitude
    counts here: within a wall a few cells thick its most often hit cells, the
    surface, pull the end points (median Intel ATE 0.21 -> 0.18 m).
    """
    n, h, w = logodds.shape
    x, y = _world(cand, local)                                            # (N, C, M)
    u = (x - origin[0]) / cell - 0.5
    v = (y - origin[1]) / cell - 0.5
    i0 = np.minimum(np.maximum(np.floor(u), 0), w - 2)
    j0 = np.minimum(np.maximum(np.floor(v), 0), h - 2)
    fu = np.minimum(np.maximum(u - i0, 0.0), 1.0)
    fv = np.minimum(np.maximum(v - j0, 0.0), 1.0)
    flat = (np.arange(n)[:, None, None] * h + j0.astype(np.intp)) * w + i0.astype(np.intp)
    f = logodds.reshape(-1)

    def ev(offset: int) -> NDArray[np.float32]:
        # f[offset:] instead of flat + offset: no index array per corner.
        return np.maximum(f[offset:].take(flat), 0).astype(np.float32)

    a, b = ev(0), ev(1)
    c, d = ev(w), ev(w + 1)
    val = (a * (1 - fu) + b * fu) * (1 - fv) + (c * (1 - fu) + d * fu) * fv
    return val.sum(axis=2)


def _pool_occupied(level: NDArray[np.int8]) -> tuple[NDArray[np.int8], NDArray[np.int8]]:
    """(N, H, W) -> 0/1 flags (N, H/2, W/2) and (N, H/4, W/4): whether any cell of each
    2x2 and 4x4 block is occupied (H, W multiples of 4).

    Column pairs of a contiguous flag array are read as one uint16 each, row pairs
    as the two halves of a doubled row: cheaper than maxima of strided int8 views.
    A few maps at a time, in reused work arrays: the temporaries stay in cache.
    """
    n, h, w = level.shape
    maps = 8  # at a time
    half = np.empty((n, h // 2, w // 2), dtype=np.bool_)
    quarter = np.empty((n, h // 4, w // 4), dtype=np.bool_)
    for a in range(0, n, maps):
        b = min(n, a + maps)
        rows = np.maximum(level[a:b, 0::2, :], level[a:b, 1::2, :],
                          out=scratch("pool_rows", (b - a, h // 2, w), np.int8))
        occupied = np.greater(rows, 0, out=rows.view(np.bool_))
        np.not_equal(occupied.view(np.uint16), 0, out=half[a:b])
        pairs = half[a:b].reshape(b - a, h // 4, w)                       # rows 2i, 2i+1 side by side
        quads = np.bitwise_or(pairs[:, :, :w // 2], pairs[:, :, w // 2:],
                              out=scratch("pool_quads", (b - a, h // 4, w // 2), np.bool_))
        np.not_equal(quads.view(np.uint16), 0, out=quarter[a:b])
    return half.view(np.int8), quarter.view(np.int8)


def _window(grid: GridMaps, poses: NDArray[np.float64], reach: float) -> tuple[int, int, int, int]:
    """Cell bounds (x0, y0, x1, y1) of the part of the grid within reach of any pose,
    with sides a multiple of POOL cells."""
    h, w = grid.shape
    lo = grid.world_to_cell(poses[:, :2].min(axis=0) - reach)
    hi = grid.world_to_cell(poses[:, :2].max(axis=0) + reach) + 1
    x0, y0 = (int(v) for v in np.maximum(lo, 0))
    x1 = min(w, x0 + POOL * math.ceil((int(hi[0]) - x0) / POOL))
    y1 = min(h, y0 + POOL * math.ceil((int(hi[1]) - y0) / POOL))
    x1 = x0 + POOL * ((x1 - x0) // POOL)
    y1 = y0 + POOL * ((y1 - y0) // POOL)
    return x0, y0, x1, y1


def _search_area(grid: GridMaps, poses: NDArray[np.float64], local: NDArray[np.float64], turn: float,
                 shift: float, window: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    """The part of window (x0, y0, x1, y1) the searches can read: the end points of every
    pose turned by up to +-turn, shifted by up to shift [m], with a margin. It keeps the
    window's alignment to POOL cells, so the pooled cells are the window's own.

    A 180-degree scan covers about half the disc around the robot: half the pooling.
    """
    x0, y0, x1, y1 = window
    cand = np.repeat(poses[:, None, :], 5, axis=1)
    cand[..., 2] += np.linspace(-turn, turn, 5)
    x, y = _world(cand, local)
    # between the sampled turns the end points bulge out by at most r (1 - cos(turn / 4))
    reach = float(np.hypot(local[:, 0], local[:, 1]).max())
    margin = shift + reach * (1.0 - math.cos(turn / 4)) + SEARCH_MARGIN
    lo = grid.world_to_cell(np.array([x.min(), y.min()]) - margin)
    hi = grid.world_to_cell(np.array([x.max(), y.max()]) + margin) + 1
    nx0 = x0 + POOL * max(0, (int(lo[0]) - x0) // POOL)
    ny0 = y0 + POOL * max(0, (int(lo[1]) - y0) // POOL)
    nx1 = min(x1, nx0 + POOL * math.ceil(max(int(hi[0]) - nx0, 0) / POOL))
    ny1 = min(y1, ny0 + POOL * math.ceil(max(int(hi[1]) - ny0, 0) / POOL))
    return nx0, ny0, nx1, ny1


def refine_poses(slam: FastSlam, beams: Beams,
                 prior: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None) -> NDArray[np.bool_]:
    """Moves each particle whose scan match is trusted to a sample around its matched
    pose, in place in slam.poses (N, 3); returns which particles (N,) bool.

    prior: (centre (N, 3), std-devs (3,) along, across, heading) of the odometry prior;
    None: centred on slam.poses with half the search window as std-devs.
    """
    cfg = slam.cfg
    grid = slam.grid
    n = len(slam.poses)
    trusted = np.zeros(n, dtype=bool)
    if np.count_nonzero(beams.hit) < MIN_BEAMS:
        return trusted
    sel = _spread_returns(beams, cfg.match_beams)
    local = _end_points(beams, sel)
    res = grid.resolution
    coarse = POOL * res
    k0 = max(1, math.ceil(cfg.match_xy_range / coarse))
    far = float(np.percentile(np.hypot(local[:, 0], local[:, 1]), 90))
    dth = min(coarse / max(far, coarse), 0.1)                      # turn moving far points one pooled cell
    ka = math.ceil(cfg.match_theta_range / dth)
    reach = float(np.hypot(local[:, 0], local[:, 1]).max()) + cfg.match_xy_range + 2 * coarse
    x0, y0, x1, y1 = _search_area(grid, slam.poses, local, ka * dth, k0 * coarse, _window(grid, slam.poses, reach))
    if x1 - x0 < 4 * POOL or y1 - y0 < 4 * POOL:
        return trusted
    raw = grid.logodds[:, y0:y1, x0:x1]                           # a view
    half, quarter = _pool_occupied(raw)                            # 2x2, 4x4 cells: occupied if any is
    known = np.count_nonzero(quarter > 0, axis=(1, 2))             # (N,) occupied 4x4 blocks in reach
    w_origin = grid.origin + np.array([x0, y0]) * res
    # 1. coarse: wide window on 4x4 cells
    turns = np.arange(-ka, ka + 1) * dth
    start = slam.poses
    if prior is None:
        centre = start
        spread = np.array([cfg.match_xy_range, cfg.match_xy_range, cfg.match_theta_range]) / 2
    else:
        centre, spread = prior[0], np.maximum(prior[1], PRIOR_FLOOR)
    m = len(local)
    pose = _pick(_grid_search(quarter, w_origin, coarse, start, turns, local, k0, flags=True),
                 start, turns, k0, coarse, centre, spread, m)
    # 2. the best coarse cell again on 2x2 cells, then on the map's own cells
    turns = np.array([-0.5, 0.0, 0.5]) * dth
    pose = _pick(_grid_search(half, w_origin, 2 * res, pose, turns, local, 2, flags=True),
                 pose, turns, 2, 2 * res, centre, spread, m)
    turns = np.array([-0.25, 0.0, 0.25]) * dth
    scores = _grid_search(grid.logodds, grid.origin, res, pose, turns, local, 1)
    pose = _pick(scores, pose, turns, 1, res, centre, spread, m)
    cov = None
    if cfg.match_refine == "icp":
        pose, info = _icp(grid, pose, local, _normals(beams, sel), centre, spread)
        if cfg.match_spread == "match":
            cov = inv3(info)
    else:
        pose = _hill_climb(grid, pose, local, dth)
    return _accept(slam, pose, local, half, w_origin, known, cov)


def _hill_climb(grid: GridMaps, pose: NDArray[np.float64], local: NDArray[np.float64],
                dth: float) -> NDArray[np.float64]:
    """3. hill climbing on the interpolated evidence, steps halving when stuck."""
    n = len(pose)
    res = grid.resolution
    best = _bilinear_scores(grid.logodds, grid.origin, res, pose[:, None, :], local)[:, 0]
    step = np.tile([res / 2, res / 2, dth / 8], (n, 1))
    moves = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    for _ in range(FINE_ITERATIONS):
        cand = pose[:, None, :] + moves[None] * step[:, None, :]
        sc = _bilinear_scores(grid.logodds, grid.origin, res, cand, local)
        j = sc.argmax(axis=1)
        top = sc[np.arange(n), j]
        up = top > best
        pose[up] = cand[up, j[up]]
        best = np.where(up, top, best)
        step[~up] *= 0.5
    return pose


def _accept(slam: FastSlam, pose: NDArray[np.float64], local: NDArray[np.float64], half: NDArray[np.int8],
            w_origin: NDArray[np.float64], known: NDArray[np.intp],
            cov: NDArray[np.float64] | None = None) -> NDArray[np.bool_]:
    """Moves the particles with a trusted match to a sample around it, with covariance
    cov (N, 3, 3) or the fixed match_sigma_*; returns which."""
    cfg = slam.cfg
    n = len(pose)
    res = slam.grid.resolution
    # trust: share of end points on an occupied 2x2 cell at the matched pose
    x, y = _world(pose, local)
    cx = np.clip(((x - w_origin[0]) / (2 * res)).astype(np.int64), 0, half.shape[2] - 1)
    cy = np.clip(((y - w_origin[1]) / (2 * res)).astype(np.int64), 0, half.shape[1] - 1)
    on_map = (half[np.arange(n)[:, None], cy, cx] > 0).mean(axis=1)
    trusted = (on_map >= cfg.match_min_score) & (known >= cfg.match_min_known)
    if not trusted.any():
        return trusted
    # The fixed spread is the default: one taken from the posterior of the cell-level
    # search (often a few cm) blurred the maps and doubled the Intel ATE. The ICP's
    # covariance is narrow across surfaces and wide only along them.
    z = slam.rng.normal(0.0, 1.0, (n, 3))
    if cov is None:
        sample = pose + z * np.array([cfg.match_sigma_xy, cfg.match_sigma_xy, cfg.match_sigma_theta])
    else:  # the match's own uncertainty: wide only along what the scan cannot tell
        low = cholesky3(cov)
        sample = pose + (low * z[:, None, :]).sum(axis=2)  # L z per particle
    sample[:, 2] = wrap_angle(sample[:, 2])
    slam.poses[trusted] = sample[trusted]
    return trusted


def _normals(beams: Beams, sel: NDArray[np.intp]) -> NDArray[np.float64]:
    """(M, 2) unit normals (robot frame) of the surface at the selected end points, from
    the returns on either side in the whole scan; zeros where those are missing or
    farther apart than NORMAL_GAP (a corner, an edge, a lone return)."""
    hit = beams.hit
    r = np.where(hit, beams.ranges, np.nan)
    pts = np.stack([beams.mount[0] + r * np.cos(beams.angles), beams.mount[1] + r * np.sin(beams.angles)], 1)
    prev = pts[np.maximum(sel - 1, 0)]
    nxt = pts[np.minimum(sel + 1, len(r) - 1)]
    tangent = nxt - prev
    length = np.hypot(tangent[:, 0], tangent[:, 1])
    ok = (sel > 0) & (sel < len(r) - 1) & (length > 0) & (length < NORMAL_GAP)
    ok &= np.isfinite(length)
    out = np.zeros((len(sel), 2))
    out[ok] = np.stack([-tangent[ok, 1], tangent[ok, 0]], 1) / length[ok, None]
    return out


def _icp(grid: GridMaps, pose: NDArray[np.float64], local: NDArray[np.float64], normals: NDArray[np.float64],
         centre: NDArray[np.float64], spread: NDArray[np.float64]
         ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """3. Gauss-Newton steps on the distances from the end points to the centres of their
    nearest occupied cells (a weighted mean of them), measured along the surface normal where the scan gives one
    (normals (M, 2), robot frame; zero: the whole distance), plus the Gaussian prior
    (centre (N, 3), spread (3,) along, across, heading).

    Unlike the evidence, a cell centre does not care how often the cell was hit, and
    the prior keeps directions the scan cannot tell where odometry put them: along a
    corridor the hill climb drifted backwards by ~1 % of the distance (the cells seen
    longest are behind the robot). Along the surface the distance is left out, or cell
    centres would pull the end points along walls.
    """
    n = len(pose)
    res = grid.resolution
    h, w = grid.shape
    d = np.arange(-ICP_RADIUS, ICP_RADIUS + 1)
    ox, oy = (v.reshape(-1) for v in np.meshgrid(d, d))
    shift = (oy * w + ox).tolist()                                     # flat offsets of the kernel
    lo = shift[0]
    kk = len(d)
    dk = d.astype(np.float32)[:, None, None]                           # (K, 1, 1) float32 arithmetic
    gain = np.float32(-0.5 / ICP_SPREAD ** 2)
    kernel = np.empty((len(shift), n, len(local)), dtype=grid.logodds.dtype)
    cells = grid.logodds.reshape(-1)
    # prior information in the map frame: R diag(1/sa^2, 1/sc^2) R^T, and 1/st^2
    c0, s0 = cos_sin(centre[:, 2])
    ia, ic = 1.0 / spread[0] ** 2, 1.0 / spread[1] ** 2
    p_xx, p_yy, p_xy = ia * c0 ** 2 + ic * s0 ** 2, ia * s0 ** 2 + ic * c0 ** 2, (ia - ic) * c0 * s0
    p_tt = 1.0 / spread[2] ** 2
    has_normal = np.any(normals != 0, axis=1)
    pose = pose.copy()
    for _ in range(ICP_ITERATIONS):
        c, s = cos_sin(pose[:, 2, None])
        rx = c * local[:, 0] - s * local[:, 1]                         # (N, M) end point - position
        ry = s * local[:, 0] + c * local[:, 1]
        u = (pose[:, 0, None] + rx - grid.origin[0]) / res
        v = (pose[:, 1, None] + ry - grid.origin[1]) / res
        # cells within the kernel; clamped so every kernel cell is inside (the edge
        # cells of the grid were never seen: nothing occupied to find there)
        iu = np.clip(np.floor(u).astype(np.intp), ICP_RADIUS, w - 1 - ICP_RADIUS)
        iv = np.clip(np.floor(v).astype(np.intp), ICP_RADIUS, h - 1 - ICP_RADIUS)
        base = (np.arange(n)[:, None] * h + iv) * w + iu + lo          # (N, M), >= 0 (lo < 0)
        for j, sh in enumerate(shift):                                 # kernel first: sums add whole slabs
            np.take(cells[sh - lo:], base, out=kernel[j], mode="clip")  # cells base + sh
        ex = (u - iu - 0.5).astype(np.float32) - dk                    # (K, N, M) end point - centre [cells]
        ey = (v - iv - 0.5).astype(np.float32) - dk
        # The target is the Gaussian-weighted mean of the occupied centres nearby, not
        # the nearest one: a wall two cells thick has its surface between its rows.
        # The weight exp(-(ex^2 + ey^2) / 2s^2) is one factor per axis.
        near = (kernel > 0).view(np.int8).reshape(kk, kk, n, -1) * np.exp(gain * ey * ey)[:, None]
        near *= np.exp(gain * ex * ex)                                  # (K rows, K columns, N, M)
        by_column, by_row = near.sum(axis=0), near.sum(axis=1)         # (K, N, M) each
        total = by_column.sum(axis=0)
        found = total > 1e-6                                           # (N, M)
        total = np.maximum(total, 1e-6) / res
        gx = (by_column * ex).sum(axis=0) / total                      # target offsets [m]
        gy = (by_row * ey).sum(axis=0) / total
        # weights W = n n^T / sigma^2 on a surface, I / sigma^2 without a normal
        nx = c * normals[:, 0] - s * normals[:, 1]                     # normals in the map frame
        ny = s * normals[:, 0] + c * normals[:, 1]
        k = found / ICP_SIGMA ** 2
        a = np.where(has_normal, nx * nx, 1.0) * k
        b = np.where(has_normal, nx * ny, 0.0) * k
        e = np.where(has_normal, ny * ny, 1.0) * k
        # normal equations with J = [[1, 0, -ry], [0, 1, rx]] per end point
        fx, fy = a * gx + b * gy, b * gx + e * gy                      # W err
        off = pose - centre
        off[:, 2] = wrap_angle(off[:, 2])
        hess = np.empty((n, 3, 3))
        hess[:, 0, 0] = a.sum(1) + p_xx
        hess[:, 1, 1] = e.sum(1) + p_yy
        hess[:, 0, 1] = hess[:, 1, 0] = b.sum(1) + p_xy
        hess[:, 0, 2] = hess[:, 2, 0] = (b * rx - a * ry).sum(1)
        hess[:, 1, 2] = hess[:, 2, 1] = (e * rx - b * ry).sum(1)
        hess[:, 2, 2] = (a * ry * ry - 2 * b * rx * ry + e * rx * rx).sum(1) + p_tt
        grad = np.stack([fx.sum(1) + p_xx * off[:, 0] + p_xy * off[:, 1],
                         fy.sum(1) + p_xy * off[:, 0] + p_yy * off[:, 1],
                         (rx * fy - ry * fx).sum(1) + p_tt * off[:, 2]], axis=1)
        pose -= solve3(hess, grad)
    pose[:, 2] = wrap_angle(pose[:, 2])
    return pose, hess


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
    x, y = _world(poses, _end_points(beams, sel))               # (N, S)
    u = (x - grid.origin[0]) / res
    v = (y - grid.origin[1]) / res
    ix = np.floor(u).astype(np.int64)
    iy = np.floor(v).astype(np.int64)
    fx = (u - ix - 0.5).astype(np.float32)
    fy = (v - iy - 0.5).astype(np.float32)
    if ix.min() - r >= 0 and iy.min() - r >= 0 and ix.max() + r < w and iy.max() + r < h:
        # Every searched cell is inside (the usual case): no bounds to check.
        base = (np.arange(n)[:, None] * h + iy) * w + ix        # (N, S)
        flat = base[..., None] + (oy * w + ox)                  # (N, S, O)
        occupied = grid.logodds.reshape(-1).take(flat) > 0
    else:
        cx = ix[..., None] + ox                                 # (N, S, O)
        cy = iy[..., None] + oy
        inside = (cx >= 0) & (cx < w) & (cy >= 0) & (cy < h)
        flat = (np.arange(n)[:, None, None] * h + np.clip(cy, 0, h - 1)) * w + np.clip(cx, 0, w - 1)
        occupied = (grid.logodds.reshape(-1).take(flat) > 0) & inside
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
