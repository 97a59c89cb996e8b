#!/usr/bin/env python3
"""`rosrun assign5 carmen_to_bag.py --help`: python -m fastslam.carmen_to_bag from a catkin workspace."""
import sys

from fastslam.carmen_to_bag import main

if __name__ == "__main__":
    sys.exit(main())
