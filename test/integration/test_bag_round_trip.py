"""ROS 1 bags written by fastslam.io.bag_writer and read back by fastslam.io.bag_reader:
records, topics, and the laser mount from /tf_static and /tf; each test with both readers
(rosbags, and ROS's rosbag API as on ROS Noetic)."""
from __future__ import annotations

import math

import numpy as np
import pytest

from fastslam.filter.scan import Scan
from fastslam.geometry import wrap_angle
from fastslam.io import bag_reader
from fastslam.io.bag_reader import read_bag
from fastslam.io.bag_writer import BagWriter, write_bag
from fastslam.io.records import BagError, OdomRecord, ScanRecord
from fastslam.transforms import LaserMount, StaticTransform


@pytest.fixture(autouse=True, params=["rosbags", pytest.param("rosbag", marks=pytest.mark.ros)])
def reader(request, monkeypatch):
    """Every read_bag of a test goes through this library (read_bag's default choice)."""
    monkeypatch.setattr(bag_reader, "READERS", (request.param,))
    return request.param


def scans_and_odoms(rng: np.random.Generator, n: int = 5, frame: str = "laser"):
    scans, odoms = [], []
    for k in range(n):
        ranges = rng.uniform(0.1, 10.0, 7).astype(np.float32)
        ranges[k % 7] = np.inf
        scans.append(ScanRecord(10.0 + 0.2 * k, ranges, -1.5, 0.5, 0.12, 12.0, frame))
        odoms.append(OdomRecord(10.0 + 0.2 * k, 0.1 * k, -0.05 * k, 0.3 * k - 0.5))
    return scans, odoms


def test_round_trip_of_scans_and_odometry(tmp_path):
    scans, odoms = scans_and_odoms(np.random.default_rng(0))
    data = read_bag(write_bag(tmp_path / "a.bag", scans, odoms))
    assert (data.scan_topic, data.odom_topic) == ("/scan", "/odom")
    assert len(data.scans) == 5 and len(data.odoms) == 5
    for a, b in zip(scans, data.scans):
        np.testing.assert_array_equal(b.ranges, a.ranges)          # inf survives
        assert b.t == pytest.approx(a.t, abs=1e-9) and b.frame_id == "laser"
        assert (b.angle_min, b.angle_increment, b.range_max) == (-1.5, 0.5, 12.0)
        assert b.range_min == pytest.approx(0.12)                  # float32 field in the message
    for a, b in zip(odoms, data.odoms):
        assert (b.x, b.y) == (a.x, a.y) and b.yaw == pytest.approx(a.yaw, abs=1e-12)
        assert (b.frame_id, b.child_frame_id) == ("odom", "base_link")
    kinds = [type(r).__name__ for r in data.records()]
    assert kinds == ["OdomRecord", "ScanRecord"] * 5                # odometry first at equal stamps
    np.testing.assert_allclose(data.odom_poses()[:, 1], [o.x for o in odoms])
    # no /tf_static: the laser is assumed at the base origin, and says so
    assert data.mount == LaserMount(found=False)


def test_topics_are_found_automatically_or_named(tmp_path):
    scans, odoms = scans_and_odoms(np.random.default_rng(1))
    path = tmp_path / "two.bag"
    with BagWriter(path, scan_topic="/front/scan", odom_topic="/wheel/odom") as w:
        for s, o in zip(scans, odoms):
            w.odom(o)
            w.scan(s)
            w.scan(s, topic="/rear/scan")
    with pytest.raises(BagError) as err:
        read_bag(path)
    message = str(err.value)
    assert "2 sensor_msgs/msg/LaserScan topics" in message
    assert "/front/scan [sensor_msgs/msg/LaserScan]" in message and "/rear/scan" in message
    assert "/wheel/odom [nav_msgs/msg/Odometry]" in message
    data = read_bag(path, scan_topic="/rear/scan")
    assert data.scan_topic == "/rear/scan" and data.odom_topic == "/wheel/odom" and len(data.scans) == 5
    with pytest.raises(BagError, match="scan topic '/nope'"):
        read_bag(path, scan_topic="/nope")


def test_missing_bag_and_existing_output(tmp_path):
    with pytest.raises(BagError, match="no bag"):
        read_bag(tmp_path / "none.bag")
    (tmp_path / "x.bag").write_bytes(b"")
    with pytest.raises(BagError, match="exists"):
        write_bag(tmp_path / "x.bag", [], [])
    with pytest.raises(BagError, match="cannot read bag"):
        read_bag(tmp_path / "x.bag")


def test_mount_chain_with_yaw_and_upside_down_laser(tmp_path):
    scans, odoms = scans_and_odoms(np.random.default_rng(2))
    chain = [StaticTransform.planar("base_link", "plate", 0.2, 0.1, 0.5, z=0.3),
             StaticTransform.planar("plate", "laser", 0.1, 0.0, math.pi / 2, upside_down=True)]
    mount = read_bag(write_bag(tmp_path / "m.bag", scans, odoms, static_transforms=chain)).mount
    # x = 0.2 + 0.1 cos 0.5, y = 0.1 + 0.1 sin 0.5, yaw = 0.5 + pi/2, z axis down
    assert mount.x == pytest.approx(0.2 + 0.1 * math.cos(0.5), abs=1e-12)
    assert mount.y == pytest.approx(0.1 + 0.1 * math.sin(0.5), abs=1e-12)
    assert mount.yaw == pytest.approx(0.5 + math.pi / 2, abs=1e-12)
    assert mount.upside_down and mount.found
    # beams mirror: laser angles -1.5, -1.0 point at yaw + 1.5, yaw + 1.0 in the base frame
    scan = Scan.from_laser(np.ones(2), -1.5, 0.5, 0.1, 5.0, mount=(mount.x, mount.y, mount.yaw),
                           upside_down=mount.upside_down)
    np.testing.assert_allclose(scan.angles, wrap_angle(np.array([mount.yaw + 1.5, mount.yaw + 1.0])))


def test_upright_yawed_laser(tmp_path):
    scans, odoms = scans_and_odoms(np.random.default_rng(3))
    tf = [StaticTransform.planar("base_link", "laser", -0.05, 0.0, math.pi)]
    mount = read_bag(write_bag(tmp_path / "u.bag", scans, odoms, static_transforms=tf)).mount
    assert (mount.x, mount.y) == pytest.approx((-0.05, 0.0), abs=1e-12)
    assert abs(mount.yaw) == pytest.approx(math.pi, abs=1e-12) and not mount.upside_down


def test_mount_from_an_inverted_edge_and_from_tf(tmp_path):
    scans, odoms = scans_and_odoms(np.random.default_rng(4))
    path = tmp_path / "inv.bag"
    with BagWriter(path) as w:
        # the laser is the parent here: base_link sits 0.3 m behind it
        w.static([StaticTransform.planar("laser", "base_link", -0.3, 0.0, 0.0)], t=10.0)
        for s, o in zip(scans, odoms):
            w.odom(o)
            w.scan(s)
    mount = read_bag(path).mount
    assert (mount.x, mount.y, mount.yaw, mount.found) == (pytest.approx(0.3), pytest.approx(0.0), 0.0, True)

    path = tmp_path / "tf1.bag"
    with BagWriter(path) as w:
        for s, o in zip(scans, odoms):
            w.odom(o)
            w.tf([StaticTransform.planar("base_link", "laser", 0.15, 0.0, 0.0)], t=o.t)  # tf1 style
            w.scan(s)
    mount = read_bag(path).mount
    assert mount.x == pytest.approx(0.15) and mount.found


def test_laser_in_the_base_frame(tmp_path):
    scans, odoms = scans_and_odoms(np.random.default_rng(5), frame="base_link")
    mount = read_bag(write_bag(tmp_path / "b.bag", scans, odoms)).mount
    assert mount == LaserMount(laser_frame="base_link", found=True)


def test_reference_topic_is_read_apart_from_the_odometry(tmp_path):
    scans, odoms = scans_and_odoms(np.random.default_rng(6))
    path = tmp_path / "gt.bag"
    truth = [OdomRecord(o.t, o.x + 1.0, o.y - 2.0, o.yaw, child_frame_id="base_link", frame_id="world")
             for o in odoms]
    with BagWriter(path) as w:
        for s, o, g in zip(scans, odoms, truth):
            w.odom(o)
            w.odom(g, topic="/ground_truth")     # no tf for it
            w.scan(s)
    data = read_bag(path)
    assert data.odom_topic == "/odom" and len(data.reference) == 5 and len(data.odoms) == 5
    for got, want in [*zip(data.reference, truth), *zip(data.odoms, odoms)]:
        assert (got.t, got.x, got.y, got.frame_id) == (want.t, want.x, want.y, want.frame_id)
        assert got.yaw == pytest.approx(want.yaw, abs=1e-12)      # through a quaternion
    assert data.mount == LaserMount(found=False)
