#!/usr/bin/env python3
"""`roslaunch assign5 replay.launch bag:=room.bag` (a relative path) replays a simulator
bag into slam.py, ends by itself without an error banner and leaves the map beside the
bag; the live trajectory equals fastslam.offline on the same bag with the node's own
parameters and seed, on the scans the node processed. The bag's odometry comes 20 ms
after the scans, between them, as a real robot's may (ACES's: 20-140 ms): the node waits
for the next message and interpolates the odometry at the scan's stamp; the offline
runner hands the scan over after that message too (BagData.records), so both give the
scan the same odometry.
"""
import dataclasses
import os
import re
import subprocess
import sys
import tempfile
import threading
import unittest

import numpy as np
import rospy
import rostest
from nav_msgs.msg import Path

from assign5.params import split_params
from fastslam import offline, simrun
from fastslam.config import SlamConfig
from fastslam.eval.maps import trajectory_errors
from fastslam.io.bag_reader import BagData, read_bag
from fastslam.io.bag_writer import write_bag
from fastslam.transforms import StaticTransform

ODOM_LAG = 0.02  # [s] the bag's odometry is stamped this much after the simulator's (30 Hz; scans 5 Hz)


class Replay(unittest.TestCase):
    def test_replay_launch_matches_offline_and_saves_the_map(self):
        rospy.init_node("replay_test")
        folder = tempfile.mkdtemp(prefix="assign5_replay_")
        bag = os.path.join(folder, "room.bag")
        sim = simrun.run("room", SlamConfig(particles=1), seed=2, record=True)
        odoms = [dataclasses.replace(o, t=o.t + ODOM_LAG) for o in sim.odoms]
        write_bag(bag, sim.scans, odoms, static_transforms=[
            StaticTransform.planar("base_footprint", "base_link", z=0.010),
            StaticTransform.planar("base_link", "base_scan", x=-0.032, z=0.172)])

        got = threading.Condition()
        paths = []

        def on_path(msg):
            with got:
                paths.append(msg)
                got.notify_all()

        rospy.Subscriber("slam/trajectory", Path, on_path)
        # as typed in the bag's folder: PWD is what a shell would set there
        launch = subprocess.run(["roslaunch", "assign5", "replay.launch", "bag:=room.bag", "config:=burger",
                                 "seed:=5"], cwd=folder, env={**os.environ, "PWD": folder},
                                stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
        out = launch.stdout
        self.assertEqual(launch.returncode, 0, out[-3000:])
        self.assertIsNone(re.search(r"Traceback|\[FATAL\]|ERROR|has died", out), out[-3000:])
        saved = os.path.join(folder, "room_map.yaml")
        self.assertIn(f"map saved: {saved}", out)
        self.assertTrue(os.path.isfile(saved) and os.path.getsize(os.path.join(folder, "room_map.pgm")) > 1000)
        with got:
            self.assertTrue(got.wait_for(lambda: paths, 10.0), "no trajectory was published")
            last = paths[-1]

        live = np.array([(p.header.stamp.to_sec(), p.pose.position.x, p.pose.position.y,
                          2 * np.arctan2(p.pose.orientation.z, p.pose.orientation.w)) for p in last.poses])
        self.assertGreater(len(live), 0.8 * len(sim.scans), "the node dropped too many scans")
        _, cfg = split_params(rospy.get_param("/slam"))   # the node's parameters stay on the master
        self.assertEqual((cfg.seed, cfg.proposal), (5, "scan_match"))
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
    rostest.rosrun("assign5", "replay_test", Replay)
