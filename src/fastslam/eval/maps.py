"""Quality of a SLAM result against ground truth: trajectory error and map agreement."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fastslam.eval.trajectory import match_by_time
from fastslam.geometry import inverse, transform_points
from fastslam.io.map_files import OCCUPIED_MIN as OCCUPIED  # map_saver's occupied threshold [%]

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray

    from fastslam.sim.world import World


def trajectory_errors(estimate: NDArray[np.float64], truth: NDArray[np.float64]) -> NDArray[np.float64]:
    """(T,) position error of each estimated row (t, x, y, theta) against truth rows
    (t, x, y, theta, ascending t) interpolated at that time, both in the same frame (no
    alignment); estimated rows outside the truth's time span are left out."""
    _, ref, est = match_by_time(truth[:, 0], truth[:, 1:], estimate[:, 0], estimate[:, 1:], interpolate=True)
    return np.hypot(est[:, 0] - ref[:, 0], est[:, 1] - ref[:, 1])


def in_frame_of(pose: NDArray[np.float64], points: NDArray[np.float64]) -> NDArray[np.float64]:
    """(P, 2) world points seen from pose (3,): the map frame of a run that started there."""
    x, y = transform_points(inverse(pose), np.asarray(points, dtype=float).reshape(-1, 2))
    return np.stack([x, y], axis=1)


def nearest_distance(points: NDArray[np.float64], targets: NDArray[np.float64],
                      pairs: int = 1 << 21) -> NDArray[np.float64]:
    """(P,) distance from each point (P, 2) to the nearest target (Q, 2), about `pairs`
    point-target pairs at a time (a fixed chunk of points took 0.8 GB on the office)."""
    if len(targets) == 0:
        return np.full(len(points), np.inf)
    chunk = max(1, pairs // len(targets))
    out = np.empty(len(points))
    for a in range(0, len(points), chunk):
        d = points[a:a + chunk, None, :] - targets[None, :, :]
        out[a:a + chunk] = np.sqrt(np.min(np.einsum("pqk,pqk->pq", d, d), axis=1))
    return out


def map_quality(occupancy: NDArray[np.int8], resolution: float, origin: tuple[float, float],
                boundary: NDArray[np.float64]) -> dict[str, float]:
    """Agreement of an occupancy grid with the true obstacle boundary.

    Args:
        occupancy: (H, W) OccupancyGrid values (-1 unknown, 0..100).
        origin: (x, y) of the grid's cell (0, 0) corner, same frame as boundary [m].
        boundary: (P, 2) points densely sampled on the true obstacle boundaries [m].
    Returns:
        boundary_recall: of the true boundary cells the map observed (a known cell
            within one cell), the fraction within one cell of an occupied map cell;
        observed_fraction: the fraction of true boundary cells observed at all;
        spurious_fraction: the fraction of occupied map cells farther than two cells
            from any true boundary point;
        occupied_cells: how many cells the map calls occupied.
    """
    h, w = occupancy.shape
    cells = np.floor((boundary - np.asarray(origin)) / resolution).astype(np.int64)
    inside = (cells[:, 0] >= 0) & (cells[:, 0] < w) & (cells[:, 1] >= 0) & (cells[:, 1] < h)
    truth = np.unique(cells[inside], axis=0)                            # (B, 2) ix, iy
    occupied = occupancy >= OCCUPIED
    known = occupancy >= 0

    def near(mask: NDArray[np.bool_], radius: int) -> NDArray[np.bool_]:
        """mask dilated by a square of the given radius in cells."""
        padded = np.pad(mask, radius)
        out = np.zeros_like(mask)
        for dy in range(2 * radius + 1):
            for dx in range(2 * radius + 1):
                out |= padded[dy:dy + h, dx:dx + w]
        return out

    observed = near(known, 1)[truth[:, 1], truth[:, 0]]
    hit = near(occupied, 1)[truth[:, 1], truth[:, 0]]
    occ_cells = np.argwhere(occupied)[:, ::-1]                          # (O, 2) ix, iy
    centres = np.asarray(origin) + (occ_cells + 0.5) * resolution
    far = nearest_distance(centres, boundary) > 2 * resolution + resolution / 2
    return {
        "boundary_recall": float(hit[observed].mean()) if observed.any() else 0.0,
        "observed_fraction": float(observed.mean()) if len(truth) else 0.0,
        "spurious_fraction": float(far.mean()) if len(far) else 0.0,
        "occupied_cells": int(occupied.sum()),
    }


def run_quality(world: World, estimate: NDArray[np.float64], truth: NDArray[np.float64], occupancy: NDArray[np.int8],
                resolution: float, origin: tuple[float, float]) -> dict[str, float]:
    """Trajectory error and map agreement of a simulated run, all in the run's map frame.

    Args:
        world: the simulated World (its spawn is the map frame's origin).
        estimate, truth: (T, 4) rows t, x, y, theta in the map frame.
        occupancy, resolution, origin: the map as in map_quality.
    """
    err = trajectory_errors(estimate, truth)
    boundary = in_frame_of(world.spawn, world.sample_boundary(resolution / 4))
    return {"trajectory_rms_m": float(np.sqrt(np.mean(err ** 2))), "trajectory_max_m": float(err.max()),
            "final_error_m": float(err[-1]), **map_quality(occupancy, resolution, origin, boundary)}
