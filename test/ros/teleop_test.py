#!/usr/bin/env python3
"""`roslaunch assign5 teleop.launch` on a pseudo-terminal: keys -> ramped cmd_vel, stop,
CTRL-C -> a zero command, and the launch ends by itself (exit 0, no error banner).

Every wait is on a condition (messages or output seen) with a deadline.
"""
import os
import pty
import re
import subprocess
import threading
import time
import unittest

import rospy
import rostest
from geometry_msgs.msg import Twist


class TeleopTest(unittest.TestCase):
    def setUp(self) -> None:
        rospy.init_node("teleop_test", anonymous=True)
        self.cond = threading.Condition()
        self.msgs: list = []
        self.out = b""
        self.sub = rospy.Subscriber("cmd_vel", Twist, self._on, queue_size=100)
        master, slave = pty.openpty()
        self.master = master
        # on the rostest master (ROS_MASTER_URI is inherited): roslaunch starts no master of its own
        self.proc = subprocess.Popen(["roslaunch", "assign5", "teleop.launch"], stdin=slave, stdout=slave,
                                     stderr=slave, close_fds=True, start_new_session=True)
        os.close(slave)
        threading.Thread(target=self._drain, daemon=True).start()

    def tearDown(self) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, 9)
            self.proc.wait()
        self.sub.unregister()
        os.close(self.master)

    def _on(self, msg: Twist) -> None:
        with self.cond:
            self.msgs.append((time.monotonic(), msg.linear.x, msg.angular.z))
            self.cond.notify_all()

    def _drain(self) -> None:
        while True:
            try:
                chunk = os.read(self.master, 4096)
            except OSError:
                return
            if not chunk:
                return
            with self.cond:
                self.out += chunk
                self.cond.notify_all()

    def wait(self, predicate, timeout: float, what: str) -> None:
        with self.cond:
            ok = self.cond.wait_for(predicate, timeout)
        self.assertTrue(ok, f"no {what} within {timeout} s; output:\n{self.out.decode(errors='replace')[-1500:]}")

    def last(self):
        with self.cond:
            return self.msgs[-1][1:]

    def test_keys(self) -> None:
        self.wait(lambda: b"CTRL-C to quit" in self.out and len(self.msgs) >= 5, 30, "banner and idle cmd_vel")
        os.write(self.master, b"www")
        self.wait(lambda: b"linear vel 0.03" in self.out, 10, "status after www")
        os.write(self.master, b"a")
        # the ramp reaches the targets (half a key step per loop)
        self.wait(lambda: abs(self.msgs[-1][1] - 0.03) < 1e-9 and abs(self.msgs[-1][2] - 0.1) < 1e-9, 10,
                  "ramped command")
        # about 10 Hz while idle (the loop's 0.1 s key timeout): count one second of messages
        with self.cond:
            start = len(self.msgs)
            t0 = self.msgs[-1][0]
        self.wait(lambda: self.msgs[-1][0] - t0 >= 1.0, 5, "a second of messages")
        with self.cond:
            rate = sum(1 for m in self.msgs[start:] if m[0] - t0 <= 1.0)
        self.assertTrue(6 <= rate <= 13, f"{rate} messages in 1 s")
        os.write(self.master, b" ")
        self.wait(lambda: self.msgs[-1][1:] == (0.0, 0.0), 5, "stop")
        os.write(self.master, b"www\x03")
        self.assertEqual(self.proc.wait(timeout=30), 0, self.out.decode(errors="replace")[-1500:])
        text = self.out.decode(errors="replace")
        self.assertIn("all processes on machine have died, roslaunch will exit", text)
        self.assertIsNone(re.search(r"Traceback|\[FATAL\]|ERROR|has died", text.replace("have died", "")), text)
        self.wait(lambda: self.msgs[-1][1:] == (0.0, 0.0), 5, "zero command on CTRL-C")


if __name__ == "__main__":
    rostest.rosrun("assign5", "teleop_test", TeleopTest)
