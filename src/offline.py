#!/usr/bin/env python3
"""`rosrun assign5 offline.py --help`: python -m fastslam.offline from a catkin workspace."""
import sys

from fastslam.offline import main

if __name__ == "__main__":
    sys.exit(main())
