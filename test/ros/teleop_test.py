#!/usr/bin/env python3
"""teleop_key.py in a pseudo-terminal: keys -> ramped cmd_vel, stop, CTRL-C -> zero command and exit 0."""
import os
import pty
import select
import subprocess
import sys
import threading
import time
import unittest
from pathlib import Path

import rospy
import rostest
from geometry_msgs.msg import Twist

SCRIPT = Path(__file__).resolve().parents[2] / "src" / "teleop_key.py"


class TeleopTest(unittest.TestCase):
    def setUp(self) -> None:
        rospy.init_node("teleop_test", anonymous=True)
        self.lock = threading.Lock()
        self.msgs: list = []
        self.sub = rospy.Subscriber("cmd_vel", Twist, self._on, queue_size=100)
        master, slave = pty.openpty()
        self.master = master
        self.proc = subprocess.Popen([sys.executable, str(SCRIPT)], stdin=slave, stdout=slave, stderr=slave,
                                     close_fds=True)
        os.close(slave)
        self.out = b""

    def tearDown(self) -> None:
        if self.proc.poll() is None:
            self.proc.kill()
        os.close(self.master)

    def _on(self, msg: Twist) -> None:
        with self.lock:
            self.msgs.append((time.monotonic(), msg.linear.x, msg.angular.z))

    def _read(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            r, _, _ = select.select([self.master], [], [], 0.05)
            if r:
                try:
                    self.out += os.read(self.master, 4096)
                except OSError:
                    return

    def _wait_msgs(self, n: int, timeout: float = 10.0) -> None:
        end = time.monotonic() + timeout
        while time.monotonic() < end and len(self.msgs) < n:
            self._read(0.1)

    def test_keys(self) -> None:
        self._wait_msgs(5)
        self.assertGreaterEqual(len(self.msgs), 5, "no cmd_vel while idle")
        self.assertIn(b"CTRL-C to quit", self.out)
        for key in b"www":
            os.write(self.master, bytes([key]))
            self._read(0.15)
        os.write(self.master, b"a")
        self._read(1.5)
        with self.lock:
            last = self.msgs[-1]
        self.assertAlmostEqual(last[1], 0.03, places=6)
        self.assertAlmostEqual(last[2], 0.1, places=6)
        self.assertIn(b"linear vel 0.03", self.out)
        # about 10 Hz while idle (the loop's 0.1 s key timeout)
        with self.lock:
            recent = [m for m in self.msgs if m[0] > time.monotonic() - 1.0]
        self.assertTrue(6 <= len(recent) <= 12, f"{len(recent)} messages in 1 s")
        os.write(self.master, b" ")
        self._read(0.5)
        self.assertEqual(self.msgs[-1][1:], (0.0, 0.0))
        os.write(self.master, b"www\x03")
        end = time.monotonic() + 10.0
        while self.proc.poll() is None and time.monotonic() < end:
            self._read(0.1)
        self.assertEqual(self.proc.poll(), 0, self.out.decode(errors="replace")[-500:])
        time.sleep(0.3)
        with self.lock:
            self.assertEqual(self.msgs[-1][1:], (0.0, 0.0), "CTRL-C must send a zero command")


if __name__ == "__main__":
    rostest.rosrun("assign5", "teleop_test", TeleopTest)
