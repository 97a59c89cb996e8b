"""Particle weights: the assignment's 1/(||d - z|| + 1), the likelihood end-point model,
normalising log-weights, and end-point distances to the nearest occupied cell."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastslam.filter.grid import GridMaps
from fastslam.filter.scan import Beams
from fastslam.filter.weights import assignment_log_weights, endpoint_distances, likelihood_log_weights, normalise_log


def test_weight_by_hand():
    # d = [1, 2], z = [1, 1]: ||d - z|| = 1, w = 1 / 2
    log_w = assignment_log_weights(np.array([[1.0, 2.0]]), np.array([1.0, 1.0]), np.array([True, True]))
    assert np.exp(log_w[0]) == pytest.approx(0.5)


def test_weight_of_a_three_four_five_difference():
    # d - z = (3, 4): ||.|| = 5, w = 1 / 6; equal scans: w = 1
    log_w = assignment_log_weights(np.array([[4.0, 6.0], [1.0, 2.0]]), np.array([1.0, 2.0]), np.ones(2, bool))
    np.testing.assert_allclose(np.exp(log_w), [1 / 6, 1.0])


def test_invalid_beams_are_left_out_of_d_and_z():
    d = np.array([[1.0, 2.0, 9.0], [1.0, 1.0, 0.0]])
    z = np.array([1.0, 1.0, np.inf])
    w = np.exp(assignment_log_weights(d, z, np.array([True, True, False])))
    np.testing.assert_allclose(w, [0.5, 1.0])
    np.testing.assert_allclose(normalise_log(np.log(w)), [1 / 3, 2 / 3])


def test_normalise_is_uniform_when_nothing_is_finite():
    np.testing.assert_allclose(normalise_log(np.array([-np.inf, np.nan])), [0.5, 0.5])


def test_log_weights_normalise_like_direct_weights():
    log_w = np.log(np.array([0.1, 0.3, 0.6, 1e-3]))
    direct = np.exp(log_w) / np.exp(log_w).sum()
    np.testing.assert_allclose(normalise_log(log_w), direct, rtol=1e-12)
    np.testing.assert_allclose(normalise_log(log_w - 500.0), direct, rtol=1e-12)


def test_log_weights_stay_finite_where_direct_computation_underflows():
    log_w = np.array([-2000.0, -2001.0, -2000.0 - np.log(3.0)])
    assert np.exp(log_w).sum() == 0.0                       # direct: 0/0
    np.testing.assert_allclose(normalise_log(log_w), np.array([3.0, 3.0 / np.e, 1.0]) / (4.0 + 3.0 / np.e))
    np.testing.assert_allclose(normalise_log(np.array([-np.inf, 0.0, -np.inf])), [0.0, 1.0, 0.0])
    np.testing.assert_allclose(normalise_log(np.full(4, -np.inf)), [0.25] * 4)


def test_likelihood_log_weights_hand_computed():
    d = np.array([[0.0, 0.05, 10.0], [0.1, 0.1, 0.0]])
    valid = np.array([True, True, False])
    lw = likelihood_log_weights(d, valid, sigma=0.05, max_dist=0.3, gain=0.5)
    np.testing.assert_allclose(lw, [0.5 * -0.5, 0.5 * -4.0])


def test_likelihood_caps_each_distance():
    # 1.0 m is capped at 0.2 m: -(0.2 / 0.1)^2 / 2 = -2 for that beam, -0.5 for 0.1 m
    lw = likelihood_log_weights(np.array([[1.0, 0.1]]), np.ones(2, bool), sigma=0.1, max_dist=0.2, gain=1.0)
    assert lw[0] == pytest.approx(-2.5)


def _one_wall_grid() -> GridMaps:
    grid = GridMaps(2, (40, 40), 0.05, (-1.0, -1.0))
    grid.logodds[:, :, 30] = 50     # a wall of occupied cells, centres at x = 0.525
    grid.logodds[1] = 0             # particle 1 has seen nothing
    return grid


def test_endpoint_distances_are_distances_to_the_nearest_occupied_cell_centre():
    grid = _one_wall_grid()
    beams = Beams(angles=np.array([0.0, 0.0, np.pi / 2]), ranges=np.array([0.425, 0.525, np.inf]),
                  hit=np.array([True, True, False]), free_range=np.array([0.425, 0.525, 0.0]), range_min=0.1)
    poses = np.array([[0.0, 0.025, 0.0], [0.0, 0.025, 0.0]])
    d = endpoint_distances(grid, poses, beams, max_dist=0.3)
    assert d.shape == (2, 3)
    assert d[0, 0] == pytest.approx(0.1, abs=1e-9)
    assert d[0, 1] == pytest.approx(0.0, abs=1e-9)
    assert d[0, 2] == 0.3                            # no return: the cap, left out by the weight
    np.testing.assert_array_equal(d[1], [0.3, 0.3, 0.3])  # empty map: every end point capped


def test_endpoint_distances_cap_far_walls():
    grid = _one_wall_grid()
    beams = Beams(angles=np.array([0.0]), ranges=np.array([0.1]), hit=np.array([True]),
                  free_range=np.array([0.1]), range_min=0.05)
    d = endpoint_distances(grid, np.array([[0.0, 0.025, 0.0]] * 2), beams, max_dist=0.15)
    np.testing.assert_array_equal(d, [[0.15], [0.15]])


def test_endpoint_distance_to_a_lone_cell_diagonally_and_at_the_grid_edge():
    grid = GridMaps(1, (10, 10), 0.1, (0.0, 0.0))
    grid.logodds[0, 0, 0] = 5                         # centre (0.05, 0.05), in the corner of the grid
    beams = Beams(angles=np.array([0.0, 0.0]), ranges=np.array([0.3, 0.05]), hit=np.ones(2, bool),
                  free_range=np.array([0.3, 0.05]), range_min=0.01)
    # from (0, 0.09) along +x: end points (0.3, 0.09) and (0.05, 0.09); the search crosses the edge
    d = endpoint_distances(grid, np.array([[0.0, 0.09, 0.0]]), beams, max_dist=0.3)
    np.testing.assert_allclose(d, [[math.hypot(0.25, 0.04), 0.04]], atol=1e-9)
