"""The matcher's last stage, finer than a cell: hill climbing on the interpolated
evidence (gmapping's optimiser), or Gauss-Newton steps pulling each end point onto the
occupied cells along the scan's surface normals (ICP), with the odometry prior."""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from fastslam.filter.grid import GridMaps
from fastslam.filter.scan import Beams
from fastslam.geometry import cos_sin, solve3, transform_points, wrap_angle

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


FINE_ITERATIONS = 6    # hill-climbing steps (a step halves when no neighbour improves)
ICP_ITERATIONS = 3     # Gauss-Newton steps by default (match_icp_iterations)
ICP_RADIUS = 2         # cells searched around each end point for occupied ones
ICP_SIGMA = 0.05       # [m] std-dev of an end point about its cell centre
ICP_SPREAD = 1.0       # [cells] std-dev of the weights of occupied centres around an end point
BEARING_MIN_TRAVEL = 0.05   # [m] prior_on_bearing: shorter steps (turns on the spot) have no bearing
NORMAL_GAP = 0.3       # [m] neighbouring returns farther apart give no surface normal
_OFFSETS = np.arange(-ICP_RADIUS, ICP_RADIUS + 1)
_KERNEL_X, _KERNEL_Y = (v.reshape(-1) for v in np.meshgrid(_OFFSETS, _OFFSETS))   # the kernel's cells, rows first
_OFFSETS_32 = _OFFSETS.astype(np.float32)[:, None, None]                           # (K, 1, 1) float32 arithmetic


def _bilinear_scores(grid: GridMaps, cand: NDArray[np.float64], local: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N, C) sum over end points of the bilinearly interpolated evidence max(l, 0)
    of the maps, in grid units.

    Unlike the searches on whole cells (occupied or not), the log-odds magnitude
    counts here: within a wall a few cells thick its most often hit cells, the
    surface, pull the end points (median Intel ATE 0.21 -> 0.18 m).
    """
    n = len(cand)
    h, w = grid.shape
    origin, cell = grid.origin, grid.resolution
    x, y = transform_points(cand, local)                                            # (N, C, M)
    u = (x - origin[0]) / cell - 0.5
    v = (y - origin[1]) / cell - 0.5
    i0 = np.minimum(np.maximum(np.floor(u), 0), w - 2)
    j0 = np.minimum(np.maximum(np.floor(v), 0), h - 2)
    fu = np.minimum(np.maximum(u - i0, 0.0), 1.0)
    fv = np.minimum(np.maximum(v - j0, 0.0), 1.0)
    corners = grid.values_around(np.arange(n)[:, None, None], j0.astype(np.intp), i0.astype(np.intp),
                                 [0, 0, 1, 1], [0, 1, 0, 1])                      # (4, N, C, M)
    a, b, c, d = np.maximum(corners, 0).astype(np.float32)
    val = (a * (1 - fu) + b * fu) * (1 - fv) + (c * (1 - fu) + d * fu) * fv
    return val.sum(axis=2)


def hill_climb(grid: GridMaps, pose: NDArray[np.float64], local: NDArray[np.float64],
                dth: float) -> NDArray[np.float64]:
    """3. hill climbing on the interpolated evidence, steps halving when stuck."""
    n = len(pose)
    res = grid.resolution
    best = _bilinear_scores(grid, pose[:, None, :], local)[:, 0]
    step = np.tile([res / 2, res / 2, dth / 8], (n, 1))
    moves = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], dtype=float)
    for _ in range(FINE_ITERATIONS):
        cand = pose[:, None, :] + moves[None] * step[:, None, :]
        sc = _bilinear_scores(grid, cand, local)
        j = sc.argmax(axis=1)
        top = sc[np.arange(n), j]
        up = top > best
        pose[up] = cand[up, j[up]]
        best = np.where(up, top, best)
        step[~up] *= 0.5
    return pose


def surface_normals(beams: Beams, sel: NDArray[np.intp]) -> NDArray[np.float64]:
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


def prior_information(centre: NDArray[np.float64], spread: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N, 3, 3) information of the Gaussian prior with std-devs spread (3,) along and
    across the heading of centre (N, 3) and of the heading, in the map frame: the
    prior part of the Hessian icp_fit returns."""
    c, s = cos_sin(centre[:, 2])
    ia, ic = 1.0 / spread[0] ** 2, 1.0 / spread[1] ** 2
    out = np.zeros((len(centre), 3, 3))
    out[:, 0, 0] = ia * c ** 2 + ic * s ** 2
    out[:, 1, 1] = ia * s ** 2 + ic * c ** 2
    out[:, 0, 1] = out[:, 1, 0] = (ia - ic) * c * s
    out[:, 2, 2] = 1.0 / spread[2] ** 2
    return out


def prior_on_bearing(centre: NDArray[np.float64], origin: NDArray[np.float64], pick: NDArray[np.float64],
                     max_turn: float) -> NDArray[np.float64]:
    """(N, 3) the prior's centres (N, 3) moved along their steps from origin (N, 2), so that
    the point of the pick's bearing from origin nearest the centre lies the step's travel out:
    centre - origin scaled by 1 / cos(turn), the turn between the two bearings, at most max_turn.

    A step whose first turn erred ends on an arc round its start. Where the scan fixes
    the bearing but not the travel (a corridor), the Gaussian about the prediction puts
    the match at the foot of the perpendicular, travel * cos(turn) out: with simulated
    odometry noise our maps came out 0.2-0.5 % small. Steps or picks under BEARING_MIN_TRAVEL
    keep their centre; the heading stays.
    """
    step = centre[:, :2] - origin
    found = pick[:, :2] - origin
    travel = np.hypot(step[:, 0], step[:, 1])
    reach = np.hypot(found[:, 0], found[:, 1])
    moved = (travel >= BEARING_MIN_TRAVEL) & (reach >= BEARING_MIN_TRAVEL)
    cos_turn = np.ones(len(centre))
    cos_turn[moved] = (step[moved] * found[moved]).sum(axis=1) / (travel[moved] * reach[moved])
    out = centre.copy()
    out[:, :2] = origin + step / np.maximum(cos_turn, math.cos(max_turn))[:, None]
    return out


def icp_fit(grid: GridMaps, pose: NDArray[np.float64], local: NDArray[np.float64], normals: NDArray[np.float64],
            centre: NDArray[np.float64], spread: NDArray[np.float64], maps: NDArray[np.intp] | None = None,
            iterations: int = ICP_ITERATIONS) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """3. Gauss-Newton steps on the distances from the end points to the centres of their
    nearest occupied cells (a weighted mean of them), measured along the surface normal where the scan gives one
    (normals (M, 2), robot frame; zero: the whole distance), plus the Gaussian prior
    (centre (N, 3), spread (3,) along, across, heading).

    Unlike the evidence, a cell centre does not care how often the cell was hit, and
    the prior keeps directions the scan cannot tell where odometry put them: along a
    corridor the hill climb drifted backwards by ~1 % of the distance (the cells seen
    longest are behind the robot). Along the surface the distance is left out, or cell
    centres would pull the end points along walls.

    maps: (N,) the map of each pose (default pose n on map n), so that one call refines
    several starts per particle. iterations: Gauss-Newton steps, at least 1 (the target,
    a weighted mean of cells round the end point, moves with it: each step goes only part
    of the rest of the way). Returns the poses, their information matrices (the
    Hessian with the prior) and their fit: the objective, in squared std-devs, at the
    pose before the last step (an end point with no occupied cell in reach costs as
    much as one at the kernel's edge), for choosing among starts.
    """
    if iterations < 1:
        raise ValueError(f"icp_fit needs at least one step, got iterations={iterations}")
    n, m = len(pose), len(local)
    res = grid.resolution
    h, w = grid.shape
    ox, oy, dk = _KERNEL_X, _KERNEL_Y, _OFFSETS_32
    kk = len(dk)
    gain = np.float32(-0.5 / ICP_SPREAD ** 2)
    kernel = np.empty((len(ox), n, m), dtype=np.int8)
    # prior information in the map frame: R diag(1/sa^2, 1/sc^2) R^T, and 1/st^2
    prior = prior_information(centre, spread)
    p_xx, p_yy, p_xy, p_tt = prior[:, 0, 0], prior[:, 1, 1], prior[:, 0, 1], prior[:, 2, 2]
    has_normal = np.any(normals != 0, axis=1)
    pose = pose.copy()
    map_of = np.arange(n) if maps is None else np.asarray(maps, dtype=np.intp)
    particle = np.broadcast_to(map_of[:, None], (n, m))
    cap = (ICP_RADIUS * grid.resolution / ICP_SIGMA) ** 2                 # cost of an end point not found
    cell: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None     # the kernel's centre cells so far
    # The loop is numpy calls on small arrays (one particle's 180 end points between
    # updates): the same arithmetic as one expression per term, in fewer calls.
    lx, ly, n0, n1 = (np.ascontiguousarray(v) for v in (local[:, 0], local[:, 1], normals[:, 0], normals[:, 1]))
    sums = np.empty((9, n, m))     # the end points' terms of the Hessian and gradient, summed in one call
    a, e, b, h02, h12, h22, fx, fy, g2 = sums
    tmp = np.empty((n, m))
    with_prior = np.zeros((3, 3), dtype=bool)
    with_prior[[0, 1, 0, 1, 2], [0, 1, 1, 0, 2]] = True
    for _ in range(iterations):
        c, s = cos_sin(pose[:, 2, None])
        rx = c * lx - s * ly                                           # (N, M) end point - position
        ry = s * lx + c * ly
        u = (pose[:, 0, None] + rx - grid.origin[0]) / res
        v = (pose[:, 1, None] + ry - grid.origin[1]) / res
        # cells within the kernel; clamped so every kernel cell is inside (the edge
        # cells of the grid were never seen: nothing occupied to find there); a cast
        # truncates towards zero, floor's value wherever the clamp lets it through
        iu = u.astype(np.intp)
        np.minimum(np.maximum(iu, ICP_RADIUS, out=iu), w - 1 - ICP_RADIUS, out=iu)
        iv = v.astype(np.intp)
        np.minimum(np.maximum(iv, ICP_RADIUS, out=iv), h - 1 - ICP_RADIUS, out=iv)
        if cell is None:
            grid.values_around(particle, iv, iu, oy, ox, out=kernel)   # kernel first: sums add whole slabs
        else:   # a later step moves few end points to another cell: only theirs are read again
            moved = iu != cell[1]
            moved |= iv != cell[0]
            at = np.flatnonzero(moved)
            if len(at):
                kernel.reshape(len(ox), -1)[:, at] = grid.values_around(
                    map_of[at // m], iv.reshape(-1)[at], iu.reshape(-1)[at], oy, ox)
        cell = (iv, iu)
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
        nx = c * n0 - s * n1                                           # normals in the map frame
        ny = s * n0 + c * n1
        k = found / ICP_SIGMA ** 2
        np.multiply(np.where(has_normal, nx * nx, 1.0), k, out=a)
        np.multiply(np.where(has_normal, nx * ny, 0.0), k, out=b)
        np.multiply(np.where(has_normal, ny * ny, 1.0), k, out=e)
        # normal equations with J = [[1, 0, -ry], [0, 1, rx]] per end point
        np.multiply(a, gx, out=fx)                                     # W err
        fx += np.multiply(b, gy, out=tmp)
        np.multiply(b, gx, out=fy)
        fy += np.multiply(e, gy, out=tmp)
        a_ry, e_rx = a * ry, e * rx
        np.subtract(np.multiply(b, rx, out=h02), a_ry, out=h02)
        np.subtract(e_rx, np.multiply(b, ry, out=h12), out=h12)
        np.multiply(a_ry, ry, out=h22)
        h22 -= 2 * b * rx * ry
        h22 += np.multiply(e_rx, rx, out=tmp)
        np.subtract(np.multiply(rx, fy, out=g2), np.multiply(ry, fx, out=tmp), out=g2)
        total_terms = sums.sum(axis=2)                                 # (9, N), each as its row's own sum
        off = pose - centre
        off[:, 2] = wrap_angle(off[:, 2])
        hess = total_terms[[0, 2, 3, 2, 1, 4, 3, 4, 5]].T.reshape(n, 3, 3)
        np.add(hess, prior, out=hess, where=with_prior)
        grad = total_terms[6:].T.copy()
        grad[:, :2] += prior[:, :2, 0] * off[:, :1]
        grad[:, :2] += prior[:, :2, 1] * off[:, 1:2]
        grad[:, 2] += p_tt * off[:, 2]
        pose -= solve3(hess, grad)
    cost = ((gx * fx + gy * fy).sum(1) + cap * np.count_nonzero(~found, axis=1)
            + p_xx * off[:, 0] ** 2 + 2 * p_xy * off[:, 0] * off[:, 1] + p_yy * off[:, 1] ** 2
            + p_tt * off[:, 2] ** 2)
    pose[:, 2] = wrap_angle(pose[:, 2])
    return pose, hess, cost
