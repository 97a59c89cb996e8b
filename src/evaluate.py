#!/usr/bin/env python3
"""`rosrun assign5 evaluate.py --help`: python -m fastslam.evaluate from a catkin workspace."""
import sys

from fastslam.evaluate import main

if __name__ == "__main__":
    sys.exit(main())
