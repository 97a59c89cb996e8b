"""Replays a bag's /tf without the map -> odom it recorded, so the live slam.py's own
map -> odom is the only one (remap the bag's /tf to tf_in)."""
from __future__ import annotations

from dataclasses import dataclass, field

import rospy
from tf2_msgs.msg import TFMessage

from . import params


@dataclass(frozen=True)
class RelayConfig:
    """tf_relay.py's private parameters: the transform map_frame -> odom_frame is dropped."""

    map_frame: str = field(default="map", metadata={"doc": "parent frame of the dropped transform"})
    odom_frame: str = field(default="odom", metadata={"doc": "child frame of the dropped transform"})


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
