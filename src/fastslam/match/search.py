"""The matcher's correlative search: candidate poses on a grid of shifts and turns,
scored by the occupied cells their end points fall in, coarse to fine.

A candidate's score is the number of end points on occupied cells (grid units:
occupied or not). Translations of a level are whole cells of that level, so a
candidate's cells are the cells of its heading plus a constant flat offset: one gather
per end point and candidate, no trigonometry per candidate. The pooled maps are built
once per update, only in the window the scans of all particles can reach.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Tuple

import numpy as np

from fastslam.filter.grid import GridMaps
from fastslam.filter.scratch import scratch
from fastslam.geometry import cos_sin, transform_points, wrap_angle

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray

    from fastslam.filter.motion import OdometryArc

    Pooled = Tuple[NDArray[np.int8], NDArray[np.int8]]   # (2x2, 4x4 cells)


POOL = 4               # coarse level: cells per side of a pooled cell
SEARCH_MARGIN = 0.5    # [m] beyond the coarse search: the finer stages and ICP move a little further
POOL_CELLS = 1 << 20   # cells pooled at a time (maps x window): the work arrays stay small
SEARCH_CELLS = 1 << 16  # candidate end points (particles x turns x end points) searched at a time


def _cell_score(logodds: NDArray[np.int8]) -> NDArray[np.int8]:
    """1 for an occupied cell, else 0.

    Occupied or not, never how strongly: cells the robot saw many times (behind it)
    would otherwise pull the match backwards along a corridor.
    """
    return (logodds > 0).view(np.int8)


def grid_search(level: NDArray[np.int8] | GridMaps, origin: NDArray[np.float64], cell: float,
                 poses: NDArray[np.float64], turns: NDArray[np.float64], local: NDArray[np.float64],
                 k: int, flags: bool = False) -> NDArray[np.int64]:
    """Scores (N, A, (2k+1)^2) of poses turned by turns (A,) and shifted by -k..k cells.

    level: (N, Hv, Wv) log-odds (only max(l, 0) counts) with cells of size `cell` and
    lower-left corner `origin`, or (flags) already the 0/1 cell scores; or the maps
    themselves (a GridMaps: its log-odds). Candidate t = (dy + k) * (2k + 1) + (dx + k).
    """
    n = len(poses)
    per = max(1, SEARCH_CELLS // max(n * len(local), 1))
    if len(turns) > per:   # a few turns at a time: the (N, A, M) work arrays stay small
        return np.concatenate([grid_search(level, origin, cell, poses, turns[a:a + per], local, k, flags)
                               for a in range(0, len(turns), per)], axis=1)
    hv, wv = level.shape if isinstance(level, GridMaps) else level.shape[1:]
    cand = np.repeat(poses[:, None, :], len(turns), axis=1)
    cand[..., 2] += turns
    x, y = transform_points(cand, local)                                            # (N, A, M)
    # Cells near the edge are clamped so every shifted cell stays inside: end points
    # there are at most k cells off, in a part of the window nothing was seen in.
    # (a cast truncates towards zero: floor's cell wherever the clamp at k >= 0 lets it through)
    cx = np.minimum(np.maximum(((x - origin[0]) / cell).astype(np.int64), k), wv - 1 - k)
    cy = np.minimum(np.maximum(((y - origin[1]) / cell).astype(np.int64), k), hv - 1 - k)
    d = np.arange(-k, k + 1)
    # Scores of 0/1 cells over M end points: M < 2**7 fits int8, M < 2**15 int16.
    acc = np.int8 if len(local) < 128 else np.int16
    # End points first: one gather per shift (no (N, A, T, M) index array), and the sum
    # over end points adds whole (N, A) slabs. Every shifted cell is inside (clamped above).
    if isinstance(level, GridMaps):
        vals = level.values_around(np.arange(n)[None, :, None], cy.transpose(2, 0, 1), cx.transpose(2, 0, 1),
                                   np.repeat(d, len(d)), np.tile(d, len(d)))       # (T, M, N, A)
        sums = (vals if flags else _cell_score(vals)).sum(axis=1, dtype=acc)      # (T, N, A)
        return sums.transpose(1, 2, 0).astype(np.int64, order="C")
    flat = (np.arange(n)[:, None, None] * hv + cy) * wv + cx                # (N, A, M)
    shifts = (d[:, None] * wv + d[None, :]).reshape(-1).tolist()            # (T,), ascending
    lo = shifts[0]
    at = np.ascontiguousarray(flat.transpose(2, 0, 1), dtype=np.intp)       # (M, N, A)
    at += lo                                                                # >= 0: cells are clamped k from the edge
    f = level.reshape(-1)
    # all shifts' cells at once and one sum, or (a wide search) each shift's cells summed in turn
    together = len(shifts) * at.size <= SEARCH_CELLS * 16
    vals = scratch("grid_search", ((len(shifts),) if together else ()) + at.shape, np.int8)
    sums = np.empty((len(shifts), n, len(turns)), dtype=acc)                 # (T, N, A)
    for i, s in enumerate(shifts):
        np.take(f[s - lo:], at, out=vals[i] if together else vals, mode="clip")   # cells flat + s (s - lo >= 0)
        if not together:
            np.sum(vals if flags else _cell_score(vals), axis=0, dtype=acc, out=sums[i])
    if together:
        np.sum(vals if flags else _cell_score(vals), axis=1, dtype=acc, out=sums)
    return sums.transpose(1, 2, 0).astype(np.int64, order="C")


def pick(scores: NDArray[np.int64], poses: NDArray[np.float64], turns: NDArray[np.float64],
          k: int, cell: float, start: NDArray[np.float64], prior: NDArray[np.float64], beams: int,
          gain: float = 1.0, arc: OdometryArc | None = None) -> NDArray[np.float64]:
    """Best candidate of each particle as a pose (N, 3).

    Scores become log-likelihoods as in _nats; the odometry prediction `start` (N, 3)
    adds a Gaussian prior with std-devs prior (3,) along and across its heading and of
    the heading, so that along a corridor, where the scan cannot tell, the particle
    stays where odometry put it. gain scales the scores' nats: neighbouring returns on
    one wall are not independent, and counting each as a whole nat lets two more end
    points on a half-mapped wall outweigh a shift of two std-devs of the prior. arc: the
    step's odometry model in its own terms instead of that Gaussian (match_prior_arc).
    """
    n, a, t = scores.shape
    d = np.arange(-k, k + 1)
    ox = (poses[:, 0] - start[:, 0])[:, None] + np.tile(d, 2 * k + 1)[None, :] * cell   # (N, T)
    oy = (poses[:, 1] - start[:, 1])[:, None] + np.repeat(d, 2 * k + 1)[None, :] * cell
    oa = wrap_angle(poses[:, 2] - start[:, 2])[:, None] + turns[None, :]                # (N, A)
    if arc is not None:
        px, py, ph = (start[:, i, None, None] for i in range(3))                         # (N, 1, 1)
        log_prior = -0.5 * arc.cost(px + ox[:, None, :], py + oy[:, None, :], ph + oa[:, :, None], px, py, ph)
    else:
        along, across = ox, oy  # an isotropic prior needs no turning
        if prior[0] != prior[1]:
            c, s_ = cos_sin(start[:, 2, None])
            along, across = c * ox + s_ * oy, c * oy - s_ * ox                           # start's frame
        log_prior = -0.5 * (((along / prior[0]) ** 2 + (across / prior[1]) ** 2)[:, None, :]
                            + ((oa / prior[2]) ** 2)[:, :, None])
    s = gain * _nats(scores, beams) + log_prior
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


def pool_occupied(level: NDArray[np.int8], above: int = 0, out: Pooled | None = None) -> Pooled:
    """(N, H, W) -> 0/1 flags (N, H/2, W/2) and (N, H/4, W/4): whether any cell of each
    2x2 and 4x4 block is occupied (log-odds above `above`; H, W multiples of 4); out:
    the arrays to write them to.

    Any cell above `above` is the block's maximum above it (see _block_max).
    """
    m2 = _block_max(level, "pool2")
    half, quarter = (None, None) if out is None else (out[0].view(np.bool_), out[1].view(np.bool_))
    return (np.greater(m2, above, out=half).view(np.int8),
            np.greater(_block_max(m2, "pool4"), above, out=quarter).view(np.int8))


def pool_signed(level: NDArray[np.int8], out: Pooled | None = None) -> Pooled:
    """(N, H, W) -> (N, H/2, W/2) and (N, H/4, W/4): +1 where any cell of the 2x2 or 4x4
    block is occupied, -1 where every cell is known free, 0 otherwise (H, W multiples of 4);
    out: the arrays to write them to.

    An end point on a free block contradicts the map (the beam would have ended
    there before): summed, these flags score a candidate by the end points it puts on
    walls less those it puts in free space, which a wrong alignment (a turned copy of
    a room, the wrong side of a wall) cannot hide. They are the sign of the block's
    maximum: above 0 if any cell is occupied, below 0 if every cell is free.
    """
    m2 = _block_max(level, "pool2")
    half, quarter = (None, None) if out is None else out
    return np.sign(m2, out=half), np.sign(_block_max(m2, "pool4"), out=quarter)


def _block_max(level: NDArray[np.int8], key: str) -> NDArray[np.int8]:
    """(k, H, W) -> (k, H/2, W/2) maxima of 2x2 blocks, in a reused work array: row pairs
    first (whole rows), then the two bytes of each column pair."""
    k, h, w = level.shape
    rows = np.maximum(level[:, 0::2, :], level[:, 1::2, :], out=scratch(key + "_rows", (k, h // 2, w), np.int8))
    pairs = rows.reshape(k, h // 2, w // 2, 2)
    return np.maximum(pairs[..., 0], pairs[..., 1], out=scratch(key, (k, h // 2, w // 2), np.int8))


def window(grid: GridMaps, poses: NDArray[np.float64], reach: float, shift: int = 0) -> tuple[int, int, int, int]:
    """Cell bounds (x0, y0, x1, y1) of the part of the grid within reach of any pose,
    with sides a multiple of POOL cells; shift: its corner that many cells further down
    and left (where the pooled blocks fall: bench.phase)."""
    h, w = grid.shape
    lo = grid.world_to_cell(poses[:, :2].min(axis=0) - reach) - shift
    hi = grid.world_to_cell(poses[:, :2].max(axis=0) + reach) + 1
    x0, y0 = (int(v) for v in np.maximum(lo, 0))
    x1 = min(w, x0 + POOL * math.ceil((int(hi[0]) - x0) / POOL))
    y1 = min(h, y0 + POOL * math.ceil((int(hi[1]) - y0) / POOL))
    x1 = x0 + POOL * ((x1 - x0) // POOL)
    y1 = y0 + POOL * ((y1 - y0) // POOL)
    return x0, y0, x1, y1


def search_area(grid: GridMaps, poses: NDArray[np.float64], local: NDArray[np.float64], turn: float,
                 shift: float, window: tuple[int, int, int, int]) -> tuple[int, int, int, int]:
    """The part of window (x0, y0, x1, y1) the searches can read: the end points of every
    pose turned by up to +-turn, shifted by up to shift [m], with a margin. It keeps the
    window's alignment to POOL cells, so the pooled cells are the window's own.

    A 180-degree scan covers about half the disc around the robot: half the pooling.
    """
    x0, y0, x1, y1 = window
    cand = np.repeat(poses[:, None, :], 5, axis=1)
    cand[..., 2] += np.linspace(-turn, turn, 5)
    x, y = transform_points(cand, local)
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
