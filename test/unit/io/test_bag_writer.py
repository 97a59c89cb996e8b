"""The bag writer, read back with rosbags itself (not our reader): topics, types, stamps,
message fields, /tf per odometry message, latched /tf_static."""
from __future__ import annotations

import math

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.typesys import Stores, get_typestore

from fastslam.io.bag_writer import BagWriter, write_bag
from fastslam.io.records import BagError, OdomRecord, ScanRecord
from fastslam.transforms import StaticTransform


def read_raw(path):
    """[(topic, msgtype, time ns, message)] of every message by time, then topic (rosbags
    orders equal times by connection), and the connections by topic."""
    with AnyReader([path], default_typestore=get_typestore(Stores.ROS1_NOETIC)) as reader:
        out = [(c.topic, c.msgtype, t, reader.deserialize(raw, c.msgtype)) for c, t, raw in reader.messages()]
        return sorted(out, key=lambda m: (m[2], m[0])), {c.topic: c for c in reader.connections}


def test_messages_as_written(tmp_path):
    scans = [ScanRecord(10.0 + k, np.array([1.0, np.inf, 2.5], np.float32), -0.5, 0.25, 0.1, 8.0, "laser")
             for k in range(2)]
    odoms = [OdomRecord(10.0 + k, 1.0 + k, -2.0, 0.5, child_frame_id="base_footprint") for k in range(2)]
    path = write_bag(tmp_path / "w.bag", scans, odoms,
                     static_transforms=[StaticTransform.planar("base_footprint", "laser", 0.1, 0.0, math.pi)])
    msgs, conns = read_raw(path)
    assert [(topic, t) for topic, _, t, _ in msgs] == [
        ("/odom", 10_000_000_000), ("/scan", 10_000_000_000), ("/tf", 10_000_000_000),
        ("/tf_static", 10_000_000_000), ("/odom", 11_000_000_000), ("/scan", 11_000_000_000), ("/tf", 11_000_000_000)]
    assert conns["/tf_static"].ext.latching == 1 and not conns["/tf"].ext.latching
    scan = msgs[1][3]
    assert msgs[1][1] == "sensor_msgs/msg/LaserScan"
    np.testing.assert_array_equal(scan.ranges, [1.0, np.inf, 2.5])                 # no return stays inf
    assert (scan.angle_min, scan.angle_increment, scan.angle_max) == (-0.5, 0.25, 0.0)   # -0.5 + 2 * 0.25
    assert scan.range_min == pytest.approx(0.1) and scan.range_max == 8.0
    assert scan.header.frame_id == "laser" and (scan.header.stamp.sec, scan.header.stamp.nanosec) == (10, 0)
    assert msgs[5][3].header.seq == 1                                              # the second scan
    odom = msgs[4][3]
    assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_footprint")
    assert (odom.pose.pose.position.x, odom.pose.pose.position.y) == (2.0, -2.0)
    q = odom.pose.pose.orientation
    assert (q.x, q.y, q.z, q.w) == pytest.approx((0.0, 0.0, math.sin(0.25), math.cos(0.25)))
    tf = msgs[6][3].transforms[0]
    assert (tf.header.frame_id, tf.child_frame_id, tf.transform.translation.x) == ("odom", "base_footprint", 2.0)
    static = msgs[3][3].transforms[0]
    assert (static.header.frame_id, static.child_frame_id, static.transform.translation.x) == \
        ("base_footprint", "laser", 0.1)
    assert static.transform.rotation.z == pytest.approx(1.0)                        # yaw pi


def test_fractional_stamps_and_extra_topics(tmp_path):
    rec = ScanRecord(1.25, np.ones(2, np.float32), 0.0, 0.1, 0.1, 5.0)
    with BagWriter(tmp_path / "x.bag", scan_topic="/front", publish_tf=False) as w:
        w.scan(rec)
        w.scan(rec, topic="/rear")
        w.odom(OdomRecord(1.5, 0.0, 0.0, 0.0))
    msgs, conns = read_raw(tmp_path / "x.bag")
    assert sorted(conns) == ["/front", "/odom", "/rear"]                            # no /tf: publish_tf off
    assert [(m[0], m[2]) for m in msgs] == [("/front", 1_250_000_000), ("/rear", 1_250_000_000),
                                            ("/odom", 1_500_000_000)]
    assert (msgs[0][3].header.stamp.sec, msgs[0][3].header.stamp.nanosec) == (1, 250_000_000)


def test_an_existing_file_is_never_overwritten(tmp_path):
    (tmp_path / "old.bag").write_bytes(b"old")
    with pytest.raises(BagError, match="exists"):
        write_bag(tmp_path / "old.bag", [], [])
    assert (tmp_path / "old.bag").read_bytes() == b"old"
