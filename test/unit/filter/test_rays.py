"""Digital lines through the grid: equal to Bresenham's on axis and diagonal beams,
8-connected from the start cell to the end cell on any."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.filter.grid import GridMaps
from fastslam.filter.rays import trace

RES = 0.1


def bresenham(x0, y0, x1, y1):
    """Textbook integer Bresenham, all octants."""
    cells = []
    dx, dy = abs(x1 - x0), -abs(y1 - y0)
    sx, sy = (1 if x0 < x1 else -1), (1 if y0 < y1 else -1)
    err = dx + dy
    while True:
        cells.append((x0, y0))
        if (x0, y0) == (x1, y1):
            return cells
        e2 = 2 * err
        if e2 >= dy:
            err += dy
            x0 += sx
        if e2 <= dx:
            err += dx
            y0 += sy



def grid_and_rays(angles, origin=(0.05, 0.05), max_range=1.0, n=1):
    grid = GridMaps(n, (60, 60), RES, (-3.0, -3.0))
    origins = np.tile(np.asarray(origin, float), (n, 1))
    rays = trace(grid, origins, np.tile(np.asarray(angles, float), (n, 1)), max_range)
    return grid, rays


def cells_of(grid, rays, beam, upto):
    flat = rays.flat[0, beam, : upto + 1]
    h, w = grid.shape
    return [(int(f % w), int(f // w % h)) for f in flat]


@pytest.mark.parametrize("angle", [0, 45, 90, 135, 180, 225, 270, 315])
def test_axis_and_diagonal_beams_equal_bresenham(angle):
    grid, rays = grid_and_rays([np.radians(angle)])
    n = int(rays.steps[0, 0])
    start = tuple(grid.world_to_cell(np.array([0.05, 0.05])))
    got = cells_of(grid, rays, 0, n)
    assert got == bresenham(*start, *got[-1])
    assert n == (10 if angle % 90 == 0 else 7)


def test_any_beam_is_8_connected_from_start_to_end():
    angles = np.radians(np.arange(0, 360, 7.3))
    grid, rays = grid_and_rays(angles, origin=(0.013, -0.037), max_range=2.3)
    for b in range(len(angles)):
        cells = np.array(cells_of(grid, rays, b, int(rays.steps[0, b])))
        step = np.abs(np.diff(cells, axis=0))
        assert step.max() == 1 and np.all(step.sum(axis=1) >= 1)  # no gap, no repeat
        end = grid.world_to_cell(np.array([0.013, -0.037]) + 2.3 * np.array([np.cos(angles[b]), np.sin(angles[b])]))
        assert tuple(cells[-1]) == tuple(end)
