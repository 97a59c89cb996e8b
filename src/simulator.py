#!/usr/bin/env python3
"""2D TurtleBot3 burger simulator (no Gazebo): cmd_vel in; scan, odom, tf, ground_truth, /clock out."""
import rospy

from assign5 import sim_node


def main() -> None:
    rospy.init_node("simulator")
    cfg, world, route = sim_node.load()
    sim_node.SimNode(cfg, world, route).run()


if __name__ == "__main__":
    try:
        main()
    except rospy.ROSInterruptException:
        pass
