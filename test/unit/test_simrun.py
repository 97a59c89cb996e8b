"""fastslam.simrun: a short simulated run fed straight into the filter (the assignment's
checks over whole routes: test/integration/test_sim_slam.py)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastslam import simrun
from fastslam.config import SlamConfig


def test_world_names_and_paths(worlds_dir, tmp_path):
    assert simrun.world_path("room") == simrun.WORLDS / "room.yaml"
    assert simrun.WORLDS.resolve() == worlds_dir.resolve()
    own = tmp_path / "mine.yaml"
    own.write_text("circles: [[5, 5, 1]]\n")
    assert simrun.world_path(str(own)) == own


@pytest.fixture(scope="module")
def two_seconds() -> simrun.SimRun:
    """2 s of the room's route: perfect odometry, exact ranges, 2 particles without noise."""
    return simrun.run("room", SlamConfig(particles=2, seed=0, toggle_noise=0),
                      sim={"odom_noise": False, "range_noise": 0.0}, max_time=2.0, record=True)


def test_rates_and_records(two_seconds):
    run = two_seconds
    # 60 physics ticks a second: odometry at 30 Hz (60 rows), scans at 5 Hz (10 updates)
    assert run.truth.shape == run.odom.shape == (60, 4) and run.updates == 10
    np.testing.assert_allclose(run.truth[:, 0], np.arange(1, 61) / 30)
    assert len(run.scans) == 10 and len(run.odoms) == 60
    assert run.scans[0].frame_id == "base_scan" and run.odoms[0].child_frame_id == "base_footprint"
    assert run.scans[0].ranges.dtype == np.float32 and len(run.scans[0].ranges) == 360
    assert run.scans[0].angle_increment == pytest.approx(math.radians(1.0))
    assert run.mount == (-0.032, 0.0, 0.0)


def test_truth_is_in_the_map_frame_and_perfect_odometry_equals_it(two_seconds):
    run = two_seconds
    np.testing.assert_array_equal(run.odom, run.truth)
    assert run.truth[-1, 1] > 0.3                       # the robot drove off along its route
    last = run.odoms[-1]
    np.testing.assert_allclose([last.x, last.y, last.yaw], run.truth[-1, 1:])


def test_metrics(two_seconds):
    m = two_seconds.metrics()
    assert m["updates"] == 10 and m["dead_reckoning_rms_m"] == 0.0
    assert m["trajectory_rms_m"] < 0.005                # noise-free: the filter follows the odometry
    assert m["spurious_fraction"] == 0.0 and m["boundary_recall"] > 0.8
    assert m["ms_per_update"] > 0.0
    assert set(m) >= {"trajectory_max_m", "final_error_m", "observed_fraction", "occupied_cells"}
