"""Exact ray casting against segments and circles, hand-computed answers."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastslam.sim.lidar import Lidar, cast_rays, driver_ranges, ray_circles, ray_segments
from fastslam.sim.world import world_from_dict


def test_ray_segment_hand_computed() -> None:
    seg = np.array([[[2.0, -1.0], [2.0, 1.0]]])
    dirs = np.array([[1.0, 0.0], [math.sqrt(0.5), math.sqrt(0.5)], [-1.0, 0.0], [0.0, 1.0],
                     [2 / math.sqrt(5), 1 / math.sqrt(5)]])
    d = ray_segments([0.0, 0.0], dirs, seg)
    # along x: 2; at 45 deg it would meet x=2 at y=2, past the end: miss; behind: miss;
    # parallel: miss; towards the end point (2, 1): sqrt(5)
    np.testing.assert_allclose(d, [2.0, np.inf, np.inf, np.inf, math.sqrt(5)])


def test_ray_segment_nearest_of_several() -> None:
    segs = np.array([[[3, -1], [3, 1]], [[1, -1], [1, 1]], [[-1, -5], [-1, 5]]], float)
    np.testing.assert_allclose(ray_segments([0.5, 0.0], [[1.0, 0.0], [-1.0, 0.0]], segs), [0.5, 1.5])


def test_ray_circle_hand_computed() -> None:
    circ = np.array([[3.0, 0.0, 1.0]])
    a = math.asin(0.2)                  # inside the tangent angle asin(1/3)
    dirs = np.array([[1.0, 0.0], [0.0, 1.0], [math.cos(a), math.sin(a)]])
    d = ray_circles([0.0, 0.0], dirs, circ)
    # head-on: 3 - 1 = 2; sideways: miss; at angle a: t = 3 cos a - sqrt(1 - 9 sin^2 a) = 3 sqrt(0.96) - 0.8
    np.testing.assert_allclose(d, [2.0, np.inf, 3 * math.sqrt(0.96) - 0.8])
    # from inside the circle the far side is hit
    np.testing.assert_allclose(ray_circles([3.0, 0.0], [[1.0, 0.0]], circ), [1.0])


def test_cast_rays_world_frame_and_lidar_mount() -> None:
    w = world_from_dict({"segments": [[[2, -5], [2, 5]]], "circles": [[0, 3, 0.5]]})
    # robot at (0, 0) facing +y: beam 0 looks along +y to the circle, beam -90 deg along +x to the wall
    np.testing.assert_allclose(cast_rays(w, [0, 0, math.pi / 2], [0.0, -math.pi / 2]), [2.5, 2.0])
    lidar = Lidar(w, range_max=3.5)
    ranges = lidar.scan([0.0, 0.0, 0.0])          # sensor 0.032 m behind the base centre
    assert ranges.shape == (360,)
    np.testing.assert_allclose(ranges[0], 2.032)
    np.testing.assert_allclose(ranges[90], math.hypot(3, 0.032) - 0.5, rtol=1e-3)  # close to the circle centre line
    assert np.isinf(ranges[180])                   # nothing behind within 3.5 m


def test_range_limits_and_noise_seeded() -> None:
    w = world_from_dict({"segments": [[[0.1, -1], [0.1, 1]], [[-5, -1], [-5, 1]], [[-1, 1.0], [1, 1.0]]]})
    lidar = Lidar(w, mount=(0.0, 0.0, 0.0))
    r = lidar.cast([0, 0, 0], np.array([0.0, math.pi, math.pi / 2]), 0.12, 3.5)
    # too close: the distance, below range_min (as Gazebo); too far: no return; exact
    assert r[0] == pytest.approx(0.1) and np.isinf(r[1]) and r[2] == 1.0
    # as the LDS-01 driver publishes them: 0.0 for both too close and no return
    np.testing.assert_array_equal(driver_ranges(r, 0.12, "zero"), [0.0, 0.0, 1.0])
    assert driver_ranges(r, 0.12, "inf") is r
    r1 = lidar.cast([0, 0, 0], np.full(1000, math.pi / 2), 0.12, 3.5, rng=np.random.default_rng(0), sigma=0.01)
    r2 = lidar.cast([0, 0, 0], np.full(1000, math.pi / 2), 0.12, 3.5, rng=np.random.default_rng(0), sigma=0.01)
    np.testing.assert_array_equal(r1, r2)
    assert abs(r1.mean() - 1.0) < 0.002 and abs(r1.std() - 0.01) < 0.001


def test_angles_are_lds01() -> None:
    lidar = Lidar(world_from_dict({"circles": [[5, 5, 1]]}))
    assert lidar.angles[0] == 0.0 and len(lidar.angles) == 360
    np.testing.assert_allclose(np.diff(lidar.angles), math.radians(1.0))
