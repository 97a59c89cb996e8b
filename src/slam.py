#!/usr/bin/env python3
"""FastSLAM node (CS-475 assignment 5): scan + odom in, map, particles and map->odom out."""
import sys

import rospy

from assign5 import params
from assign5.malloc import one_malloc_arena
from assign5.signals import init_node
from assign5.slam_node import SlamNode


def main() -> int:
    one_malloc_arena()  # before rospy starts its threads
    init_node("slam")  # SIGTERM during start-up hung rospy's own shutdown (assign5/signals.py)
    node_cfg, slam_cfg = params.load()
    try:
        node = SlamNode(node_cfg, slam_cfg)
    except MemoryError:
        rospy.logfatal(f"{rospy.get_name()}: out of memory allocating {slam_cfg.particles} maps of "
                       f"{slam_cfg.map_width:g} x {slam_cfg.map_height:g} m: set memory_limit_mb to what this "
                       "machine can give, or use fewer particles or a smaller map")
        return 2
    rospy.spin()
    return 1 if node.fatal else 0  # an error stopped processing: required="true" fires


if __name__ == "__main__":
    try:
        sys.exit(main())
    except rospy.ROSInterruptException:
        pass
