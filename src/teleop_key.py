#!/usr/bin/env python3
"""Keyboard teleop for the burger (like turtlebot3_teleop_key): w/x a/d s/space, CTRL-C quits."""
import sys
import time

import rospy

from assign5 import params
from assign5.teleop_node import TeleopConfig, TeleopNode


def main() -> int:
    if not sys.stdin.isatty():
        print("teleop_key: stdin is not a terminal; run it in a terminal (roslaunch assign5 teleop.launch)",
              file=sys.stderr)
        return 1
    rospy.init_node("teleop_key")
    node = TeleopNode(params.read(TeleopConfig))
    time.sleep(0.3)   # let cmd_vel subscribers connect before the first command
    node.run()
    return 0


if __name__ == "__main__":
    sys.exit(main())
