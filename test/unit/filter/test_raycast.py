"""The grid update along traced beams (free before the hit, the hit occupied, once per
scan, clamped) and expected ranges."""
from __future__ import annotations

import numpy as np

from fastslam.filter import raycast
from fastslam.filter.grid import GridMaps, LogOddsSteps
from fastslam.filter.rays import trace

RES = 0.1


def grid_and_rays(angles, origin=(0.05, 0.05), max_range=1.0, n=1):
    grid = GridMaps(n, (60, 60), RES, (-3.0, -3.0))
    origins = np.tile(np.asarray(origin, float), (n, 1))
    rays = trace(grid, origins, np.tile(np.asarray(angles, float), (n, 1)), max_range)
    return grid, rays


def test_update_marks_cells_before_the_hit_free_and_the_hit_occupied_only():
    grid, rays = grid_and_rays([0.0])  # beam along +x from cell (30, 30)
    hit_step = rays.step_of_range(np.array([0.5]))
    raycast.update_logodds(grid, rays, hit_step, hit_step, first_step=rays.first_step_at(0.12),
                           steps=LogOddsSteps(-4, 9, -100, 100))
    row = grid.logodds[0, 30]
    # range_min 0.12 m: steps 0 and 1 untouched, 2..4 free, step 5 (x = 0.5 m) hit
    assert list(row[30:37]) == [0, 0, -4, -4, -4, 9, 0]
    assert np.count_nonzero(grid.logodds) == 4


def test_a_cell_crossed_twice_in_one_scan_changes_once_and_hits_win():
    grid, rays = grid_and_rays([0.0, 0.0, 0.0])
    ends = rays.step_of_range(np.array([0.5, 0.3, 0.8]))
    raycast.update_logodds(grid, rays, ends, ends, first_step=np.zeros_like(ends),
                           steps=LogOddsSteps(-4, 9, -100, 100))
    assert list(grid.logodds[0, 30, 30:40]) == [-4, -4, -4, 9, -4, 9, -4, -4, 9, 0]


def test_clamps_hold():
    grid, rays = grid_and_rays([0.0])
    ends = rays.step_of_range(np.array([0.5]))
    for _ in range(30):
        raycast.update_logodds(grid, rays, ends, ends, first_step=np.zeros_like(ends),
                               steps=LogOddsSteps(-4, 9, -20, 50))
    assert list(grid.logodds[0, 30, 30:36]) == [-20] * 5 + [50]


def test_expected_ranges_in_a_square_room_match_geometry_within_one_cell():
    half = 1.5
    grid = GridMaps(2, (60, 60), RES, (-3.0, -3.0))
    centres = grid.cell_to_world(np.stack(np.meshgrid(np.arange(60), np.arange(60)), -1))
    wall = (np.abs(centres[..., 0]) > half) | (np.abs(centres[..., 1]) > half)
    near = np.maximum(np.abs(centres[..., 0]), np.abs(centres[..., 1])) < half + RES
    grid.logodds[:] = np.where(wall & near, 50, -10)
    angles = np.radians(np.arange(0, 360, 3.0))
    origins = np.array([[0.02, 0.03], [0.4, -0.3]])
    rays = trace(grid, origins, np.tile(angles, (2, 1)), 3.0)
    d = raycast.expected_ranges(grid, rays, 0.12)
    for p, (ox, oy) in enumerate(origins):
        c, s = np.cos(angles), np.sin(angles)
        with np.errstate(divide="ignore"):
            tx = np.where(c > 0, (half - ox) / c, (-half - ox) / c)
            ty = np.where(s > 0, (half - oy) / s, (-half - oy) / s)
        truth = np.minimum(np.abs(tx), np.abs(ty))
        assert np.max(np.abs(d[p] - truth)) <= RES * np.sqrt(2) + 1e-9


def test_nothing_occupied_gives_max_range_and_outside_cells_are_ignored():
    grid = GridMaps(1, (20, 20), RES, (-1.0, -1.0))
    rays = trace(grid, np.array([[0.9, 0.0]]), np.array([[0.0, np.pi]]), 1.5)
    assert not rays.inside
    np.testing.assert_allclose(raycast.expected_ranges(grid, rays), [[1.5, 1.5]])
    ends = rays.step_of_range(np.array([1.5, 1.5]))
    raycast.update_logodds(grid, rays, ends + 1, np.array([[-1, -1]]), first_step=np.zeros_like(ends),
                           steps=LogOddsSteps(-1, 1, -5, 5))
    # cells 19 down to 4 of row 10 (16 cells); the +x beam leaves the grid after cell 19
    assert list(np.flatnonzero(grid.logodds[0].reshape(-1))) == [10 * 20 + i for i in range(4, 20)]
