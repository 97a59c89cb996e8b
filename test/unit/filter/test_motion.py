"""Motion of all particles at once: the assignment's model (dr along the old heading plus
additive noise) and the rot1-trans-rot2 odometry model."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.filter.motion import (
    odometry_std,
    odometry_step,
    sample_motion_assignment,
    sample_motion_odometry,
    step_sigmas,
)
from fastslam.geometry import compose, relative, wrap_angle

ZERO = np.zeros(3)


def test_heading_pi_over_2_moves_along_y_without_noise():
    poses = np.array([[0.0, 0.0, np.pi / 2]])
    sample_motion_assignment(poses, ZERO, np.array([0.1, 0.0, 0.0]), np.zeros(3), np.random.default_rng(0))
    np.testing.assert_allclose(poses[0], [0.0, 0.1, np.pi / 2], atol=1e-12)


def test_style_guide_example_dx1_dtheta_half_pi():
    poses = np.zeros((2, 3))
    sample_motion_assignment(poses, ZERO, np.array([1.0, 0.0, np.pi / 2]), np.zeros(3), np.random.default_rng(0))
    np.testing.assert_allclose(poses, [[1.0, 0.0, np.pi / 2]] * 2, atol=1e-12)


def test_driving_backwards_gives_negative_dr():
    dr, dth = odometry_step(np.array([1.0, 1.0, 0.0]), np.array([0.7, 1.0, 0.0]))
    assert dr == pytest.approx(-0.3) and dth == 0.0
    poses = np.array([[0.0, 0.0, np.pi]])
    sample_motion_assignment(poses, np.array([1.0, 1.0, 0.0]), np.array([0.7, 1.0, 0.0]),
                             np.zeros(3), np.random.default_rng(0))
    np.testing.assert_allclose(poses[0, :2], [0.3, 0.0], atol=1e-12)


def test_noise_has_the_configured_spread_and_is_seeded():
    poses = np.zeros((20000, 3))
    sample_motion_assignment(poses, ZERO, ZERO, np.array([0.1, 0.2, 0.05]), np.random.default_rng(1))
    np.testing.assert_allclose(poses.std(axis=0), [0.1, 0.2, 0.05], rtol=0.03)
    again = np.zeros((20000, 3))
    sample_motion_assignment(again, ZERO, ZERO, np.array([0.1, 0.2, 0.05]), np.random.default_rng(1))
    assert np.array_equal(poses, again)


def test_odometry_model_reproduces_the_delta_forward_and_backward():
    start = np.array([1.0, 2.0, 0.3])
    for end in (np.array([1.5, 2.4, 0.9]), compose(start, [-0.4, 0.05, -0.2])):
        poses = np.array([[-3.0, 1.0, -1.0]])
        sample_motion_odometry(poses, start, end, (0.1, 0.2, 0.1, 0.2), False, np.random.default_rng(0))
        np.testing.assert_allclose(relative([-3.0, 1.0, -1.0], poses[0]), relative(start, end), atol=1e-12)


def test_odometry_std_hand_computed():
    # 0.5 m straight ahead, then a 0.2 rad turn: rot1 = 0, trans = 0.5, rot2 = 0.2
    alphas = (0.1, 0.02, 0.05, 0.1)                    # srr, srt, str, stt
    std = odometry_std(np.zeros(3), np.array([0.5, 0.0, 0.2]), alphas)
    s_rot1 = 0.1 * 0.0 + 0.05 * 0.5                     # 0.025 rad
    s_trans = 0.1 * 0.5 + 0.02 * (0.0 + 0.2)            # 0.054 m
    s_rot2 = 0.1 * 0.2 + 0.05 * 0.5                     # 0.045 rad
    np.testing.assert_allclose(std, [s_trans, 0.5 * s_rot1, np.hypot(s_rot1, s_rot2)])
    np.testing.assert_array_equal(odometry_std(np.zeros(3), np.zeros(3), alphas), np.zeros(3))


@pytest.mark.parametrize("delta", [(1.0, 0.0, np.pi / 2), (-0.5, 0.0, 0.2), (0.3, -0.4, -1.0), (0.0, 0.0, 0.7)])
def test_odometry_model_without_noise_reproduces_the_odometry_delta(delta):
    rng = np.random.default_rng(0)
    prev = np.array([2.0, -1.0, 0.8])
    c, s = np.cos(prev[2]), np.sin(prev[2])
    odom = np.array([prev[0] + c * delta[0] - s * delta[1], prev[1] + s * delta[0] + c * delta[1],
                     prev[2] + delta[2]])
    poses = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, np.pi / 2]])
    sample_motion_odometry(poses, prev, odom, (0.1, 0.2, 0.1, 0.2), False, rng)
    # each particle moves by the same robot-frame delta from its own pose
    np.testing.assert_allclose(poses[0], [delta[0], delta[1], wrap_angle(delta[2])], atol=1e-12)
    np.testing.assert_allclose(poses[1], [1.0 - delta[1], 1.0 + delta[0], wrap_angle(np.pi / 2 + delta[2])],
                               atol=1e-12)


def test_odometry_model_noise_scales_with_motion():
    rng = np.random.default_rng(0)
    poses = np.zeros((4000, 3))
    sample_motion_odometry(poses, np.zeros(3), np.array([1.0, 0.0, 0.0]), (0.1, 0.0, 0.0, 0.0), True, rng)
    assert poses[:, 0].mean() == pytest.approx(1.0, abs=0.01)
    assert poses[:, 0].std() == pytest.approx(0.1, rel=0.05)
    assert np.abs(poses[:, 2]).max() == 0.0


def test_step_sigmas_hand_computed():
    # alphas (srr, srt, str, stt) = (0.1, 0.2, 0.3, 0.4); rot1 = -0.5, trans = 2, rot2 = 0.25
    s_rot1, s_trans, s_rot2 = step_sigmas(-0.5, 2.0, 0.25, (0.1, 0.2, 0.3, 0.4))
    assert s_rot1 == pytest.approx(0.4 * 0.5 + 0.3 * 2.0)            # 0.8
    assert s_trans == pytest.approx(0.1 * 2.0 + 0.2 * (0.5 + 0.25))  # 0.35
    assert s_rot2 == pytest.approx(0.4 * 0.25 + 0.3 * 2.0)           # 0.7
    arrays = step_sigmas(np.array([-0.5, 0.0]), np.array([2.0, -1.0]), np.array([0.25, 0.0]), (0.1, 0.2, 0.3, 0.4))
    np.testing.assert_allclose(arrays[1], [0.35, 0.1])                  # reversing counts |trans|


def test_reversing_odometry_turns_less_and_travels_backwards():
    # 1 m straight back: rot1 = 0 (not pi) and trans = -1, so the noise does not see a half turn
    std = odometry_std(np.zeros(3), np.array([-1.0, 0.0, 0.0]), (0.1, 0.0, 0.0, 1.0))
    np.testing.assert_allclose(std, [0.1, 0.0, 0.0], atol=1e-12)
    poses = np.array([[0.0, 0.0, np.pi / 2]])
    sample_motion_odometry(poses, np.zeros(3), np.array([-1.0, 0.0, 0.0]), (0.1, 0.2, 0.1, 0.2), False,
                           np.random.default_rng(0))
    np.testing.assert_allclose(poses[0], [0.0, -1.0, np.pi / 2], atol=1e-12)
