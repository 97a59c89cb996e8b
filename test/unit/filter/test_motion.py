import numpy as np
import pytest

from fastslam.filter.motion import odometry_step, sample_motion_assignment, sample_motion_odometry
from fastslam.geometry import circular_mean, compose, inverse, relative, wrap_angle

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


def test_wrap_and_circular_mean():
    np.testing.assert_allclose(wrap_angle([np.pi, -np.pi, 3 * np.pi / 2, 0.1]), [-np.pi, -np.pi, -np.pi / 2, 0.1])
    eps = 0.01
    assert abs(abs(circular_mean([np.pi - eps, -np.pi + eps])) - np.pi) < 1e-9


def test_compose_inverse_round_trip():
    a = np.array([1.0, -2.0, 2.5])
    np.testing.assert_allclose(compose(a, inverse(a)), ZERO, atol=1e-12)
    np.testing.assert_allclose(compose([1, 0, np.pi / 2], [1, 0, 0]), [1, 1, np.pi / 2], atol=1e-12)


def test_odometry_std_hand_computed():
    from fastslam.filter.motion import odometry_std

    # 0.5 m straight ahead, then a 0.2 rad turn: rot1 = 0, trans = 0.5, rot2 = 0.2
    alphas = (0.1, 0.02, 0.05, 0.1)                    # srr, srt, str, stt
    std = odometry_std(np.zeros(3), np.array([0.5, 0.0, 0.2]), alphas)
    s_rot1 = 0.1 * 0.0 + 0.05 * 0.5                     # 0.025 rad
    s_trans = 0.1 * 0.5 + 0.02 * (0.0 + 0.2)            # 0.054 m
    s_rot2 = 0.1 * 0.2 + 0.05 * 0.5                     # 0.045 rad
    np.testing.assert_allclose(std, [s_trans, 0.5 * s_rot1, np.hypot(s_rot1, s_rot2)])
    np.testing.assert_array_equal(odometry_std(np.zeros(3), np.zeros(3), alphas), np.zeros(3))
