"""The two bag readers, rosbags and ROS's rosbag API (ROS Noetic's), read the same
records from the same bags, and the offline tool gives the same results through either."""
from __future__ import annotations

import sys

import numpy as np
import pytest

from bench.common import data_path
from fastslam import offline
from fastslam.io.bag_reader import read_bag
from fastslam.io.trajectory_files import read_trajectory

pytestmark = pytest.mark.ros   # ROS's rosbag is Debian's (Python 3.11) here


def _same_records(a, b):
    assert (a.scan_topic, a.odom_topic, a.topics, a.mount) == (b.scan_topic, b.odom_topic, b.topics, b.mount)
    assert a.odoms == b.odoms and a.reference == b.reference        # every stamp and pose bit for bit
    assert len(a.scans) == len(b.scans)
    for x, y in zip(a.scans, b.scans):
        assert (x.t, x.angle_min, x.angle_increment, x.range_min, x.range_max, x.frame_id) == \
               (y.t, y.angle_min, y.angle_increment, y.range_min, y.range_max, y.frame_id)
        assert x.ranges.dtype == y.ranges.dtype and x.ranges.tobytes() == y.ranges.tobytes()


@pytest.mark.parametrize("name", ["mit-csail.bag", "aces.bag"])
def test_same_records_from_the_development_bags(name):
    path = data_path(name)
    assert path.is_file(), f"{path} is missing: shared/data must lie beside the repository"
    a, b = read_bag(path, reader="rosbags"), read_bag(path, reader="rosbag")
    assert (a.reader, b.reader) == ("rosbags", "rosbag") and len(a.scans) > 1000
    _same_records(a, b)


def test_offline_tool_without_rosbags_reads_through_rosbag_with_the_same_results(tmp_path, monkeypatch):
    bag = data_path("mit-csail.bag")
    args = [str(bag), "--seed", "0", "--set", "particles=5", "--quiet"]
    assert offline.main([*args, "--out", str(tmp_path / "a")]) == 0
    monkeypatch.setitem(sys.modules, "rosbags", None)      # as on ROS Noetic: rosbags cannot be imported
    assert offline.main([*args, "--out", str(tmp_path / "b")]) == 0
    for name in ("trajectory.txt", "trajectory_scans.txt", "live_poses.txt", "map.pgm"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    t, poses = read_trajectory(tmp_path / "b" / "trajectory.txt")
    assert len(t) > 100 and np.all(np.isfinite(poses))
