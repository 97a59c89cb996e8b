"""Planar pose helpers and the closed-form 3x3 algebra, against answers worked by hand."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastslam.geometry import (
    cholesky3,
    circular_mean,
    compose,
    cos_sin,
    inv3,
    inverse,
    pose_exp,
    pose_log,
    relative,
    solve3,
    transform_points,
    wrap_angle,
    yaw_from_quaternion,
)

ZERO = np.zeros(3)


def test_wrap_and_circular_mean():
    np.testing.assert_allclose(wrap_angle([np.pi, -np.pi, 3 * np.pi / 2, 0.1]), [-np.pi, -np.pi, -np.pi / 2, 0.1])
    eps = 0.01
    assert abs(abs(circular_mean([np.pi - eps, -np.pi + eps])) - np.pi) < 1e-9


def test_wrap_angle_of_several_turns():
    np.testing.assert_allclose(wrap_angle([2 * np.pi + 0.5, -2 * np.pi - 0.5, 5.0, -4.0]),
                               [0.5, -0.5, 5.0 - 2 * np.pi, 2 * np.pi - 4.0], atol=1e-12)
    assert wrap_angle(0.0).shape == ()


def test_compose_inverse_round_trip():
    a = np.array([1.0, -2.0, 2.5])
    np.testing.assert_allclose(compose(a, inverse(a)), ZERO, atol=1e-12)
    np.testing.assert_allclose(compose([1, 0, np.pi / 2], [1, 0, 0]), [1, 1, np.pi / 2], atol=1e-12)


def test_compose_by_hand_and_broadcast():
    # a faces +y: b's x runs along +y, b's y along -x
    a = [1.0, 2.0, np.pi / 2]
    np.testing.assert_allclose(compose(a, [0.5, -1.0, np.pi / 4]), [2.0, 2.5, 3 * np.pi / 4], atol=1e-12)
    out = compose(a, [[0.5, -1.0, np.pi / 4], [0.0, 0.0, np.pi]])
    np.testing.assert_allclose(out, [[2.0, 2.5, 3 * np.pi / 4], [1.0, 2.0, -np.pi / 2]], atol=1e-12)


def test_inverse_and_relative_by_hand():
    a = np.array([1.0, 2.0, np.pi / 2])
    np.testing.assert_allclose(inverse(a), [-2.0, 1.0, -np.pi / 2], atol=1e-12)
    # b is 1 m in front of a, turned a further quarter left
    np.testing.assert_allclose(relative(a, [1.0, 3.0, np.pi]), [1.0, 0.0, np.pi / 2], atol=1e-12)
    np.testing.assert_allclose(relative([[0, 0, 0], a], a), [a, ZERO], atol=1e-12)


def test_transform_points_by_hand():
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, np.pi / 2]])
    x, y = transform_points(poses, [[1.0, 0.0], [0.0, 2.0]])
    assert x.shape == y.shape == (2, 2)
    np.testing.assert_allclose(x, [[1.0, 0.0], [1.0, -1.0]], atol=1e-12)
    np.testing.assert_allclose(y, [[0.0, 2.0], [2.0, 1.0]], atol=1e-12)
    x, y = transform_points([2.0, 0.0, np.pi], [[1.0, 1.0]])          # one pose: (M,) each
    np.testing.assert_allclose([x[0], y[0]], [1.0, -1.0], atol=1e-12)


def test_circular_mean_with_weights():
    assert circular_mean([0.0, np.pi / 2]) == pytest.approx(np.pi / 4)
    assert circular_mean([0.0, np.pi / 2], [3.0, 1.0]) == pytest.approx(math.atan2(1.0, 3.0))
    assert circular_mean([3.0, -3.0], [1.0, 0.0]) == pytest.approx(3.0)


def test_yaw_from_quaternion_need_not_be_normalised():
    assert yaw_from_quaternion(0.0, 0.0, math.sin(0.3), math.cos(0.3)) == pytest.approx(0.6)
    assert yaw_from_quaternion(0.0, 0.0, 3 * math.sin(0.3), 3 * math.cos(0.3)) == pytest.approx(0.6)
    assert yaw_from_quaternion(0.0, 0.0, 1.0, 0.0) == pytest.approx(np.pi)
    # roll pi, then yaw 0.3 (an upside-down laser): (x, y, z, w) = (cos 0.15, sin 0.15, 0, 0)
    assert yaw_from_quaternion(math.cos(0.15), math.sin(0.15), 0.0, 0.0) == pytest.approx(0.3)


M = np.array([[1.0, 2.0, 3.0], [0.0, 1.0, 4.0], [5.0, 6.0, 0.0]])       # det 1
M_INV = np.array([[-24.0, 18.0, 5.0], [20.0, -15.0, -4.0], [-5.0, 4.0, 1.0]])


def test_inv3_hand_computed():
    np.testing.assert_allclose(inv3(M), M_INV, atol=1e-12)
    np.testing.assert_allclose(inv3(np.diag([2.0, 4.0, 0.5])), np.diag([0.5, 0.25, 2.0]))
    stack = inv3(np.stack([M, 2 * M]))
    assert stack.shape == (2, 3, 3)
    np.testing.assert_allclose(stack[1], M_INV / 2, atol=1e-12)


def test_solve3_hand_computed():
    # M (1, -2, 3) = (6, 10, -7)
    np.testing.assert_allclose(solve3(M, np.array([6.0, 10.0, -7.0])), [1.0, -2.0, 3.0], atol=1e-12)
    x = solve3(np.stack([M, np.eye(3)]), np.array([[6.0, 10.0, -7.0], [4.0, 5.0, 6.0]]))
    np.testing.assert_allclose(x, [[1.0, -2.0, 3.0], [4.0, 5.0, 6.0]], atol=1e-12)


def test_cholesky3_hand_computed():
    lower = np.array([[2.0, 0.0, 0.0], [1.0, 3.0, 0.0], [-1.0, 2.0, 4.0]])
    spd = np.array([[4.0, 2.0, -2.0], [2.0, 10.0, 5.0], [-2.0, 5.0, 21.0]])   # lower @ lower.T
    np.testing.assert_allclose(cholesky3(spd), lower, atol=1e-12)
    np.testing.assert_allclose(cholesky3(np.stack([spd, np.diag([9.0, 1.0, 0.25])]))[1],
                               np.diag([3.0, 1.0, 0.5]))


def test_cos_sin_of_a_strided_view_equals_that_of_its_copy(rng):
    poses = rng.uniform(-np.pi, np.pi, (1001, 3))
    view = poses[:, 2]                                  # strided: every third float
    c, s = cos_sin(view)
    c_copy, s_copy = cos_sin(view.copy())
    assert np.array_equal(c, c_copy) and np.array_equal(s, s_copy)   # bit for bit
    assert c.flags.c_contiguous and view.flags.c_contiguous is False
    np.testing.assert_allclose(c, np.cos(view), rtol=0, atol=1e-15)
    np.testing.assert_allclose(s, np.sin(view), rtol=0, atol=1e-15)
    c0, s0 = cos_sin(np.pi / 2)
    assert c0.shape == () and s0 == 1.0 and abs(c0) < 1e-15


def test_pose_exp_of_a_quarter_circle_by_hand():
    # a twist of pi/2 forward and pi/2 turned: the quarter circle of radius 1 to (1, 1), facing +y
    np.testing.assert_allclose(pose_exp([np.pi / 2, 0.0, np.pi / 2]), [1.0, 1.0, np.pi / 2], atol=1e-12)
    np.testing.assert_allclose(pose_log([1.0, 1.0, np.pi / 2]), [np.pi / 2, 0.0, np.pi / 2], atol=1e-12)
    # half the twist: half way round the same circle (centre (0, 1)), 45 degrees on
    half = pose_exp(0.5 * pose_log([1.0, 1.0, np.pi / 2]))
    np.testing.assert_allclose(half, [np.sqrt(0.5), 1.0 - np.sqrt(0.5), np.pi / 4], atol=1e-12)


def test_pose_log_without_turn_is_the_translation_and_round_trips():
    np.testing.assert_allclose(pose_log([2.0, -3.0, 0.0]), [2.0, -3.0, 0.0], atol=0)
    rng = np.random.default_rng(3)
    poses = np.column_stack([rng.uniform(-5, 5, (50, 2)), rng.uniform(-3.1, 3.1, 50)])
    np.testing.assert_allclose(pose_exp(pose_log(poses)), poses, atol=1e-9)
