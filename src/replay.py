#!/usr/bin/env python3
"""Plays a bag into slam.py and ends the launch at its end (launch/replay.launch)."""
import rospy

from assign5.replay import main

if __name__ == "__main__":
    try:
        main()
    except rospy.ROSInterruptException:
        pass
