#!/usr/bin/env python3
"""Evaluates a simulator run at its route's end: out/<run>/map.pgm, map.yaml, map.png, metrics.json."""
import rospy

from assign5.run_report import main

if __name__ == "__main__":
    try:
        main()
    except rospy.ROSInterruptException:
        pass
