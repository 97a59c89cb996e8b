"""Map and trajectory quality against ground truth: errors against the interpolated truth,
boundary recall, spurious cells, nearest distances."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.eval.maps import in_frame_of, map_quality, nearest_distance, run_quality, trajectory_errors
from fastslam.sim.world import world_from_dict


def test_trajectory_errors_against_interpolated_truth():
    truth = np.array([[0.0, 0, 0, 0], [1.0, 1, 0, 0], [2.0, 2, 0, 0]])
    est = np.array([[0.5, 0.5, 0.3, 0], [1.5, 1.5, -0.4, 0], [5.0, 0, 0, 0]])
    np.testing.assert_allclose(trajectory_errors(est, truth), [0.3, 0.4])


def test_map_quality_counts_recall_and_spurious_cells():
    occ = np.full((20, 20), 0, dtype=np.int8)
    occ[:, 15] = 100           # a wall at x in [1.5, 1.6), right where the truth is
    occ[2, 2] = 100            # one stray cell
    occ[:, :1] = -1            # never seen
    boundary = np.c_[np.full(200, 1.55), np.linspace(0.0, 1.999, 200)]
    q = map_quality(occ, 0.1, (0.0, 0.0), boundary)
    assert q["boundary_recall"] == 1.0 and q["observed_fraction"] == 1.0
    assert q["occupied_cells"] == 21 and q["spurious_fraction"] == pytest.approx(1 / 21)
    occ[:, 15] = 0             # the wall seen as free: observed, but missed
    assert map_quality(occ, 0.1, (0.0, 0.0), boundary)["boundary_recall"] == 0.0


def test_points_in_the_frame_of_a_pose():
    out = in_frame_of(np.array([1.0, 2.0, np.pi / 2]), np.array([[1.0, 3.0], [0.0, 2.0]]))
    np.testing.assert_allclose(out, [[1.0, 0.0], [0.0, 1.0]], atol=1e-12)


def test_nearest_distance_by_hand_and_in_chunks():
    points = np.array([[0.0, 0.0], [3.0, 4.0], [10.0, 0.0]])
    targets = np.array([[0.0, -1.0], [6.0, 8.0], [10.0, -2.0]])
    np.testing.assert_allclose(nearest_distance(points, targets), [1.0, 5.0, 2.0])
    np.testing.assert_allclose(nearest_distance(points, targets, pairs=1), [1.0, 5.0, 2.0])  # a point at a time
    assert np.all(np.isinf(nearest_distance(points, np.zeros((0, 2)))))


def test_map_quality_without_a_map():
    occ = np.full((10, 10), -1, dtype=np.int8)
    q = map_quality(occ, 0.1, (0.0, 0.0), np.array([[0.55, 0.55]]))
    assert q == {"boundary_recall": 0.0, "observed_fraction": 0.0, "spurious_fraction": 0.0, "occupied_cells": 0}


def test_run_quality_in_the_frame_of_the_spawn():
    # a wall at x = 2 in the world; the robot spawned at (1, 0) facing +x: the wall is 1 m ahead
    world = world_from_dict({"segments": [[[2.0, -1.0], [2.0, 1.0]]], "spawn": [1.0, 0.0, 0.0]})
    occ = np.zeros((40, 40), dtype=np.int8)
    occ[:, 30] = 100                                    # cells x in [1.0, 1.05): the wall, map frame
    truth = np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 0.5, 0.0, 0.0]])
    est = np.array([[0.0, 0.0, 0.3, 0.0], [1.0, 0.5, -0.4, 0.0]])
    m = run_quality(world, est, truth, occ, 0.05, (-0.5, -1.0))
    assert m["trajectory_rms_m"] == pytest.approx(np.sqrt((0.09 + 0.16) / 2))
    assert m["trajectory_max_m"] == pytest.approx(0.4) and m["final_error_m"] == pytest.approx(0.4)
    assert m["boundary_recall"] == 1.0 and m["occupied_cells"] == 40
    assert m["spurious_fraction"] == 0.0 and m["observed_fraction"] == 1.0
