#!/usr/bin/env python3
"""Service calls never hold up tf nor stay in memory (issue 13 item 4): 20 dynamic_map calls
at once on a 2000 x 2000-cell map, from another process, while slam.py maps; map->odom
is never late by more than two periods (the gaps between its stamps: the node's own
timing, not this process's), the node's memory comes back."""
import json
import subprocess
import threading
import time

import rospy
import rostest
from clocked import ClockedCase
from tf2_msgs.msg import TFMessage

PERIOD = 0.1  # transform_publish_period in services.test [s]
# 20 concurrent GetMap calls, the responses read by numpy (genpy would make 4 M ints each)
CLIENT = """
import json, sys, threading, rospy
from nav_msgs.srv import GetMap, GetMapRequest, GetMapResponse
from rospy.numpy_msg import numpy_msg

class NumpyGetMap:
    _type, _md5sum = GetMap._type, GetMap._md5sum
    _request_class, _response_class = GetMapRequest, numpy_msg(GetMapResponse)

rospy.wait_for_service("dynamic_map", 30)
out = []
def call():
    m = rospy.ServiceProxy("dynamic_map", NumpyGetMap)().map
    out.append([m.info.width, m.info.height, int((m.data != -1).sum())])
calls = [threading.Thread(target=call) for _ in range(20)]
for c in calls:
    c.start()
for c in calls:
    c.join()
print(json.dumps(out))
"""


class Services(ClockedCase):
    NODE = "services_test"

    def test_twenty_dynamic_map_calls_at_once_hold_up_neither_tf_nor_memory(self):
        for _ in range(20):
            stamp = self.step(0.01)
        self.path_after(stamp)
        before = self.rss_mb()
        arrivals = []
        lock = threading.Lock()

        def on_tf(msg):
            for t in msg.transforms:
                if t.child_frame_id == "odom":
                    with lock:
                        arrivals.append((time.monotonic(), t.header.stamp.to_sec()))

        sub = rospy.Subscriber("/tf", TFMessage, on_tf, queue_size=100)
        self.wait_for_tf(arrivals, lock)
        client = subprocess.Popen(["python3", "-c", CLIENT], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        start = time.monotonic()
        deadline = start + 120
        while client.poll() is None and time.monotonic() < deadline:
            self.step(0.002, timeout=1.0)        # the node maps while it answers
        out, err = client.communicate(timeout=30)
        # a quick client leaves few stamps in its window: map on until enough are in for the gaps to tell
        self.wait_for_tf(arrivals, lock, count=8, since=start - PERIOD)
        end = time.monotonic()
        sub.unregister()
        self.assertEqual(client.returncode, 0, err)
        maps = json.loads(out)
        self.assertEqual(len(maps), 20)
        self.assertTrue(all(m[:2] == [2000, 2000] and m[2] > 100 for m in maps), maps)
        with lock:
            during = [stamp for t, stamp in arrivals if start - PERIOD <= t <= end + PERIOD]
        gaps = sorted(b - a for a, b in zip(during, during[1:]))
        self.assertGreater(len(gaps), 5)
        self.assertLessEqual(gaps[-1], 2 * PERIOD, f"map->odom was late while the calls ran: "
                             f"largest gaps {[round(g, 3) for g in gaps[-5:]]} s, {len(gaps)} in all")
        deadline = time.monotonic() + 10
        while self.rss_mb() - before >= 100.0 and time.monotonic() < deadline:
            self.step(0.002, timeout=0.5)
        self.assertLess(self.rss_mb() - before, 100.0, "the calls left memory behind")

    def wait_for_tf(self, arrivals, lock, count=3, since=0.0):
        """Maps on until count map->odom transforms have arrived since that monotonic time."""
        deadline = time.monotonic() + 10
        while time.monotonic() < deadline:
            with lock:
                if sum(t >= since for t, _ in arrivals) >= count:
                    return
            self.step(0.002, timeout=0.5)
        self.fail("no map->odom on /tf")


if __name__ == "__main__":
    rostest.rosrun("assign5", "services", Services)
