"""The bag reader's pure parts: choosing topics, the laser mount from a chain of
transforms, merging scans and odometry in time order (whole bags: test/integration)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastslam.io.bag_reader import BagData, _pick, laser_mount
from fastslam.io.records import BagError, OdomRecord, ScanRecord
from fastslam.transforms import LaserMount, StaticTransform, transform_matrix


def edge(t: StaticTransform) -> tuple[tuple[str, str], np.ndarray]:
    return (t.parent, t.child), transform_matrix(t.translation, t.rotation)


def test_topic_choice_messages():
    topics = {"/odom": "nav_msgs/msg/Odometry", "/imu": "sensor_msgs/msg/Imu"}
    expected = r"no sensor_msgs/msg/LaserScan topic in the bag; topics: /imu \[sensor_msgs/msg/Imu\]"
    with pytest.raises(BagError, match=expected):
        _pick(topics, "sensor_msgs/msg/LaserScan", None, "scan")
    assert _pick(topics, "nav_msgs/msg/Odometry", None, "odometry") == "/odom"


def test_conventional_name_wins_when_a_type_has_several_topics():
    topics = {"/odom": "nav_msgs/msg/Odometry", "/ground_truth": "nav_msgs/msg/Odometry",
              "/scan": "sensor_msgs/msg/LaserScan"}
    assert _pick(topics, "nav_msgs/msg/Odometry", None, "odometry") == "/odom"
    del topics["/odom"]
    topics["/wheel_odom"] = "nav_msgs/msg/Odometry"
    with pytest.raises(BagError, match="2 nav_msgs/msg/Odometry topics"):
        _pick(topics, "nav_msgs/msg/Odometry", None, "odometry")


def test_a_named_topic_must_have_the_type():
    topics = {"/scan": "sensor_msgs/msg/LaserScan", "/odom": "nav_msgs/msg/Odometry"}
    assert _pick(topics, "sensor_msgs/msg/LaserScan", "/scan", "scan") == "/scan"
    with pytest.raises(BagError, match="scan topic '/odom' with type sensor_msgs/msg/LaserScan not in the bag"):
        _pick(topics, "sensor_msgs/msg/LaserScan", "/odom", "scan")
    with pytest.raises(BagError, match=r"topics: \(none\)"):
        _pick({}, "sensor_msgs/msg/LaserScan", None, "scan")


def test_mount_through_a_chain_of_yaws():
    edges = dict([edge(StaticTransform.planar("base_link", "plate", 0.2, 0.1, 0.5, z=0.3)),
                  edge(StaticTransform.planar("plate", "laser", 0.1, 0.0, math.pi / 2))])
    m = laser_mount(edges, "base_link", "laser")
    assert m.x == pytest.approx(0.2 + 0.1 * math.cos(0.5), abs=1e-12)
    assert m.y == pytest.approx(0.1 + 0.1 * math.sin(0.5), abs=1e-12)
    assert m.yaw == pytest.approx(0.5 + math.pi / 2, abs=1e-12)
    assert m.found and not m.upside_down and (m.base_frame, m.laser_frame) == ("base_link", "laser")


def test_mount_up_and_down_the_tree_and_upside_down():
    # base_footprint -> base_link (0.1 ahead), base_link -> laser_link (upside down),
    # and the laser stored as the parent of a sibling frame: edges are used both ways
    edges = dict([edge(StaticTransform.planar("base_footprint", "base_link", 0.1)),
                  edge(StaticTransform.planar("base_link", "laser", -0.05, 0.02, 0.0, upside_down=True)),
                  edge(StaticTransform.planar("laser", "camera", 0.3))])
    m = laser_mount(edges, "base_footprint", "laser")
    assert (m.x, m.y) == pytest.approx((0.05, 0.02), abs=1e-12) and m.upside_down and m.found
    # against the direction of every edge: the camera sits at (0.35, 0.02), z down, so the
    # base is at -(0.35, -0.02) in the camera's frame (its y axis is flipped too)
    back = laser_mount(edges, "camera", "base_footprint")
    assert (back.x, back.y) == pytest.approx((-0.35, 0.02), abs=1e-12) and back.upside_down


def test_mount_without_a_chain_is_assumed_at_the_origin():
    edges = dict([edge(StaticTransform.planar("odom", "base_link", 3.0))])
    assert laser_mount(edges, "base_link", "laser") == LaserMount(found=False)
    assert laser_mount({}, "base_scan", "base_scan") == LaserMount(base_frame="base_scan", laser_frame="base_scan")


def test_records_merge_in_time_order_odometry_first():
    scans = [ScanRecord(t, np.ones(3, np.float32), 0.0, 0.1, 0.1, 5.0) for t in (1.0, 2.0)]
    odoms = [OdomRecord(t, x, 0.0, 0.1 * x) for t, x in ((0.5, 1.0), (1.0, 2.0), (3.0, 3.0))]
    data = BagData(scans=scans, odoms=odoms, mount=LaserMount(), scan_topic="/scan", odom_topic="/odom")
    assert [(type(r).__name__[0], r.t) for r in data.records()] == \
        [("O", 0.5), ("O", 1.0), ("S", 1.0), ("S", 2.0), ("O", 3.0)]
    np.testing.assert_allclose(data.odom_poses(), [[0.5, 1.0, 0.0, 0.1], [1.0, 2.0, 0.0, 0.2], [3.0, 3.0, 0.0, 0.3]])
    empty = BagData(scans=[], odoms=[], mount=LaserMount(), scan_topic="/scan", odom_topic="/odom")
    assert list(empty.records()) == [] and empty.odom_poses().shape == (0, 4)


def test_records_in_the_order_the_node_handles_them():
    # the node waits up to odom_wait for odometry stamped at or after a scan
    scans = [ScanRecord(t, np.ones(3, np.float32), 0.0, 0.1, 0.1, 5.0)
             for t in (1.0, 1.2, 2.0, 3.0, 3.05, 5.0, 5.5, 6.0)]
    odoms = [OdomRecord(t, 0.0, 0.0, 0.0) for t in (0.9, 1.05, 1.25, 1.5, 2.2, 3.08, 5.0, 5.3, 5.5, 5.55)]
    data = BagData(scans=scans, odoms=odoms, mount=LaserMount(), scan_topic="/scan", odom_topic="/odom")
    order = [(type(r).__name__[0], r.t) for r in data.records(0.1)]
    assert order == [("O", 0.9), ("O", 1.05), ("S", 1.0), ("O", 1.25), ("S", 1.2), ("O", 1.5),
                     ("S", 2.0), ("O", 2.2),                # the next odometry came 0.2 s later: not waited for
                     ("O", 3.08), ("S", 3.0), ("S", 3.05),  # two scans waiting for one message
                     ("O", 5.0), ("S", 5.0), ("O", 5.3),    # odometry of its own stamp: not waiting
                     ("O", 5.5), ("S", 5.5), ("O", 5.55),   # for the next, however soon
                     ("S", 6.0)]                            # the end of the bag
    assert [(type(r).__name__[0], r.t) for r in data.records()][:4] == [("O", 0.9), ("S", 1.0), ("O", 1.05),
                                                                       ("S", 1.2)]
