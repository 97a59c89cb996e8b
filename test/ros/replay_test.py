#!/usr/bin/env python3
"""A simulator bag played with `rosbag play --clock` into slam.py equals the offline run.

The test writes a bag of the simulated room run (the same physics as the simulator
node), plays it into the live node on sim time, then runs fastslam.offline on the same
bag with the node's own parameters and seed. On the scans the node processed the two
trajectories agree; both are compared with the simulator's ground truth.
"""
import os
import subprocess
import sys
import tempfile
import time
import unittest

import numpy as np
import rospy
import rostest
from nav_msgs.msg import Path

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "src"))
from assign5.params import split_params
from fastslam import offline, simrun
from fastslam.eval.maps import trajectory_errors
from fastslam.io.bag_reader import BagData, read_bag
from fastslam.io.bag_writer import write_bag
from fastslam.transforms import StaticTransform


class Replay(unittest.TestCase):
    def test_live_replay_matches_offline(self):
        rospy.init_node("replay_test")
        _, cfg = split_params(rospy.get_param("/slam"))
        folder = tempfile.mkdtemp(prefix="assign5_replay_")
        bag = os.path.join(folder, "room.bag")
        sim = simrun.run("room", cfg.replace(particles=1), seed=2, record=True)
        write_bag(bag, sim.scans, sim.odoms, static_transforms=[
            StaticTransform.planar("base_footprint", "base_link", z=0.010),
            StaticTransform.planar("base_link", "base_scan", x=-0.032, z=0.172)])

        paths = []
        rospy.Subscriber("slam/trajectory", Path, paths.append)
        play = subprocess.run(["rosbag", "play", "--clock", "-q", "-d", "1", "-r", "1.0", bag],
                              capture_output=True, text=True, timeout=300)
        self.assertEqual(play.returncode, 0, play.stderr)
        time.sleep(1.0)
        deadline = time.time() + 30
        while (not paths or paths[-1].poses[-1].header.stamp.to_sec() < sim.scans[-1].t - 2.5) \
                and time.time() < deadline:
            time.sleep(0.2)
        live = np.array([(p.header.stamp.to_sec(), p.pose.position.x, p.pose.position.y,
                          2 * np.arctan2(p.pose.orientation.z, p.pose.orientation.w)) for p in paths[-1].poses])
        self.assertGreater(len(live), 0.9 * len(sim.scans), "the node dropped too many scans")

        data = read_bag(bag)
        processed = set(np.round(live[:, 0], 6))
        kept = [s for s in data.scans if round(s.t, 6) in processed]
        ours = offline.run_bag(BagData(kept, data.odoms, data.mount, data.scan_topic, data.odom_topic), cfg)
        est = ours.slam.trajectory()[: len(live)]
        self.assertEqual(len(est), len(live))
        # same scans, same odometry, same seed: the same filter, to rounding
        np.testing.assert_allclose(est[:, :3], live[:, :3], atol=1e-6)
        err = trajectory_errors(live, sim.truth)
        print(f"live replay: {len(live)} of {len(sim.scans)} scans, RMS {np.sqrt(np.mean(err**2)):.3f} m",
              file=sys.stderr)
        self.assertLess(np.sqrt(np.mean(err ** 2)), rospy.get_param("~max_rms", 0.2))


if __name__ == "__main__":
    rostest.rosrun("assign5", "replay", Replay)
