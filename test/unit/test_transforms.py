"""3D rigid transforms reduced to a planar laser mount."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastslam.transforms import StaticTransform, mount_from_matrix, quaternion_matrix, transform_matrix


def test_planar_transforms_as_quaternions():
    t = StaticTransform.planar("base", "laser", 0.1, -0.2, 0.5, z=0.3)
    assert t.translation == (0.1, -0.2, 0.3)
    assert t.rotation == pytest.approx((0.0, 0.0, math.sin(0.25), math.cos(0.25)))
    down = StaticTransform.planar("base", "laser", yaw=0.5, upside_down=True)
    assert down.rotation == pytest.approx((math.cos(0.25), math.sin(0.25), 0.0, 0.0))   # Rz(0.5) Rx(pi)
    assert StaticTransform("a", "b").rotation == (0.0, 0.0, 0.0, 1.0)


def test_quaternion_matrices_by_hand():
    np.testing.assert_allclose(quaternion_matrix((0.0, 0.0, 2.0, 0.0)), np.diag([-1.0, -1.0, 1.0]),
                               atol=1e-12)   # not unit: a half turn about z
    np.testing.assert_allclose(quaternion_matrix((1.0, 0.0, 0.0, 0.0)), np.diag([1.0, -1.0, -1.0]), atol=1e-12)
    s = math.sqrt(0.5)
    np.testing.assert_allclose(quaternion_matrix((0.0, 0.0, s, s)), [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)


def test_transform_matrix_moves_points():
    s = math.sqrt(0.5)
    m = transform_matrix((1.0, 2.0, 3.0), (0.0, 0.0, s, s))       # a quarter turn, then the shift
    np.testing.assert_allclose(m @ [1.0, 0.0, 0.0, 1.0], [1.0, 3.0, 3.0, 1.0], atol=1e-12)
    np.testing.assert_array_equal(m[3], [0.0, 0.0, 0.0, 1.0])


@pytest.mark.parametrize("upside_down", [False, True])
def test_mount_from_a_matrix(upside_down):
    t = StaticTransform.planar("base_link", "laser", 0.2, 0.05, 0.3, z=0.17, upside_down=upside_down)
    m = mount_from_matrix(transform_matrix(t.translation, t.rotation), "base_link", "laser")
    assert (m.x, m.y, m.yaw) == pytest.approx((0.2, 0.05, 0.3), abs=1e-12)
    assert m.upside_down == upside_down and m.found
    assert not mount_from_matrix(np.eye(4), "b", "l", found=False).found

