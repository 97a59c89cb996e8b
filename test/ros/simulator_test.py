#!/usr/bin/env python3
"""Graph test of simulator.py (launched by simulator.test with use_sim_time and speed 4)."""
import math
import threading
import unittest

import rospy
import rostest
import tf2_ros
from nav_msgs.msg import Odometry
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Bool


def _yaw(q) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


class SimulatorTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls) -> None:
        rospy.init_node("simulator_test")
        cls.lock = threading.Condition()
        cls.scans, cls.odoms, cls.truths, cls.done = [], [], [], []
        cls.tf_buffer = tf2_ros.Buffer(cache_time=rospy.Duration(30.0))
        cls.tf_listener = tf2_ros.TransformListener(cls.tf_buffer)
        rospy.Subscriber("scan", LaserScan, lambda m: cls._add(cls.scans, m), queue_size=50)
        rospy.Subscriber("odom", Odometry, lambda m: cls._add(cls.odoms, m), queue_size=200)
        rospy.Subscriber("ground_truth", Odometry, lambda m: cls._add(cls.truths, m), queue_size=200)
        rospy.Subscriber("route_done", Bool, lambda m: cls._add(cls.done, m), queue_size=5)
        # a wall-clock deadline: sim time only moves once the simulator publishes /clock
        with cls.lock:
            cls.lock.wait_for(lambda: len(cls.scans) >= 30 and any(m.data for m in cls.done), 60.0)

    @classmethod
    def _add(cls, store: list, msg) -> None:
        with cls.lock:
            store.append(msg)
            cls.lock.notify_all()

    def test_scan_format_and_rate(self) -> None:
        scans = list(self.scans)
        self.assertGreaterEqual(len(scans), 30, "fewer than 30 scans")
        s = scans[-1]
        self.assertEqual(len(s.ranges), 360)
        self.assertEqual(s.header.frame_id, "base_scan")
        self.assertAlmostEqual(s.angle_min, 0.0)
        self.assertAlmostEqual(s.angle_increment, math.radians(1.0), places=6)
        self.assertAlmostEqual(s.range_min, 0.12, places=6)
        self.assertAlmostEqual(s.range_max, 3.5, places=6)
        finite = [r for r in s.ranges if math.isfinite(r)]
        self.assertGreater(len(finite), 100, "the arena should be visible in most directions")
        self.assertTrue(all(0.12 <= r <= 3.5 for r in finite))
        stamps = [m.header.stamp.to_sec() for m in scans]
        rate = (len(stamps) - 1) / (stamps[-1] - stamps[0])
        self.assertTrue(4.0 <= rate <= 6.0, f"scan rate {rate:.2f} Hz of sim time")

    def test_odom_tf_and_ground_truth(self) -> None:
        odoms, truths = list(self.odoms), list(self.truths)
        self.assertGreater(len(odoms), 100)
        self.assertGreater(len(truths), 100)
        first = odoms[0]
        self.assertEqual((first.header.frame_id, first.child_frame_id), ("odom", "base_footprint"))
        self.assertEqual(truths[0].header.frame_id, "world")
        # perfect odometry (odom_noise false in simulator.test): odom = truth seen from the spawn (-2, -0.5, 0)
        by_stamp = {m.header.stamp: m for m in truths}
        pairs = [(o, by_stamp[o.header.stamp]) for o in odoms if o.header.stamp in by_stamp]
        self.assertGreater(len(pairs), 50)
        for o, t in pairs[::10]:
            self.assertAlmostEqual(o.pose.pose.position.x, t.pose.pose.position.x + 2.0, places=6)
            self.assertAlmostEqual(o.pose.pose.position.y, t.pose.pose.position.y + 0.5, places=6)
            self.assertAlmostEqual(_yaw(o.pose.pose.orientation), _yaw(t.pose.pose.orientation), places=6)
        rates = (len(odoms) - 1) / (odoms[-1].header.stamp.to_sec() - odoms[0].header.stamp.to_sec())
        self.assertTrue(25.0 <= rates <= 35.0, f"odom rate {rates:.1f} Hz")
        # tf odom -> base_footprint equals the odometry message at the same stamp
        msg = odoms[-5]
        tf = self.tf_buffer.lookup_transform("odom", "base_footprint", msg.header.stamp, rospy.Duration(2.0))
        self.assertAlmostEqual(tf.transform.translation.x, msg.pose.pose.position.x, places=6)
        self.assertAlmostEqual(tf.transform.translation.y, msg.pose.pose.position.y, places=6)
        self.assertAlmostEqual(_yaw(tf.transform.rotation), _yaw(msg.pose.pose.orientation), places=6)
        scan_tf = self.tf_buffer.lookup_transform("base_footprint", "base_scan", rospy.Time(0), rospy.Duration(2.0))
        self.assertAlmostEqual(scan_tf.transform.translation.x, -0.032, places=6)
        self.assertAlmostEqual(scan_tf.transform.translation.z, 0.182, places=6)

    def test_route_done(self) -> None:
        self.assertTrue(any(m.data for m in self.done), "route_done never became True")
        last = self.truths[-1].pose.pose.position
        self.assertAlmostEqual(last.x, -0.9, delta=0.15)
        self.assertAlmostEqual(last.y, -0.55, delta=0.15)


if __name__ == "__main__":
    rostest.rosrun("assign5", "simulator_test", SimulatorTest)
