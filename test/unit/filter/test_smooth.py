"""spread_gaps: each gap's error between two processed scans spread along it, by hand."""
from __future__ import annotations

import numpy as np

from fastslam.filter.smooth import spread_gaps


def _straight(n: int) -> np.ndarray:
    return np.column_stack([np.arange(n, dtype=float), np.zeros(n), np.zeros(n)])


def test_a_sideways_gap_is_spread_by_distance_the_odometry_step_weighed():
    # scans 0 and 3 processed; the motion since 0 leads to (3, 0), the particle is at (3, 0.3)
    odom = _straight(4)
    poses = odom.copy()
    poses[3] = [3.0, 0.3, 0.0]
    done = np.array([True, False, False, True])
    # steps of 1 m, the last (odometry) one counted twice: shares 1/4 and 2/4 of 0.3 m
    out = spread_gaps(poses, done, odom, odom_weight=2.0)
    np.testing.assert_allclose(out, [[0, 0, 0], [1, 0.075, 0], [2, 0.15, 0], [3, 0.3, 0]], atol=1e-12)
    # counted once: thirds
    out = spread_gaps(poses, done, odom, odom_weight=1.0)
    np.testing.assert_allclose(out[1:3, 1], [0.1, 0.2], atol=1e-12)


def test_a_turn_is_spread_along_the_arc_and_lands_on_the_processed_pose():
    odom = _straight(3)
    poses = odom.copy()
    poses[2] = [2.0, 0.0, 0.2]            # the particle ends turned by 0.2 rad
    done = np.array([True, False, True])
    out = spread_gaps(poses, done, odom, odom_weight=1.0)
    # half the way: half the rotation, about the start of the gap (the correction's twist halved)
    np.testing.assert_allclose(out[1, 2], 0.1, atol=1e-12)
    # the correction (2, 0, 0) -> (2, 0, 0.2) is a rotation of 0.2 about (2, 0): half of it turns (1, 0) about (2, 0)
    about = np.array([2.0, 0.0])
    c, s = np.cos(0.1), np.sin(0.1)
    np.testing.assert_allclose(out[1, :2], about + np.array([[c, -s], [s, c]]) @ (np.array([1.0, 0.0]) - about),
                               atol=1e-12)
    np.testing.assert_array_equal(out[[0, 2]], poses[[0, 2]])


def test_scans_outside_processed_ones_and_standing_gaps_are_kept():
    odom = np.zeros((5, 3))               # standing: no length to spread over
    poses = np.zeros((5, 3))
    poses[3] = [0.0, 0.1, 0.0]
    done = np.array([False, True, False, True, False])
    np.testing.assert_array_equal(spread_gaps(poses, done, odom), poses)
    # moving, but scans before the first and after the last processed one stay
    odom = _straight(5)
    poses = odom.copy()
    poses[3] = [3.0, 0.2, 0.0]
    out = spread_gaps(poses, done, odom, odom_weight=1.0)
    np.testing.assert_array_equal(out[[0, 4]], poses[[0, 4]])
    np.testing.assert_allclose(out[2], [2.0, 0.1, 0.0], atol=1e-12)
