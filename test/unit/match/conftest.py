"""A filter that mapped the pillar room with exact odometry (test_matcher, test_refine)."""
from __future__ import annotations

from typing import Callable

import numpy as np
import pytest

from fastslam.config import SlamConfig
from fastslam.filter.scan import Scan
from fastslam.filter.slam import FastSlam

ANGLES = np.radians(np.arange(360.0))


@pytest.fixture(scope="session")
def scan360(room_scan) -> Callable[[np.ndarray], Scan]:
    """scan360(pose) -> the exact 360-beam scan of the pillar room from pose."""
    return lambda pose: room_scan(pose, ANGLES)


@pytest.fixture
def mapped_room(scan360) -> Callable[..., tuple[FastSlam, np.ndarray]]:
    """mapped_room(particles=3) -> (filter, last pose): maps built with exact odometry along
    8 poses near the room's centre (5 m square + pillar), no motion noise."""
    def build(particles: int = 3) -> tuple[FastSlam, np.ndarray]:
        cfg = SlamConfig(particles=particles, seed=0, toggle_noise=0, proposal="odometry", max_range=3.5,
                         motion_model="odometry",
                         match_sigma_xy=0.0, match_sigma_theta=0.0, match_xy_range=0.3, match_theta_range=0.15)
        slam = FastSlam(cfg)
        pose = np.zeros(3)
        for i in range(8):
            pose = np.array([-0.3 + 0.05 * i, 0.1 * np.sin(i), 0.1 * i])
            slam.step(pose, scan360(pose))
        return slam, pose

    return build
