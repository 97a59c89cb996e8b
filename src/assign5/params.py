"""Parameters of the SLAM node: ROS-only settings here, the algorithm's in SlamConfig.

Both come from the node's private namespace (launch files load config/slam.yaml and
config/node.yaml there); keys that name neither are an error, like a bad value.
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any, Mapping

from fastslam.config import SlamConfig
from fastslam.fields import ConfigError, check_fields, coerce
from fastslam.fields import num as _num


@dataclass(frozen=True)
class NodeConfig:
    """Topics, frames, rates and safety limits of slam.py (names as slam_gmapping's)."""

    scan_topic: str = field(default="scan", metadata={"doc": "sensor_msgs/LaserScan input"})
    odom_topic: str = field(default="odom", metadata={"doc": "nav_msgs/Odometry input"})
    map_frame: str = field(default="map", metadata={"doc": "frame of the map and particles"})
    odom_frame: str = field(default="odom", metadata={"doc": "odometry frame; map->odom is published"})
    base_frame: str = field(default="base_footprint", metadata={"doc": "robot frame the odometry moves"})
    map_update_interval: float = _num(2.0, 0.0, 3600.0, "seconds (of scan time) between map publications")
    transform_publish_period: float = _num(0.05, 0.0, 10.0, "map->odom broadcast period; 0 = never [s]")
    tf_delay: float = _num(0.05, 0.0, 10.0, "map->odom is stamped this far ahead, as gmapping does [s]")
    debug_maps: int = _num(0, 0, 1000, "also publish the maps of the K best particles on ~particle_map_<i>")
    map_file: str = field(default="~/.ros/assign5_map", metadata={"doc": "~save_map writes <map_file>.pgm/.yaml"})
    save_on_exit: bool = field(default=False, metadata={"doc": "save the map on shutdown"})
    odom_timeout: float = _num(0.5, 0.0, 60.0, "a scan this much newer than the latest odometry waits/drops [s]")
    odom_wait: float = _num(0.1, 0.0, 5.0, "wall time a scan waits for odometry at its stamp [s]")
    odom_buffer: float = _num(10.0, 0.5, 600.0, "seconds of odometry kept for interpolation [s]")
    max_odom_speed: float = _num(5.0, 0.01, 1000.0, "odometry stepping faster than this between two messages is "
                                 "out of step: counted, kept, merged with the previous one [m/s]")
    max_odom_jump: float = _num(5.0, 0.01, 1e6, "odometry farther than this from the last second's is a kidnap [m]")
    max_future: float = _num(1.0, 0.0, 3600.0, "scans stamped further ahead of now are rejected [s]")
    tf_timeout: float = _num(0.2, 0.0, 10.0, "how long to wait for the laser's mounting in tf [s]")
    queue_size: int = _num(1, 1, 100, "scan subscriber queue; 1 drops scans the node cannot keep up with")

    def __post_init__(self) -> None:
        check_fields(self)
        for f in dataclasses.fields(self):
            if f.type == "str" and not getattr(self, f.name):
                raise ConfigError(f"{f.name}='' must be a non-empty string")


NODE_KEYS = {f.name for f in dataclasses.fields(NodeConfig)}
CORE_KEYS = {f.name for f in dataclasses.fields(SlamConfig)}


def split_params(params: Mapping[str, Any]) -> tuple[NodeConfig, SlamConfig]:
    """Private parameters -> (NodeConfig, SlamConfig); raises ConfigError naming the key."""
    unknown = sorted(set(params) - NODE_KEYS - CORE_KEYS)
    if unknown:
        raise ConfigError(f"unknown parameter '{unknown[0]}'")
    node = NodeConfig(**coerce(NodeConfig, {k: v for k, v in params.items() if k in NODE_KEYS}))
    core = SlamConfig.from_dict({k: v for k, v in params.items() if k in CORE_KEYS})
    return node, core


def load() -> tuple[NodeConfig, SlamConfig]:
    """Reads ~ parameters; on a bad one logs it as fatal and exits non-zero."""
    import sys

    import rospy

    params = rospy.get_param("~", {})
    try:
        return split_params(params)
    except ConfigError as err:
        rospy.logfatal(f"{rospy.get_name()}: bad parameter: {err}")
        sys.exit(2)
