"""Replays a bag's /tf without the map -> odom it recorded, so the live slam.py's own
map -> odom is the only one (remap the bag's /tf to tf_in)."""
from __future__ import annotations

import rospy
from tf2_msgs.msg import TFMessage

from . import params
from .params import RelayConfig


def main() -> None:
    rospy.init_node("tf_relay")
    cfg = params.read(RelayConfig)
    drop_child, drop_parent = cfg.odom_frame, cfg.map_frame
    pub = rospy.Publisher("/tf", TFMessage, queue_size=100)

    def relay(msg: TFMessage) -> None:
        kept = [t for t in msg.transforms
                if not (t.child_frame_id.lstrip("/") == drop_child and t.header.frame_id.lstrip("/") == drop_parent)]
        if kept:
            pub.publish(TFMessage(transforms=kept))

    rospy.Subscriber("tf_in", TFMessage, relay, queue_size=100)
    rospy.spin()
