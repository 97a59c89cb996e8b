"""The trimmed update of the likelihood mode: no expected ranges, beams traced about as
far as they reach, every free_beam_step-th beam clearing."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.config import SlamConfig
from fastslam.filter.scan import Scan
from fastslam.filter.slam import FastSlam
from fastslam.filter.trimmed import clearing_step

ANGLES_4 = np.radians(np.arange(0.0, 360.0, 4.0))


@pytest.fixture
def likelihood_map(room_scan, room_ranges):
    """likelihood_map(free_beam_step, free_beam_spacing) -> (filter, end points, mid points): one scan of the
    pillar room written by the likelihood mode (trimmed trace) into 2 maps."""
    def build(free_beam_step: int = 1, free_beam_spacing: float = 0.0) -> tuple[FastSlam, np.ndarray, np.ndarray]:
        slam = FastSlam(SlamConfig(particles=2, seed=0, toggle_noise=0, weight_model="likelihood",
                                   free_beam_step=free_beam_step, free_beam_spacing=free_beam_spacing))
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


def _maps(slam: FastSlam) -> np.ndarray:
    return np.stack([slam.grid.particle_map(i) for i in range(slam.grid.particles)])


def test_free_beam_spacing_clears_along_beams_that_far_apart(likelihood_map):
    # beams 4 degrees apart: 12 degrees apart is every 3rd, 10 also (3 steps are the least
    # reaching it), 8 every 2nd; a free_beam_step larger than the spacing asks for wins
    third, _, _ = likelihood_map(free_beam_step=3)
    second, _, _ = likelihood_map(free_beam_step=2)
    assert not np.array_equal(_maps(third), _maps(second))
    for step, spacing, same in ((1, 12.0, third), (1, 10.0, third), (1, 8.0, second), (3, 8.0, third),
                                (2, 0.0, second)):
        slam, _, _ = likelihood_map(free_beam_step=step, free_beam_spacing=spacing)
        np.testing.assert_array_equal(_maps(slam), _maps(same), err_msg=f"step {step}, spacing {spacing}")


@pytest.mark.parametrize("between_deg, step, spacing, k", [
    (0.5, 2, 1.5, 3),     # a 0.5-degree laser (CSAIL): every 3rd
    (1.0, 2, 1.5, 2),     # a 1-degree laser (ACES): every 2nd, the step
    (0.25, 1, 1.5, 6),
    (0.5, 1, 1.6, 4),     # 3.2 steps: 4, the least at least 1.6 degrees apart
    (0.5, 5, 1.5, 5),     # free_beam_step larger
    (0.5, 2, 0.0, 2),     # off
])
def test_clearing_step_is_the_least_k_putting_beams_spacing_apart(between_deg, step, spacing, k):
    angles = np.radians(-90.0 + between_deg * np.arange(20))
    assert clearing_step(angles, step, spacing) == k


def test_clearing_step_reads_a_resolution_stored_a_hair_under_and_angles_across_pi():
    # float32's 0.5 degrees is 0.5 less 1e-8 rad: still every 3rd for 1.5 degrees, not 4th
    inc = float(np.float32(np.radians(0.5)))
    assert inc < np.radians(0.5)
    assert clearing_step(np.arange(10) * inc, 1, 1.5) == 3
    # a laser mounted backwards: its angles wrap from +pi to -pi between the first two
    angles = np.array([np.pi - np.radians(0.25), -np.pi + np.radians(0.25)])
    assert clearing_step(angles, 1, 1.5) == 3
    assert clearing_step(np.zeros(1), 2, 1.5) == 2      # one beam: nothing to space


def test_a_return_past_max_range_short_of_mark_range_marks_its_end_cell_and_clears_to_max_range():
    # one beam along +x, 3.0 m; the filter's max_range 2.0 m; without mark_range and with 4.0 m
    scan = Scan(ranges=np.array([3.0]), angles=np.zeros(1), range_min=0.1, range_max=10.0)
    points = np.array([[0.55, 0.05], [1.85, 0.05], [2.45, 0.05], [3.05, 0.05]])   # cells along the beam
    cells = {}
    for mark in (0.0, 4.0):
        slam = FastSlam(SlamConfig(particles=2, seed=0, toggle_noise=0, weight_model="likelihood", max_range=2.0,
                                   no_return_range=2.0, map_resolution=0.1, mark_range=mark))
        slam.step(np.zeros(3), scan)
        cells[mark] = _values(slam, points)
    free, occupied = slam.grid.quantise(slam.cfg.l_free), slam.grid.quantise(slam.cfg.l_occ)
    # cleared to max_range either way; between max_range and the return untouched; the end cell
    # a wall only with mark_range
    np.testing.assert_array_equal(cells[0.0], [[free, free, 0, 0]] * 2)
    np.testing.assert_array_equal(cells[4.0], [[free, free, 0, occupied]] * 2)
