"""A loop in the pillar room with drifting odometry, run through the filter (test_slam,
test_history)."""
from __future__ import annotations

from typing import Callable

import numpy as np
import pytest

from fastslam.config import SlamConfig
from fastslam.filter.scan import Scan
from fastslam.filter.slam import FastSlam
from fastslam.geometry import compose, relative

ANGLES = np.radians(np.arange(360.0))


def square_path(steps: int = 120) -> np.ndarray:
    """True poses (T, 3): a loop inside the 5 m room, 5 cm and 1.5 degrees per step."""
    poses, p = [], np.array([-1.0, -1.0, 0.0])
    for i in range(steps):
        turn = np.radians(3.0) if (i // 30) % 2 == 1 and i % 30 < 30 else 0.0
        p = compose(p, [0.05, 0.0, turn])
        poses.append(p)
    return np.array(poses)


def drifting_odometry(truth: np.ndarray, scale: float = 1.02, yaw_drift: float = 0.002) -> np.ndarray:
    """Odometry that over-reads distance by 2 % and drifts 0.11 degrees a step."""
    odom = [np.zeros(3)]
    for a, b in zip(truth[:-1], truth[1:]):
        d = relative(a, b)
        odom.append(compose(odom[-1], [d[0] * scale, d[1] * scale, d[2] + yaw_drift]))
    return np.array(odom)


@pytest.fixture(scope="session")
def loop() -> Callable[..., np.ndarray]:
    """loop(steps) -> (T, 3) true poses of a loop in the pillar room."""
    return square_path


@pytest.fixture(scope="session")
def drifting() -> Callable[..., np.ndarray]:
    """drifting(truth) -> (T, 3) odometry 2 % long and 0.002 rad a step off."""
    return drifting_odometry


@pytest.fixture(scope="session")
def run_room(room_ranges) -> Callable[..., FastSlam]:
    """run_room(cfg, truth, odom, noise=0.01, seed=0) -> the filter after one scan per
    true pose (360 beams, Gaussian range noise seeded by seed), stamps 0.2 s apart."""
    def run(cfg: SlamConfig, truth: np.ndarray, odom: np.ndarray, noise: float = 0.01, seed: int = 0) -> FastSlam:
        rng = np.random.default_rng(seed)
        slam = FastSlam(cfg)
        for t, (pose, o) in enumerate(zip(truth, odom)):
            ranges = room_ranges(pose, ANGLES) + rng.normal(0, noise, 360)
            slam.step(o, Scan(ranges=ranges, angles=ANGLES, range_min=0.12, range_max=3.5, stamp=0.2 * t))
        return slam

    return run
