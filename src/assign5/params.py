"""Parameters of the nodes, each read through a typed config (fastslam.fields).

The SLAM node's private namespace holds both its ROS-only settings (NodeConfig, here)
and the algorithm's (SlamConfig); the launch files load config/node.yaml and one preset
(config/slam.yaml, burger.yaml, real.yaml) there. slam_gmapping's parameter names are
read as ours with a notice. Keys that name nothing are an error, like a bad value: the
node stops at start-up with one line naming the parameter.
"""
from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, field
from typing import Any, Mapping, NoReturn, TypeVar

from fastslam.config import SlamConfig, translate_gmapping
from fastslam.fields import ConfigError, check_fields, coerce
from fastslam.fields import num as _num
from fastslam.filter.budget import MAX_BEAMS, MAX_MAP_EXTENT, Limits, startup_problem
from fastslam.filter.scan_wait import ODOM_DELIVERY, ODOM_WAIT

T = TypeVar("T")
OPTIONAL_STRINGS = ("base_frame",)   # empty: taken from the input (see the field's doc)


@dataclass(frozen=True)
class NodeConfig:
    """Topics, frames, rates and safety limits of slam.py (names as slam_gmapping's)."""

    scan_topic: str = field(default="scan", metadata={"doc": "sensor_msgs/LaserScan input"})
    odom_topic: str = field(default="odom", metadata={"doc": "nav_msgs/Odometry input"})
    map_frame: str = field(default="map", metadata={"doc": "frame of the map and particles"})
    odom_frame: str = field(default="odom", metadata={"doc": "odometry frame; map->odom is published"})
    base_frame: str = field(default="", metadata={
        "doc": "robot frame the odometry moves, on which tf gives the laser's mount; empty: the odometry's "
               "child_frame_id (base_link if it names none), as the offline tool reads a bag"})
    map_update_interval: float = _num(2.0, 0.0, 3600.0, "seconds (of scan time) between map publications")
    transform_publish_period: float = _num(0.05, 0.0, 10.0, "map->odom broadcast period; 0 = never [s]")
    tf_delay: float = _num(0.05, 0.0, 10.0, "map->odom is stamped this far ahead, as gmapping does [s]")
    debug_maps: int = _num(0, 0, 1000, "also publish the maps of the K best particles on ~particle_map_<i>")
    map_file: str = field(default="assign5_map", metadata={
        "doc": "~save_map writes <map_file>.pgm/.yaml; a relative path is under $ROS_HOME (default ~/.ros)"})
    save_on_exit: bool = field(default=True, metadata={"doc": "save the map on shutdown (once something is mapped)"})
    odom_timeout: float = _num(0.5, 0.0, 60.0, "a scan this much newer than the latest odometry waits/drops [s]")
    odom_wait: float = _num(ODOM_WAIT, 0.0, 5.0, "odometry stamped up to this much after a scan is waited for (this "
                            f"and {ODOM_DELIVERY:g} s more of wall time) and interpolated with; later, the pose before "
                            "the scan is used (the offline tool: the same) [s]")
    odom_buffer: float = _num(10.0, 0.5, 600.0, "seconds of odometry kept for interpolation [s]")
    max_odom_speed: float = _num(5.0, 0.01, 1000.0, "odometry stepping faster than this between two messages is "
                                 "out of step: counted, kept, merged with the previous one [m/s]")
    max_odom_jump: float = _num(5.0, 0.01, 1e6, "odometry farther than this from the last second's is a kidnap [m]")
    reset_backwards: float = _num(1.0, 0.0, 1e6, "a scan stamped before the previous one by at most this is out "
                                  "of order (dropped, counted); by more, the filter resets, the map saved first [s]")
    max_beams: int = _num(MAX_BEAMS, 16, 10**7, "scans with more beams are evenly subsampled to this many")
    max_map_extent: float = _num(MAX_MAP_EXTENT, 1.0, 1e6, "the map never grows past this side length [m]")
    memory_limit_mb: float = _num(0.0, 0.0, 1e9, "memory the node may use; the maps never grow past it less a "
                                  "reserve; 0 = 80 % of the machine's (or the cgroup's or ulimit's) [MB]")
    max_future: float = _num(1.0, 0.0, 3600.0, "scans stamped further ahead of now are rejected [s]")
    tf_timeout: float = _num(0.2, 0.0, 10.0, "how long to wait for the laser's mounting in tf [s]")
    queue_size: int = _num(1, 1, 100, "scan subscriber queue; 1 drops scans the node cannot keep up with")
    no_scan_warning: float = _num(5.0, 0.0, 3600.0, "warn (once) when no scan came this long after start, "
                                  "naming the topics that carry LaserScan; 0 = never [s of wall time]")

    def __post_init__(self) -> None:
        check_fields(self)
        for f in dataclasses.fields(self):
            if f.type == "str" and not getattr(self, f.name) and f.name not in OPTIONAL_STRINGS:
                raise ConfigError(f"{f.name}='' must be a non-empty string")


def map_path(map_file: str) -> str:
    """map_file with ~ expanded; a relative one lies in $ROS_HOME (default ~/.ros, as
    rospkg.get_ros_home), which is made if missing."""
    path = os.path.expanduser(map_file)
    if os.path.isabs(path):
        return path
    home = os.environ.get("ROS_HOME") or os.path.join(os.path.expanduser("~"), ".ros")
    os.makedirs(home, exist_ok=True)
    return os.path.join(home, path)


@dataclass(frozen=True)
class RelayConfig:
    """tf_relay.py's private parameters: the transform map_frame -> odom_frame is dropped."""

    map_frame: str = field(default="map", metadata={"doc": "parent frame of the dropped transform"})
    odom_frame: str = field(default="odom", metadata={"doc": "child frame of the dropped transform"})


@dataclass(frozen=True)
class ReportConfig:
    """run_report.py's private parameters."""

    world_file: str = field(default="", metadata={"doc": "the simulated world's YAML (its spawn and walls)"})
    out: str = field(default="out/demo", metadata={"doc": "results folder"})
    settle: float = _num(10.0, 0.0, 600.0, "after the route: wait this long for the node's final map [s]")

    def __post_init__(self) -> None:
        check_fields(self)
        if not self.world_file:
            raise ConfigError("world_file='' must name the world's YAML file")


NODE_KEYS = {f.name for f in dataclasses.fields(NodeConfig)}
CORE_KEYS = {f.name for f in dataclasses.fields(SlamConfig)}


def split_params(params: Mapping[str, Any], notices: list[str] | None = None) -> tuple[NodeConfig, SlamConfig]:
    """Private parameters -> (NodeConfig, SlamConfig); raises ConfigError naming the key.
    One line per slam_gmapping name read is appended to notices."""
    ours, said = translate_gmapping(params)
    if notices is not None:
        notices.extend(said)
    unknown = sorted(set(ours) - NODE_KEYS - CORE_KEYS)
    if unknown:
        raise ConfigError(f"unknown parameter '{unknown[0]}'")
    node = NodeConfig(**coerce(NodeConfig, {k: v for k, v in ours.items() if k in NODE_KEYS}))
    core = SlamConfig.from_dict({k: v for k, v in ours.items() if k in CORE_KEYS}, notices=[])
    problem = startup_problem(core, limits(node, core))
    if problem:
        raise ConfigError(problem)
    return node, core


def limits(node: NodeConfig, core: SlamConfig) -> Limits:
    """The filter's bounds: max_map_extent, and the maps' share of memory_limit_mb."""
    return Limits.for_memory(node.memory_limit_mb, core.particles, node.max_beams, node.max_map_extent)


def _exit_on(err: Exception) -> NoReturn:
    import sys

    import rospy

    rospy.logfatal(f"{rospy.get_name()}: bad parameter: {err}")
    sys.exit(2)


def load() -> tuple[NodeConfig, SlamConfig]:
    """The SLAM node's ~ parameters; on a bad one logs it as fatal and exits non-zero."""
    import rospy

    notices: list[str] = []
    try:
        cfg = split_params(rospy.get_param("~", {}), notices)
    except ConfigError as err:
        _exit_on(err)
    for line in notices:
        rospy.loginfo(line)
    return cfg


def read(cls: type[T]) -> T:
    """A node's ~ parameters as the typed config cls (a dataclass with fields.num and
    choice fields); on a bad or unknown one logs it as fatal and exits non-zero."""
    import rospy

    try:
        return cls(**coerce(cls, rospy.get_param("~", {})))
    except ConfigError as err:
        _exit_on(err)
