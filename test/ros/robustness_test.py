#!/usr/bin/env python3
"""Bad input never takes slam.py down: each case is dropped or handled, then good input works.

A synthetic square room (2.5 m half-width) is scanned from poses the test publishes on
/odom, with a static tf base_footprint -> base_scan; between bad messages the test
checks that a good scan still yields a particle update.
"""
import math
import os
import sys
import time
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import PoseArray, TransformStamped
from nav_msgs.msg import Odometry, Path
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "src"))
from fastslam.sim.lidar import cast_rays
from fastslam.sim.world_loader import load_world

ANGLES = np.radians(np.arange(360.0))
ROOM = load_world(os.path.join(os.path.dirname(__file__), "..", "..", "worlds", "pillar_room.yaml"))


class Robustness(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("robustness_test")
        cls.pub_scan = rospy.Publisher("scan", LaserScan, queue_size=10)
        cls.pub_odom = rospy.Publisher("odom", Odometry, queue_size=10)
        cls.static = tf2_ros.StaticTransformBroadcaster()
        t = TransformStamped()
        t.header.stamp = rospy.Time.now()
        t.header.frame_id, t.child_frame_id = "base_footprint", "base_scan"
        t.transform.rotation.w = 1.0
        cls.static.sendTransform(t)
        cls.updates = 0
        cls.path = None
        rospy.Subscriber("particles", PoseArray, cls._on_particles)
        rospy.Subscriber("slam/trajectory", Path, cls._on_path)
        cls.x = 0.0
        deadline = time.time() + 20
        while cls.pub_scan.get_num_connections() == 0 or cls.pub_odom.get_num_connections() == 0:
            assert time.time() < deadline, "slam node did not subscribe"
            time.sleep(0.1)

    @classmethod
    def _on_particles(cls, msg):
        cls.updates += 1

    @classmethod
    def _on_path(cls, msg):
        cls.path = msg

    def odom(self, x, stamp=None, quat=(0.0, 0.0, 0.0, 1.0)):
        o = Odometry()
        o.header.stamp = stamp or rospy.Time.now()
        o.header.frame_id, o.child_frame_id = "odom", "base_footprint"
        o.pose.pose.position.x = x
        o.pose.pose.orientation.x, o.pose.pose.orientation.y, o.pose.pose.orientation.z, \
            o.pose.pose.orientation.w = quat
        self.pub_odom.publish(o)

    def scan(self, stamp=None, **fields):
        s = LaserScan()
        s.header.stamp = stamp or rospy.Time.now()
        s.header.frame_id = "base_scan"
        s.angle_min, s.angle_increment = 0.0, math.radians(1.0)
        s.angle_max = math.radians(359.0)
        s.range_min, s.range_max = 0.12, 3.5
        r = cast_rays(ROOM, np.array([self.x, 0.0, 0.0]), ANGLES)
        s.ranges = np.where(r > 3.5, np.inf, r).tolist()
        for k, v in fields.items():
            setattr(s, k, v)
        self.pub_scan.publish(s)

    def good_step(self):
        """Odometry then a scan at the same stamp; returns whether an update came out."""
        before = self.updates
        self.x += 0.01
        now = rospy.Time.now()
        self.odom(self.x, now)
        time.sleep(0.05)
        self.scan(now)
        deadline = time.time() + 3
        while self.updates == before and time.time() < deadline:
            time.sleep(0.02)
        return self.updates > before

    def assert_still_works(self):
        self.assertTrue(any(self.good_step() for _ in range(3)), "no update after the bad message")

    def bad_scan(self, stamp=None, **fields):
        now = rospy.Time.now()
        self.odom(self.x, now)
        time.sleep(0.05)
        before = self.updates
        self.scan(stamp or now, **fields)
        time.sleep(0.4)
        return self.updates - before

    def test_1_good_input_updates(self):
        # the first scans may come before the node has the static tf: those are dropped
        self.assertTrue(any(self.good_step() for _ in range(20)))
        for _ in range(3):
            self.assertTrue(self.good_step())

    def test_2_bad_scans_are_dropped(self):
        cases = {
            "empty": dict(ranges=[]),
            "length": dict(ranges=[1.0] * 100),
            "increment zero": dict(angle_increment=0.0),
            "increment nan": dict(angle_increment=float("nan")),
            "range_max zero": dict(range_max=0.0),
            "range_max below min": dict(range_min=2.0, range_max=1.0),
            "unknown frame": dict(header=type(LaserScan().header)(frame_id="nowhere", stamp=rospy.Time.now())),
        }
        for name, fields in cases.items():
            with self.subTest(name):
                self.assertEqual(self.bad_scan(**fields), 0, f"{name}: scan was used")
                self.assert_still_works()

    def test_3_bad_readings_are_ignored_not_fatal(self):
        r = [float("nan"), float("inf"), -1.0, 0.0, 99.0] * 72
        self.assertEqual(self.bad_scan(ranges=r), 1)
        self.assertEqual(self.bad_scan(intensities=[1.0, 2.0]), 1)  # intensities are not used
        self.assertEqual(self.bad_scan(angle_increment=-math.radians(1.0), angle_max=-math.radians(359.0)), 1)
        self.assert_still_works()

    def test_4_bad_odometry(self):
        now = rospy.Time.now()
        self.odom(float("nan"), now)
        self.odom(self.x, now, quat=(0.0, 0.0, 0.0, 0.0))
        self.odom(self.x, now, quat=(0.0, 0.0, 0.0, 7.0))  # not normalised: still heading 0
        self.assert_still_works()

    def test_5_odometry_jump_is_not_integrated(self):
        self.assert_still_works()
        before = self.path_end()
        self.x += 50.0
        self.assert_still_works()
        time.sleep(2.5)
        after = self.path_end()
        self.assertLess(abs(after - before), 1.0, "the kidnap jump was integrated")

    def test_6_future_stamps_are_rejected(self):
        self.assertEqual(self.bad_scan(stamp=rospy.Time.now() + rospy.Duration(3600)), 0)
        self.assert_still_works()

    def test_7_time_going_backwards_resets(self):
        self.assert_still_works()
        time.sleep(2.5)
        long_path = len(self.path.poses)
        old = rospy.Time.now() - rospy.Duration(30)
        self.odom(self.x, old - rospy.Duration(0.1))
        self.odom(self.x, old)
        time.sleep(0.05)
        self.scan(old)
        time.sleep(0.5)
        for _ in range(3):
            self.good_step()
        time.sleep(2.5)
        self.assertGreater(long_path, 5)
        self.assertLess(len(self.path.poses), long_path, "filter was not reset")

    def test_8_save_map_service(self):
        rospy.wait_for_service("slam/save_map", 5)
        res = rospy.ServiceProxy("slam/save_map", Trigger)()
        self.assertTrue(res.success, res.message)
        self.assertTrue(res.message.endswith(".yaml") and os.path.exists(res.message), res.message)
        with open(res.message) as f:
            text = f.read()
        self.assertIn("resolution: 0.05", text)
        self.assertTrue(os.path.exists(res.message[:-5] + ".pgm"))

    def test_9_bad_parameter_stops_at_start_up_naming_it(self):
        import subprocess

        for arg, message in (("_particles:=0", "particles=0 must be in [1, 10000]"),
                             ("_map_resolution:=-1", "map_resolution=-1.0 must be in"),
                             ("_sigma_x:=-0.1", "sigma_x=-0.1 must be in"),
                             ("_map_resolutoin:=0.1", "unknown parameter 'map_resolutoin'")):
            proc = subprocess.run(["rosrun", "assign5", "slam.py", "__name:=bad_slam", arg],
                                  capture_output=True, text=True, timeout=60)
            self.assertNotEqual(proc.returncode, 0, arg)
            self.assertIn(message, proc.stdout + proc.stderr, arg)
            rospy.delete_param("/bad_slam")

    def spawn_slam(self, name, *params):
        """A second slam.py on the same topics; returns once it has processed a scan."""
        import subprocess

        proc = subprocess.Popen(["rosrun", "assign5", "slam.py", f"__name:={name}", "_particles:=2", *params],
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
        got = []
        sub = rospy.Subscriber(f"{name}/neff", Float64, got.append)
        deadline = time.time() + 30
        while not got and time.time() < deadline:
            self.good_step()
        sub.unregister()
        self.assertTrue(got, f"{name} never updated")
        return proc

    def test_10_map_is_saved_on_sigterm_and_sigint(self):
        import signal
        import tempfile

        folder = tempfile.mkdtemp()
        for sig in (signal.SIGTERM, signal.SIGINT):
            stem = os.path.join(folder, f"exit_{int(sig)}")
            proc = self.spawn_slam("exit_slam", "_save_on_exit:=true", f"_map_file:={stem}")
            proc.send_signal(sig)
            out, _ = proc.communicate(timeout=30)
            self.assertTrue(os.path.exists(stem + ".yaml") and os.path.exists(stem + ".pgm"), out)
            rospy.delete_param("/exit_slam")

    def test_11_a_failed_save_is_reported_and_the_old_file_kept(self):
        import tempfile

        folder = tempfile.mkdtemp()
        blocker = os.path.join(folder, "not_a_folder")
        with open(blocker, "w") as f:
            f.write("a file where the map's folder should be")
        proc = self.spawn_slam("save_slam", f"_map_file:={blocker}/map")
        try:
            rospy.wait_for_service("save_slam/save_map", 10)
            res = rospy.ServiceProxy("save_slam/save_map", Trigger)()
            self.assertFalse(res.success)
            self.assertIn("not_a_folder", res.message)
            with open(blocker) as f:
                self.assertEqual(f.read(), "a file where the map's folder should be")
        finally:
            proc.terminate()
            proc.communicate(timeout=30)
            rospy.delete_param("/save_slam")

    def path_end(self):
        deadline = time.time() + 5
        while self.path is None and time.time() < deadline:
            time.sleep(0.1)
        return self.path.poses[-1].pose.position.x


if __name__ == "__main__":
    rostest.rosrun("assign5", "robustness", Robustness)
