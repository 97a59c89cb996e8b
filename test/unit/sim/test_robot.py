"""Burger kinematics, clamps, collision stop, simulated odometry and its noise switch."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastslam.geometry import relative
from fastslam.sim.robot import DiffDrive, OdometryModel, clamp_cmd, integrate
from fastslam.sim.world import world_from_dict

WALL = world_from_dict({"segments": [[[1.0, -5.0], [1.0, 5.0]]]})


def test_clamp_to_burger_limits() -> None:
    assert clamp_cmd(1.0, -10.0) == (0.22, -2.84)
    assert clamp_cmd(-0.1, 0.5) == (-0.1, 0.5)
    assert clamp_cmd(float("nan"), float("inf")) == (0.0, 0.0)


def test_integrate_line_and_arc() -> None:
    np.testing.assert_allclose(integrate([0, 0, 0], 0.2, 0.0, 1.0), [0.2, 0.0, 0.0])
    # quarter circle of radius v/w = 1: v = w = pi/2 for 1 s from (0, 0, 0) ends at (1, 1, pi/2)
    np.testing.assert_allclose(integrate([0, 0, 0], math.pi / 2, math.pi / 2, 1.0), [1.0, 1.0, math.pi / 2], atol=1e-12)


def test_step_clamps_speed() -> None:
    robot = DiffDrive(WALL, np.array([-3.0, 0.0, 0.0]))
    for _ in range(10):
        robot.step(1.0, 0.0, 0.1)
    np.testing.assert_allclose(robot.pose, [-3.0 + 0.22, 0.0, 0.0])
    assert robot.v == 0.22


def test_collision_stops_at_radius_and_allows_backing_off() -> None:
    robot = DiffDrive(WALL, np.array([0.0, 0.0, 0.0]))
    for _ in range(200):
        robot.step(0.22, 0.0, 0.05)
    assert robot.collided and robot.v == 0.0
    assert 1.0 - 0.105 - 0.22 * 0.05 <= robot.pose[0] < 1.0 - 0.105
    robot.step(0.0, 1.0, 0.1)                  # turning in place is always allowed
    assert robot.pose[2] == pytest.approx(0.1)
    x = robot.pose[0]
    robot.step(-0.1, 0.0, 0.1)                 # driving away is allowed
    assert not robot.collided and robot.pose[0] < x


def test_perfect_odometry_equals_truth() -> None:
    spawn = np.array([1.0, 2.0, 0.5])
    odom = OdometryModel(spawn, np.random.default_rng(0), perfect=True, scale_linear=1.5, slip_linear=0.3)
    robot = DiffDrive(world_from_dict({"circles": [[50, 50, 1]]}), spawn)
    np.testing.assert_allclose(odom.pose, 0.0)
    for i in range(300):
        robot.step(0.2, 0.8 * math.sin(i / 30), 1 / 30)
        odom.update(robot.pose)
    np.testing.assert_allclose(odom.pose, relative(spawn, robot.pose), atol=1e-12)


def test_noisy_odometry_drifts_and_is_seeded() -> None:
    def run(seed: int) -> np.ndarray:
        spawn = np.zeros(3)
        odom = OdometryModel(spawn, np.random.default_rng(seed), scale_linear=1.1, slip_linear=0.02,
                             slip_angular=0.05)
        robot = DiffDrive(world_from_dict({"circles": [[50, 50, 1]]}), spawn)
        for _ in range(300):
            robot.step(0.2, 0.0, 1 / 30)
            odom.update(robot.pose)
        return odom.pose

    a, b = run(0), run(0)
    np.testing.assert_array_equal(a, b)
    assert a[0] == pytest.approx(2.0 * 1.1, rel=0.02)    # scale error: 10 % too far after 2 m
    assert not np.array_equal(a, run(1))
