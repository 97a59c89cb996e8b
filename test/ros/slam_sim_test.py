#!/usr/bin/env python3
"""End to end on the simulator: slam.py's ROS surface, then the quality of its result.

The launch file starts the simulator on turtlebot3_world with its route, slam.py, and
this test, all on sim time. Thresholds come from the test's private parameters.
"""
import os
import sys
import tempfile
import time
import unittest

import numpy as np
import rospy
import rostest
import tf2_ros
from geometry_msgs.msg import PoseArray, PoseWithCovarianceStamped
from nav_msgs.msg import MapMetaData, OccupancyGrid
from nav_msgs.srv import GetMap
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from assign5.run_report import RunRecorder, evaluate


def wait_message(topic, kind, timeout=30.0):
    return rospy.wait_for_message(topic, kind, timeout=timeout)


class SlamOnSimulator(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        rospy.init_node("slam_sim_test")
        cls.recorder = RunRecorder()
        cls.particles = rospy.get_param("/slam/particles")
        cls.scans = 0
        rospy.Subscriber("scan", LaserScan, cls._count_scan, queue_size=50)
        cls.tf = tf2_ros.Buffer()
        cls.tf_listener = tf2_ros.TransformListener(cls.tf)

    @classmethod
    def _count_scan(cls, _msg):
        cls.scans += 1

    def test_1_particles_pose_and_neff(self):
        msg = wait_message("particles", PoseArray)
        self.assertEqual(msg.header.frame_id, "map")
        self.assertEqual(len(msg.poses), self.particles)
        pose = wait_message("slam/pose", PoseWithCovarianceStamped)
        self.assertEqual(pose.header.frame_id, "map")
        cov = np.array(pose.pose.covariance).reshape(6, 6)
        self.assertTrue(np.all(np.diag(cov)[[0, 1, 5]] >= 0))
        neff = wait_message("slam/neff", Float64).data
        self.assertTrue(1.0 <= neff <= self.particles + 1e-6, neff)

    def test_2_map_is_latched_and_matches_its_metadata_and_the_service(self):
        first = wait_message("map", OccupancyGrid)
        # a subscriber that comes after the map was published still gets it at once: latched
        late = wait_message("map", OccupancyGrid, timeout=1.0)
        meta = wait_message("map_metadata", MapMetaData, timeout=1.0)
        for m in (first, late):
            self.assertEqual(m.header.frame_id, "map")
            self.assertAlmostEqual(m.info.resolution, 0.05, places=6)
            self.assertEqual(len(m.data), m.info.width * m.info.height)
        self.assertEqual((meta.width, meta.height), (late.info.width, late.info.height))
        self.assertTrue(set(np.unique(late.data)) <= set(range(-1, 101)))
        # 10 m at 0.05 m to start with, centred on the robot's start
        self.assertGreaterEqual(late.info.width, 200)
        rospy.wait_for_service("dynamic_map", 5.0)
        served = rospy.ServiceProxy("dynamic_map", GetMap)().map
        self.assertEqual((served.info.width, served.info.height), (late.info.width, late.info.height))
        self.assertEqual(served.header.frame_id, "map")

    def test_2b_debug_maps_of_the_best_particles(self):
        best = wait_message("map", OccupancyGrid)
        for i in range(2):
            m = wait_message(f"slam/particle_map_{i}", OccupancyGrid)
            self.assertEqual(m.header.frame_id, "map")
            self.assertEqual((m.info.width, m.info.height), (best.info.width, best.info.height))
        with self.assertRaises(rospy.ROSException):
            wait_message("slam/particle_map_2", OccupancyGrid, timeout=1.0)

    def test_3_map_to_odom_transform(self):
        t = self.tf.lookup_transform("map", "odom", rospy.Time(0), rospy.Duration(10.0))
        self.assertGreater(t.header.stamp.to_sec(), 0.0)
        q = t.transform.rotation
        self.assertAlmostEqual(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w, 1.0, places=6)
        # the robot itself is reachable from the map frame
        self.tf.lookup_transform("map", "base_scan", rospy.Time(0), rospy.Duration(10.0))

    def test_4_save_map_service_writes_map_server_files(self):
        wait_message("map", OccupancyGrid)   # something is mapped
        rospy.wait_for_service("slam/save_map", 5.0)
        res = rospy.ServiceProxy("slam/save_map", Trigger)()
        self.assertTrue(res.success, res.message)
        with open(res.message) as f:
            text = f.read()
        for key in ("image:", "resolution: 0.05", "origin:", "negate: 0", "occupied_thresh: 0.65",
                    "free_thresh: 0.196"):
            self.assertIn(key, text)
        with open(res.message[:-5] + ".pgm", "rb") as f:
            self.assertEqual(f.read(2), b"P5")

    def test_5_quality_at_the_end_of_the_route(self):
        self.assertTrue(self.recorder.done.wait(rospy.get_param("~route_timeout", 300.0)), "route never finished")
        traj, grid = self.recorder.final_outputs(settle=15.0)
        with self.recorder.lock:
            truth, ms = np.array(self.recorder.truth), list(self.recorder.update_ms)
        metrics, _, _ = evaluate(rospy.get_param("~world_file"), truth, traj, grid, ms)
        print("metrics:", metrics, file=sys.stderr)
        self.assertLessEqual(metrics["trajectory_rms_m"], rospy.get_param("~max_rms", 0.10))
        self.assertGreaterEqual(metrics["boundary_recall"], rospy.get_param("~min_recall", 0.90))
        self.assertLessEqual(metrics["spurious_fraction"], rospy.get_param("~max_spurious", 0.05))
        self.assertGreater(metrics["processed_scans"], 300)
        # keeping up: (nearly) every scan of the run became an update, none fell behind
        self.assertGreaterEqual(len(ms), 0.95 * self.scans - 3, f"{len(ms)} updates for {self.scans} scans")
        type(self).live_rms = metrics["trajectory_rms_m"]

    def test_6_the_recorded_bag_replays_offline_with_the_same_quality(self):
        import glob
        import subprocess

        from assign5.params import split_params
        from fastslam import offline
        from fastslam.eval.maps import trajectory_errors
        from fastslam.io.bag_reader import read_bag

        prefix = rospy.get_param("~bag_prefix")
        self.assertTrue(self.recorder.done.wait(rospy.get_param("~route_timeout", 300.0)), "route never finished")
        subprocess.run(["rosnode", "kill", "/record"], capture_output=True, timeout=30)
        deadline = time.time() + 30
        while (glob.glob(prefix + "*.bag.active") or not glob.glob(prefix + "*.bag")) and time.time() < deadline:
            time.sleep(0.5)
        bag = max(glob.glob(prefix + "*.bag"), key=os.path.getmtime)
        data = read_bag(bag)
        self.assertEqual((data.scan_topic, data.odom_topic), ("/scan", "/odom"))
        self.assertAlmostEqual(data.mount.x, -0.032)  # from the bag's /tf_static
        _, cfg = split_params(rospy.get_param("/slam"))
        result = offline.run_bag(data, cfg)
        with self.recorder.lock:
            truth = np.array(self.recorder.truth)
        from fastslam.geometry import relative
        from fastslam.sim.world_loader import load_world

        spawn = load_world(rospy.get_param("~world_file")).spawn
        err = trajectory_errors(result.slam.trajectory(), np.c_[truth[:, 0], relative(spawn, truth[:, 1:])])
        rms = float(np.sqrt(np.mean(err ** 2)))
        print(f"offline on the recorded bag: {result.updates} updates, RMS {rms:.3f} m "
              f"(live {getattr(self, 'live_rms', float('nan')):.3f} m)", file=sys.stderr)
        self.assertGreaterEqual(result.updates, len(data.scans) - 2)
        self.assertLessEqual(rms, rospy.get_param("~max_rms", 0.10))


if __name__ == "__main__":
    tempfile.tempdir = None
    rostest.rosrun("assign5", "slam_sim", SlamOnSimulator)
