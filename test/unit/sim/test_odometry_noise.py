"""Odometry re-integration and its noise model."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastslam.geometry import wrap_angle
from fastslam.sim.odometry_noise import (
    OdomNoise,
    integrate_deltas,
    noise_sigmas,
    noisy_odometry,
    odometry_deltas,
    perturb_deltas,
)


def random_walk(rng: np.random.Generator, n: int = 200) -> np.ndarray:
    steps = np.column_stack([rng.uniform(-0.2, 1.0, n), rng.uniform(-0.1, 0.1, n), rng.uniform(-0.5, 0.5, n)])
    poses = np.zeros((n + 1, 3))
    for k, (f, l, dth) in enumerate(steps):
        x, y, th = poses[k]
        poses[k + 1] = (x + f * math.cos(th) - l * math.sin(th), y + f * math.sin(th) + l * math.cos(th),
                        wrap_angle(th + dth))
    return poses


def test_deltas_of_a_quarter_turn_step():
    d = odometry_deltas([[0, 0, 0], [1, 1, math.pi / 2]])
    np.testing.assert_allclose(d, [[math.pi / 4, math.sqrt(2), math.pi / 4]], atol=1e-12)


def test_backward_step_is_a_negative_translation():
    d = odometry_deltas([[0, 0, 0.1], [-math.cos(0.1), -math.sin(0.1), 0.1]])
    np.testing.assert_allclose(d, [[0.0, -1.0, 0.0]], atol=1e-12)


def test_turn_on_the_spot_has_zero_rot1():
    np.testing.assert_allclose(odometry_deltas([[2, 3, 3.0], [2, 3, -3.0]]), [[0, 0, 2 * math.pi - 6.0]])


def test_level_zero_reproduces_the_poses():
    poses = random_walk(np.random.default_rng(0))
    odo = noisy_odometry(poses, 0.0, np.random.default_rng(5))
    np.testing.assert_allclose(odo[:, :2], poses[:, :2], atol=1e-9)
    np.testing.assert_allclose(wrap_angle(odo[:, 2] - poses[:, 2]), 0.0, atol=1e-9)


def test_integrate_inverts_deltas_from_any_start():
    poses = random_walk(np.random.default_rng(1), 50)
    back = integrate_deltas(poses[0], odometry_deltas(poses))
    np.testing.assert_allclose(back[:, :2], poses[:, :2], atol=1e-9)


def test_noise_is_deterministic_per_seed():
    poses = random_walk(np.random.default_rng(2))
    a = noisy_odometry(poses, 1.0, np.random.default_rng(7))
    b = noisy_odometry(poses, 1.0, np.random.default_rng(7))
    c = noisy_odometry(poses, 1.0, np.random.default_rng(8))
    np.testing.assert_array_equal(a, b)
    assert np.abs(a[-1, :2] - c[-1, :2]).max() > 1e-3
    np.testing.assert_array_equal(a[0], poses[0])     # dead reckoning starts at the first pose


def test_sigmas_hand_computed():
    # level 2, rot1 0.2, trans 0.5, rot2 -0.1; A = (0.1, 0.1, 0.1, 0.05)
    s = noise_sigmas([[0.2, 0.5, -0.1]], 2.0)
    np.testing.assert_allclose(s, [[2 * (0.02 + 0.05), 2 * (0.05 + 0.05 * 0.3), 2 * (0.01 + 0.05)]])


def test_short_step_counts_as_a_turn_on_the_spot():
    # 5 cm < MIN_TRANS: (|rot1|, |rot2|) -> (0, |rot1 + rot2|) = (0, 0.5)
    s = noise_sigmas([[0.3, 0.05, 0.2]], 1.0)
    np.testing.assert_allclose(s, [[0.1 * 0.05, 0.1 * 0.05 + 0.05 * 0.5, 0.1 * 0.5 + 0.1 * 0.05]])


def test_custom_coefficients_scale_linearly():
    s = noise_sigmas([[0.0, 1.0, 0.0]], 1.0, OdomNoise(0.0, 0.3, 0.2, 0.0))
    np.testing.assert_allclose(s, [[0.3, 0.2, 0.3]])


def test_empirical_spread_matches_the_model():
    d = np.tile([[0.2, 0.5, -0.1]], (20000, 1))
    noisy = perturb_deltas(d, 1.0, np.random.default_rng(3))
    np.testing.assert_allclose(noisy.std(axis=0), noise_sigmas(d[:1], 1.0)[0], rtol=0.03)
    np.testing.assert_allclose(noisy.mean(axis=0), d[0], atol=0.003)


def test_negative_level_is_rejected():
    with pytest.raises(ValueError, match="level"):
        noisy_odometry(np.zeros((3, 3)), -1.0, np.random.default_rng(0))
