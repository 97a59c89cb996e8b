#!/usr/bin/env python3
"""Relays a replayed bag's tf minus its recorded map -> odom (launch/replay.launch)."""
import rospy

from assign5.tf_relay import main

if __name__ == "__main__":
    try:
        main()
    except rospy.ROSInterruptException:
        pass
