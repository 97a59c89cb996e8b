"""The run report's evaluation and files (the recorder itself subscribes: test/ros/)."""
from __future__ import annotations

import json

import numpy as np
import pytest
import rospy

from assign5.convert import occupancy_msgs
from assign5.run_report import evaluate, write_outputs
from fastslam.io.map_files import load_map


@pytest.fixture
def wall_world(tmp_path):
    """A wall at x = 2 (world frame); the robot spawned at (1, 0) facing +x."""
    path = tmp_path / "wall.yaml"
    path.write_text("segments: [[[2.0, -1.0], [2.0, 1.0]]]\nspawn: [1.0, 0.0, 0]\n")
    return str(path)


def grid_msg():
    occ = np.zeros((40, 40), dtype=np.int8)
    occ[:, 30] = 100                                   # x in [1.0, 1.05) of the map frame: the wall
    return occupancy_msgs(occ, 0.05, np.array([-0.5, -1.0]), "map", rospy.Time(0))[0]


def test_evaluate_in_the_frame_of_the_spawn(wall_world):
    truth_world = np.array([[0.0, 1.0, 0.0, 0.0], [1.0, 1.5, 0.0, 0.0]])       # world frame
    traj = np.array([[0.0, 0.0, 0.3, 0.0], [1.0, 0.5, -0.4, 0.0]])             # map frame
    metrics, occ, truth = evaluate(wall_world, truth_world, traj, grid_msg(), [10.0, 30.0, 20.0])
    np.testing.assert_allclose(truth, [[0.0, 0.0, 0.0, 0.0], [1.0, 0.5, 0.0, 0.0]])
    assert occ.shape == (40, 40) and occ[5, 30] == 100
    assert metrics["trajectory_rms_m"] == pytest.approx(np.sqrt((0.09 + 0.16) / 2))
    assert metrics["boundary_recall"] == 1.0 and metrics["spurious_fraction"] == 0.0
    assert metrics["processed_scans"] == 2 and metrics["ms_per_update_median"] == 20.0
    assert metrics["ms_per_update_p95"] == pytest.approx(29.0)
    assert evaluate(wall_world, truth_world, traj, grid_msg(), [])[0]["ms_per_update_median"] is None


def test_outputs(wall_world, tmp_path):
    truth_world = np.array([[0.0, 1.0, 0.0, 0.0], [1.0, 1.5, 0.0, 0.0]])
    traj = np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 0.5, 0.0, 0.0]])
    grid = grid_msg()
    metrics, occ, truth = evaluate(wall_world, truth_world, traj, grid, [5.0])
    write_outputs(tmp_path / "out", metrics, occ, grid, truth, traj)
    assert json.loads((tmp_path / "out" / "metrics.json").read_text()) == metrics
    back, res, origin = load_map(tmp_path / "out" / "map.yaml")
    np.testing.assert_array_equal(back, occ)
    assert res == 0.05 and origin == (-0.5, -1.0, 0.0)
    assert (tmp_path / "out" / "map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
