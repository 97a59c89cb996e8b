"""Streaming ROS 1 bag writer for scans, odometry and tf (rosbags, imported lazily).

The noetic typestore of rosbags has no ``tf2_msgs/TFMessage``, so it is registered
here from its one-line definition (md5 94810edda583a504dfda3829e70d7eec, as in ROS).
"""
from __future__ import annotations

import math
import os
from pathlib import Path
from types import TracebackType
from typing import Any, Iterable

import numpy as np

from fastslam.io.records import ROSBAGS_HINT, BagError, OdomRecord, ScanRecord
from fastslam.transforms import StaticTransform

_TF_DEF = "geometry_msgs/TransformStamped[] transforms"


class BagWriter:
    """``with BagWriter(path) as w: w.static([...]); w.odom(rec); w.scan(rec)``.

    Messages must come in time order; the bag time of each is its stamp. Every
    odometry message is also broadcast as ``frame_id -> child_frame_id`` on /tf.
    """

    def __init__(self, path: str | os.PathLike[str], *, scan_topic: str = "/scan",
                 odom_topic: str = "/odom", publish_tf: bool = True) -> None:
        try:
            from rosbags.rosbag1 import Writer
            from rosbags.typesys import Stores, get_types_from_msg, get_typestore
        except ImportError as err:  # pragma: no cover - depends on the installation
            raise BagError(ROSBAGS_HINT) from err
        self.path = Path(path)
        if self.path.exists():
            raise BagError(f"{self.path} exists; rosbag1 writers only create new bags")
        self.ts = get_typestore(Stores.ROS1_NOETIC)
        self.ts.register(get_types_from_msg(_TF_DEF, "tf2_msgs/msg/TFMessage"))
        self.t = self.ts.types
        self.publish_tf = publish_tf
        self._writer = Writer(self.path)
        self._topics = (scan_topic, odom_topic)
        self._conn: dict[str, Any] = {}
        self._seq = {"scan": 0, "odom": 0}

    def __enter__(self) -> BagWriter:
        self._writer.open()
        scan_topic, odom_topic = self._topics
        add = self._writer.add_connection
        self._conn[scan_topic] = add(scan_topic, "sensor_msgs/msg/LaserScan", typestore=self.ts)
        self._conn[odom_topic] = add(odom_topic, "nav_msgs/msg/Odometry", typestore=self.ts)
        if self.publish_tf:
            self._conn["/tf"] = add("/tf", "tf2_msgs/msg/TFMessage", typestore=self.ts)
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self._writer.close()

    # message builders -------------------------------------------------------------
    def _time(self, t: float) -> Any:
        ns = int(round(t * 1e9))
        return self.t["builtin_interfaces/msg/Time"](sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)

    def _header(self, t: float, frame: str, seq: int = 0) -> Any:
        return self.t["std_msgs/msg/Header"](seq=seq, stamp=self._time(t), frame_id=frame)

    def _transform(self, t: float, parent: str, child: str, xyz: tuple[float, float, float],
                   q: tuple[float, float, float, float]) -> Any:
        T = self.t
        return T["geometry_msgs/msg/TransformStamped"](
            header=self._header(t, parent), child_frame_id=child,
            transform=T["geometry_msgs/msg/Transform"](
                translation=T["geometry_msgs/msg/Vector3"](x=xyz[0], y=xyz[1], z=xyz[2]),
                rotation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3])))

    def _write(self, topic: str, t: float, msg: Any, msgtype: str) -> None:
        if topic not in self._conn:   # an extra topic: connections can be added while open
            self._conn[topic] = self._writer.add_connection(topic, msgtype, typestore=self.ts)
        self._writer.write(self._conn[topic], int(round(t * 1e9)), self.ts.serialize_ros1(msg, msgtype))

    # public -------------------------------------------------------------------------
    def static(self, transforms: list[StaticTransform], t: float = 0.0) -> None:
        """Write all static transforms as one latched /tf_static message at time ``t``."""
        if not transforms:
            return
        conn = self._writer.add_connection("/tf_static", "tf2_msgs/msg/TFMessage", typestore=self.ts,
                                           latching=1)
        msg = self.t["tf2_msgs/msg/TFMessage"](transforms=[
            self._transform(t, s.parent, s.child, s.translation, s.rotation) for s in transforms])
        self._writer.write(conn, int(round(t * 1e9)), self.ts.serialize_ros1(msg, "tf2_msgs/msg/TFMessage"))

    def scan(self, rec: ScanRecord, topic: str | None = None) -> None:
        """One sensor_msgs/LaserScan (on ``topic`` if given, else the scan topic); no-return beams stay ``inf``."""
        ranges = np.asarray(rec.ranges, dtype=np.float32)
        msg = self.t["sensor_msgs/msg/LaserScan"](
            header=self._header(rec.t, rec.frame_id, self._seq["scan"]),
            angle_min=rec.angle_min, angle_max=rec.angle_min + rec.angle_increment * max(len(ranges) - 1, 0),
            angle_increment=rec.angle_increment, time_increment=0.0, scan_time=0.0,
            range_min=rec.range_min, range_max=rec.range_max,
            ranges=ranges, intensities=np.zeros(0, dtype=np.float32))
        self._seq["scan"] += 1
        self._write(topic or self._topics[0], rec.t, msg, "sensor_msgs/msg/LaserScan")

    def odom(self, rec: OdomRecord, topic: str | None = None) -> None:
        """One nav_msgs/Odometry (zero twist and covariances) and its /tf broadcast; on
        another ``topic`` than the odometry's (e.g. /ground_truth), no /tf."""
        T = self.t
        q = (0.0, 0.0, math.sin(rec.yaw / 2), math.cos(rec.yaw / 2))
        pose = T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=rec.x, y=rec.y, z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](x=q[0], y=q[1], z=q[2], w=q[3]))
        zero = T["geometry_msgs/msg/Vector3"](x=0.0, y=0.0, z=0.0)
        msg = T["nav_msgs/msg/Odometry"](
            header=self._header(rec.t, rec.frame_id, self._seq["odom"]), child_frame_id=rec.child_frame_id,
            pose=T["geometry_msgs/msg/PoseWithCovariance"](pose=pose, covariance=np.zeros(36)),
            twist=T["geometry_msgs/msg/TwistWithCovariance"](
                twist=T["geometry_msgs/msg/Twist"](linear=zero, angular=zero), covariance=np.zeros(36)))
        self._seq["odom"] += 1
        self._write(topic or self._topics[1], rec.t, msg, "nav_msgs/msg/Odometry")
        if self.publish_tf and topic in (None, self._topics[1]):
            tf = T["tf2_msgs/msg/TFMessage"](transforms=[
                self._transform(rec.t, rec.frame_id, rec.child_frame_id, (rec.x, rec.y, 0.0), q)])
            self._write("/tf", rec.t, tf, "tf2_msgs/msg/TFMessage")

    def tf(self, transforms: list[StaticTransform], t: float) -> None:
        """Broadcast transforms on /tf at time ``t`` (e.g. a mounting published the tf1 way)."""
        msg = self.t["tf2_msgs/msg/TFMessage"](transforms=[
            self._transform(t, s.parent, s.child, s.translation, s.rotation) for s in transforms])
        self._write("/tf", t, msg, "tf2_msgs/msg/TFMessage")


def write_bag(path: str | os.PathLike[str], scans: Iterable[ScanRecord], odoms: Iterable[OdomRecord], *,
              static_transforms: Iterable[StaticTransform] = (), publish_tf: bool = True,
              scan_topic: str = "/scan", odom_topic: str = "/odom") -> Path:
    """Write a ROS 1 bag: LaserScan, Odometry, /tf (odom -> base per odometry message)
    and latched /tf_static. Bag time = each message's stamp. ``path`` must not exist."""
    with BagWriter(path, scan_topic=scan_topic, odom_topic=odom_topic, publish_tf=publish_tf) as writer:
        records: list[ScanRecord | OdomRecord] = [*odoms, *scans]
        writer.static(list(static_transforms), t=min((r.t for r in records), default=0.0))
        # stable sort with odometry first keeps "odometry before the scan of the same instant"
        for rec in sorted(records, key=lambda r: r.t):
            if isinstance(rec, ScanRecord):
                writer.scan(rec)
            else:
                writer.odom(rec)
    return Path(path)
