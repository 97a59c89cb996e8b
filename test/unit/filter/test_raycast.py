"""Batched ray tracing: Bresenham-equal lines, the grid update, expected ranges, and the
trimmed update of the likelihood mode."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.config import SlamConfig
from fastslam.filter import raycast
from fastslam.filter.grid import GridMaps, LogOddsSteps
from fastslam.filter.slam import FastSlam

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
    rays = raycast.trace(grid, origins, np.tile(np.asarray(angles, float), (n, 1)), max_range)
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
    rays = raycast.trace(grid, origins, np.tile(angles, (2, 1)), 3.0)
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
    rays = raycast.trace(grid, np.array([[0.9, 0.0]]), np.array([[0.0, np.pi]]), 1.5)
    assert not rays.inside
    np.testing.assert_allclose(raycast.expected_ranges(grid, rays), [[1.5, 1.5]])
    ends = rays.step_of_range(np.array([1.5, 1.5]))
    raycast.update_logodds(grid, rays, ends + 1, np.array([[-1, -1]]), first_step=np.zeros_like(ends),
                           steps=LogOddsSteps(-1, 1, -5, 5))
    # cells 19 down to 4 of row 10 (16 cells); the +x beam leaves the grid after cell 19
    assert list(np.flatnonzero(grid.logodds[0].reshape(-1))) == [10 * 20 + i for i in range(4, 20)]


# -- the trimmed update (likelihood mode): no expected ranges, beams traced about as far as they reach

ANGLES_4 = np.radians(np.arange(0.0, 360.0, 4.0))


@pytest.fixture
def likelihood_map(room_scan, room_ranges):
    """likelihood_map(free_beam_step) -> (filter, end points, mid points): one scan of the
    pillar room written by the likelihood mode (trimmed trace) into 2 maps."""
    def build(free_beam_step: int = 1) -> tuple[FastSlam, np.ndarray, np.ndarray]:
        slam = FastSlam(SlamConfig(particles=2, seed=0, toggle_noise=0, weight_model="likelihood",
                                   free_beam_step=free_beam_step))
        pose = np.array([0.3, -0.2, 0.4])
        slam.step(pose, room_scan(pose, ANGLES_4))
        z = room_ranges(pose, ANGLES_4)
        a = pose[2] + ANGLES_4
        ends = pose[:2] + z[:, None] * np.stack([np.cos(a), np.sin(a)], 1)
        mids = pose[:2] + 0.5 * z[:, None] * np.stack([np.cos(a), np.sin(a)], 1)
        ends[z >= 3.4] = np.nan                                  # no return (max_range 3.5): no wall
        return slam, ends, mids

    return build


def _values(slam: FastSlam, points: np.ndarray) -> np.ndarray:
    c = slam.grid.world_to_cell(points)
    return slam.grid.values(np.arange(slam.grid.particles)[:, None], c[:, 1], c[:, 0])   # (N, P)


def _near(slam: FastSlam, points: np.ndarray, reduce=np.min) -> np.ndarray:
    """(N, P) least (or most) log-odds among each point's cell and its 8 neighbours: a
    digital beam line runs from the cell of the origin, so it may pass beside a point."""
    c = slam.grid.world_to_cell(points[np.isfinite(points).all(axis=1)])
    d = np.arange(-1, 2)
    n = np.arange(slam.grid.particles)[:, None]
    return reduce([slam.grid.values(n, c[:, 1] + dy, c[:, 0] + dx) for dy in d for dx in d], axis=0)


def test_trimmed_map_update_marks_end_cells_and_clears_the_beams(likelihood_map):
    slam, ends, mids = likelihood_map()
    assert np.all(_near(slam, ends, np.max) > 0)               # walls at the end cells
    assert np.all(_near(slam, mids) < 0)                 # the middle of every beam is free
    far = np.array([[4.0, 4.0], [-4.0, 3.0]])                # outside the room: never touched
    assert np.all(_values(slam, far) == 0)


def test_free_beam_step_clears_along_every_kth_beam_but_marks_all_end_cells(likelihood_map):
    slam, ends, mids = likelihood_map(free_beam_step=2)
    full, _, _ = likelihood_map()
    traced = np.arange(len(ANGLES_4)) % 2 == 0
    assert np.all(_near(slam, mids[traced]) < 0)
    assert np.any(_values(slam, mids[~traced]) == 0)         # untraced beams leave some unknown
    assert np.all(_near(slam, ends[~traced], np.max) > 0)    # ...but their end cells are walls
    def free_cells(s: FastSlam) -> int:
        return sum(int(np.count_nonzero(s.grid.particle_map(i) < 0)) for i in range(s.grid.particles))

    assert free_cells(slam) < free_cells(full)
