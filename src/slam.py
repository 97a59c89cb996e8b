#!/usr/bin/env python3
"""FastSLAM node (CS-475 assignment 5): scan + odom in, map, particles and map->odom out."""
import rospy

from assign5 import params
from assign5.slam_node import SlamNode


def main() -> None:
    rospy.init_node("slam")
    node_cfg, slam_cfg = params.load()
    SlamNode(node_cfg, slam_cfg)
    rospy.spin()


if __name__ == "__main__":
    try:
        main()
    except rospy.ROSInterruptException:
        pass
