"""The matcher's correlative search: pooled flags, candidate scores, the prior's pick, and
the part of the map a search can read."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.filter.grid import GridMaps
from fastslam.match.search import POOL, _nats, grid_search, pick, pool_occupied, pool_signed, search_area, window


def test_pooled_flags_mark_blocks_with_an_occupied_cell():
    rng = np.random.default_rng(0)
    a = rng.integers(-100, 30, (2, 8, 12), dtype=np.int8)
    half, quarter = pool_occupied(a)
    np.testing.assert_array_equal(half, a.reshape(2, 4, 2, 6, 2).max(axis=(2, 4)) > 0)
    np.testing.assert_array_equal(quarter, a.reshape(2, 2, 4, 3, 4).max(axis=(2, 4)) > 0)


def test_signed_pooled_flags_tell_occupied_unknown_and_free_blocks():
    a = np.full((1, 4, 8), -3, dtype=np.int8)   # all free ...
    a[0, 0, 0] = 5                              # ... but one occupied cell in the first 2x2 block
    a[0, 3, 7] = 0                              # and one unknown cell in the last
    half, quarter = pool_signed(a)
    np.testing.assert_array_equal(half[0], [[1, -1, -1, -1], [-1, -1, -1, 0]])
    np.testing.assert_array_equal(quarter[0], [[1, 0]])   # occupied wins; one unknown cell: not all free
    rng = np.random.default_rng(1)
    b = rng.integers(-100, 30, (2, 8, 12), dtype=np.int8)
    half, quarter = pool_signed(b)
    np.testing.assert_array_equal(half, np.sign(b.reshape(2, 4, 2, 6, 2).max(axis=(2, 4))))
    np.testing.assert_array_equal(quarter, np.sign(b.reshape(2, 2, 4, 3, 4).max(axis=(2, 4))))


def test_pooled_flags_of_one_cell_by_hand():
    a = np.full((9, 8, 8), -5, dtype=np.int8)           # 9 maps: more than one batch of 8
    a[8, 5, 6] = 1                                      # the last map: one occupied cell, row 5, column 6
    half, quarter = pool_occupied(a)
    assert half.dtype == np.int8 and half.shape == (9, 4, 4) and quarter.shape == (9, 2, 2)
    assert np.count_nonzero(half) == 1 and half[8, 2, 3] == 1
    assert np.count_nonzero(quarter) == 1 and quarter[8, 1, 1] == 1


def test_grid_search_scores_by_hand():
    level = np.zeros((1, 8, 8), dtype=np.int8)
    level[0, 4, 5] = 1                                  # occupied: cell ix 5, iy 4
    poses = np.zeros((1, 3))
    # two end points, in cells (5, 4) and (6, 4): unshifted the first scores; shifted one
    # cell left (dx = -1) the second does. Candidate t = (dy + 1) * 3 + (dx + 1).
    local = np.array([[5.5, 4.5], [6.5, 4.5]])
    scores = grid_search(level, np.zeros(2), 1.0, poses, np.array([0.0]), local, 1, flags=True)
    assert scores.shape == (1, 1, 9) and scores.dtype == np.int64
    np.testing.assert_array_equal(scores[0, 0], [0, 0, 0, 1, 1, 0, 0, 0, 0])
    # on log-odds, only occupied (> 0) counts, by presence not strength
    logodds = np.where(level > 0, 90, -40).astype(np.int8)
    scores = grid_search(logodds, np.zeros(2), 1.0, poses, np.array([0.0, np.pi]), local, 1)
    np.testing.assert_array_equal(scores[0, 0], [0, 0, 0, 1, 1, 0, 0, 0, 0])
    np.testing.assert_array_equal(scores[0, 1], np.zeros(9))   # turned round: both end points behind


def test_nats_are_log_likelihoods_relative_to_the_best():
    # best 10: a candidate with 5 leaves half the 60 beams unexplained; a map that explains
    # nothing counts as a best of 1 (no division by zero), equal for every candidate
    np.testing.assert_allclose(_nats(np.array([[0, 5, 10], [0, 0, 0]]), 60),
                               [[-60.0, -30.0, 0.0], [-60.0, -60.0, -60.0]])


def test_motion_prior_is_tighter_along_the_heading():
    # Scores flat everywhere: only the prior decides, and the prior along the heading
    # (std 0.02) is tighter than across it (0.2), so the pick moves across, not along.
    poses = np.array([[0.0, 0.0, np.pi / 2]])           # heading +y
    scores = np.zeros((1, 1, 9), dtype=np.int64)
    centre = np.array([[0.05, 0.05, np.pi / 2]])        # 5 cm off in x (across) and y (along)
    out = pick(scores, poses, np.zeros(1), 1, 0.05, centre, np.array([0.02, 0.2, 0.1]), 60)
    np.testing.assert_allclose(out[0], [0.05, 0.05, np.pi / 2])
    out = pick(scores, poses, np.zeros(1), 1, 0.05, centre, np.array([0.2, 0.02, 0.1]), 60)
    np.testing.assert_allclose(out[0], [0.05, 0.05, np.pi / 2])


def test_pick_takes_the_best_score_against_a_weak_prior():
    poses = np.array([[1.0, 2.0, 0.0]])
    scores = np.zeros((1, 2, 9), dtype=np.int64)
    scores[0, 1, 2] = 10                                # turn 1, candidate t = 2: dy = -1, dx = +1
    out = pick(scores, poses, np.array([0.0, 0.1]), 1, 0.05, poses, np.array([1.0, 1.0, 1.0]), 60)
    np.testing.assert_allclose(out[0], [1.05, 1.95, 0.1])


def test_search_gain_weighs_end_points_against_the_prior():
    # Candidate dx = +1 cell (0.05 m along +x, the heading) puts 2 more of 20 end points on
    # walls (best 20, so -2/20 * 60 = -6 nats at the centre). The prior along is 0.02 m:
    # the shift costs 0.5 * (0.05 / 0.02)^2 = 3.125 nats. Gain 1: -6 < -3.125, the shift
    # wins; gain 0.5: -3 > -3.125, the centre wins; gain 0.52: -3.12 > -3.125 still.
    poses = np.array([[0.0, 0.0, 0.0]])
    scores = np.full((1, 1, 9), 18, dtype=np.int64)
    scores[0, 0, 5] = 20                                # t = 5: dy = 0, dx = +1
    prior = np.array([0.02, 0.02, 0.1])
    shifted = pick(scores, poses, np.zeros(1), 1, 0.05, poses, prior, 60)
    np.testing.assert_allclose(shifted[0], [0.05, 0.0, 0.0])
    np.testing.assert_allclose(pick(scores, poses, np.zeros(1), 1, 0.05, poses, prior, 60, gain=1.0)[0],
                               [0.05, 0.0, 0.0])
    for gain in (0.5, 0.52):
        np.testing.assert_allclose(pick(scores, poses, np.zeros(1), 1, 0.05, poses, prior, 60, gain=gain)[0],
                                   [0.0, 0.0, 0.0])
    # just above the break-even gain 3.125 / 6 = 0.5208: the shift wins again
    np.testing.assert_allclose(pick(scores, poses, np.zeros(1), 1, 0.05, poses, prior, 60, gain=0.53)[0],
                               [0.05, 0.0, 0.0])


def test_window_is_the_reach_of_the_poses_in_pooled_cells():
    grid = GridMaps(1, (40, 40), 0.25, (0.0, 0.0))
    # (2, 2) +- 0.5 m: cells 6 .. 10, rounded up to sides of POOL cells from cell 6
    assert window(grid, np.array([[2.0, 2.0, 0.0]]), 0.5) == (6, 6, 14, 14)
    # at the edge the window is clipped to the grid, still a multiple of POOL
    x0, y0, x1, y1 = window(grid, np.array([[9.5, 0.25, 0.0]]), 0.5)
    assert (x0, y0, x1, y1) == (36, 0, 40, 4)
    assert (x1 - x0) % POOL == 0 and (y1 - y0) % POOL == 0


def test_a_shifted_window_starts_that_many_cells_lower_and_still_covers_the_reach():
    grid = GridMaps(1, (40, 40), 0.25, (0.0, 0.0))
    pose = np.array([[2.0, 2.0, 0.0]])
    # cells 6 .. 10 as above, from cell 6 - k: sides of POOL cells reaching past cell 10
    assert window(grid, pose, 0.5, shift=2) == (4, 4, 12, 12)
    assert window(grid, pose, 0.5, shift=3) == (3, 3, 11, 11)
    # at the grid's first cell the corner stays there
    assert window(grid, np.array([[0.25, 0.25, 0.0]]), 0.5, shift=2)[:2] == (0, 0)


def test_search_area_keeps_the_windows_alignment():
    grid = GridMaps(1, (40, 40), 0.25, (0.0, 0.0))
    # one end point 1 m ahead of (5, 5): at (6, 5); no turn, no shift: 0.5 m margin around it,
    # cells 22 .. 26 and 18 .. 22, widened to POOL-aligned blocks of the window
    area = search_area(grid, np.array([[5.0, 5.0, 0.0]]), np.array([[1.0, 0.0]]), 0.0, 0.0, (0, 0, 40, 40))
    assert area == (20, 16, 28, 24)
    # the window bounds it
    assert search_area(grid, np.array([[5.0, 5.0, 0.0]]), np.array([[1.0, 0.0]]), 0.0, 0.0,
                       (24, 20, 40, 40)) == (24, 20, 28, 24)


@pytest.mark.parametrize("turn", [0.0, 0.3])
def test_search_area_holds_every_candidate_end_point(turn):
    grid = GridMaps(1, (80, 80), 0.1, (-4.0, -4.0))
    poses = np.array([[0.3, -0.2, 0.5], [-0.1, 0.4, -1.0]])
    local = np.array([[2.0, 0.0], [0.0, 1.5], [-1.0, -1.0]])
    win = window(grid, poses, 3.5)
    x0, y0, x1, y1 = search_area(grid, poses, local, turn, 0.2, win)
    for a in np.linspace(-turn, turn, 21):
        for dx in (-0.2, 0.2):
            p = poses + [dx, dx, a]
            c, s = np.cos(p[:, 2, None]), np.sin(p[:, 2, None])
            xs = p[:, 0, None] + c * local[:, 0] - s * local[:, 1]
            ys = p[:, 1, None] + s * local[:, 0] + c * local[:, 1]
            cells = grid.world_to_cell(np.stack([xs, ys], -1).reshape(-1, 2))
            assert np.all((cells[:, 0] >= x0) & (cells[:, 0] < x1) & (cells[:, 1] >= y0) & (cells[:, 1] < y1))
    assert (x0 - win[0]) % POOL == 0 and (y0 - win[1]) % POOL == 0
