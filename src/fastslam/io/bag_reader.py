"""ROS 1 bags, with or without ROS: read scans, odometry, a reference trajectory and
the laser mounting.

Two readers give the same records: ``rosbags`` (pure Python, Python 3.8+; 0.10+ needs
3.10) where it is installed, else ROS's own ``rosbag`` Python API (ROS Noetic, Debian's
python3-rosbag). Both are imported lazily, so the rest of ``fastslam`` works without
them. Times are header stamps in seconds (float); poses are 2D.
"""
from __future__ import annotations

import logging
import os
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Iterator, Tuple

import numpy as np

from fastslam.filter.scan_wait import ScanWait
from fastslam.io.records import BAG_LIBRARY_HINT, BagError, OdomRecord, ScanRecord
from fastslam.transforms import LaserMount, mount_from_matrix, transform_matrix

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


__all__ = ["READERS", "BagData", "BagError", "OdomRecord", "ScanRecord", "laser_mount", "read_bag"]

log = logging.getLogger(__name__)

SCAN_TYPE = "sensor_msgs/msg/LaserScan"
ODOM_TYPE = "nav_msgs/msg/Odometry"
TF_TYPE = "tf2_msgs/msg/TFMessage"
REFERENCE_TOPIC = "/ground_truth"   # the simulator's true pose (nav_msgs/Odometry), recorded by burger.launch
READERS = ("rosbags", "rosbag")
DEFAULT_BASE_FRAME = "base_link"   # REP 105's robot frame: odometry naming no child frame moves it
Message = Tuple[str, str, Any]      # topic, type (rosbags' spelling: pkg/msg/Name), message


@dataclass
class BagData:
    """Everything the offline SLAM needs from a bag, each list sorted by time."""

    scans: list[ScanRecord]
    odoms: list[OdomRecord]
    mount: LaserMount
    scan_topic: str
    odom_topic: str
    topics: dict[str, str] = field(default_factory=dict)  # topic -> message type
    reference: list[OdomRecord] = field(default_factory=list)  # REFERENCE_TOPIC's poses, if the bag has it
    reader: str = ""                                         # the library that read it (READERS)
    bad_tf: list[tuple[str, str]] = field(default_factory=list)  # (parent, child) seen only with a zero quaternion

    def records(self, odom_wait: float = 0.0) -> Iterator[ScanRecord | OdomRecord]:
        """Scans and odometry in the order the node handles them, played at their own speed.

        Merged in time order, odometry first on equal stamps. With odom_wait > 0, a scan
        comes where the node handles it (filter/scan_wait.py): after the first odometry
        stamped at or after it, if that is stamped at most odom_wait after it.
        """
        waits: ScanWait[ScanRecord] = ScanWait(odom_wait)
        i = j = 0
        while i < len(self.scans) or j < len(self.odoms):
            if j < len(self.odoms) and (i >= len(self.scans) or self.odoms[j].t <= self.scans[i].t):
                odom = self.odoms[j]
                j += 1
                yield from waits.due(odom.t)
                yield odom
                yield from waits.odometry(odom.t)
            else:
                scan = self.scans[i]
                i += 1
                yield from waits.due(scan.t)
                yield from waits.scan(scan.t, scan)
        yield from waits.rest()

    def odom_poses(self) -> NDArray[np.float64]:
        """(T, 4) float64 rows (t, x, y, yaw)."""
        return np.array([[o.t, o.x, o.y, o.yaw] for o in self.odoms], dtype=np.float64).reshape(-1, 4)


def _stamp(header: Any) -> float:
    stamp = header.stamp
    if hasattr(stamp, "nanosec"):   # rosbags
        return float(stamp.sec) + 1e-9 * float(stamp.nanosec)
    return float(stamp.secs) + 1e-9 * float(stamp.nsecs)   # rosbag (genpy)


def pick_reader(wanted: str | None = None) -> str:
    """The bag library to use: ``wanted``, or the first of READERS that imports."""
    for name in [wanted] if wanted else READERS:
        try:
            __import__(name)
        except ImportError:
            continue
        return name
    raise BagError(f"{wanted} is not installed" if wanted else BAG_LIBRARY_HINT)


def _rosbags_messages(path: Path, choose: Any) -> Iterator[Message]:
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.typesys import Stores, get_typestore

    try:
        with AnyReader([path], default_typestore=get_typestore(Stores.ROS1_NOETIC)) as reader:
            wanted = choose({c.topic: c.msgtype for c in reader.connections})
            conns = [c for c in reader.connections if c.topic in wanted]
            for conn, _, raw in reader.messages(connections=conns):
                yield conn.topic, conn.msgtype, reader.deserialize(raw, conn.msgtype)
    except AnyReaderError as err:
        raise BagError(f"cannot read bag {path}: {err}") from err
    except BagError:
        raise
    except Exception as err:  # rosbags on what is not a ROS 1 bag (random bytes, MCAP, ROS 2)
        raise BagError(f"{path} is not a readable ROS 1 bag ({type(err).__name__}: {err}); "
                       "ROS 2 and MCAP bags are not supported") from None


def _rosbag_messages(path: Path, choose: Any) -> Iterator[Message]:
    import rosbag

    try:
        with rosbag.Bag(str(path)) as bag:
            # ROS spells types pkg/Name; rosbags (and this module) pkg/msg/Name
            types = {t: v.msg_type.replace("/", "/msg/", 1) for t, v in bag.get_type_and_topic_info().topics.items()}
            wanted = choose(types)
            for topic, msg, _ in bag.read_messages(topics=sorted(wanted)):
                yield topic, types[topic], msg
    except (rosbag.ROSBagException, OSError, ValueError) as err:
        raise BagError(f"cannot read bag {path}: {err}") from err
    except BagError:
        raise
    except Exception as err:  # rosbag on what is not a ROS 1 bag
        raise BagError(f"{path} is not a readable ROS 1 bag ({type(err).__name__}: {err}); "
                       "ROS 2 and MCAP bags are not supported") from None


CONVENTIONAL = {SCAN_TYPE: "/scan", ODOM_TYPE: "/odom"}


def _pick(topics: dict[str, str], msgtype: str, wanted: str | None, what: str) -> str:
    listing = ", ".join(f"{t} [{m}]" for t, m in sorted(topics.items())) or "(none)"
    if wanted is not None:
        if topics.get(wanted) != msgtype:
            raise BagError(f"{what} topic {wanted!r} with type {msgtype} not in the bag; topics: {listing}")
        return wanted
    found = [t for t, m in topics.items() if m == msgtype]
    if not found:
        raise BagError(f"no {msgtype} topic in the bag; topics: {listing}")
    if len(found) > 1 and CONVENTIONAL.get(msgtype) in found:
        # e.g. /odom beside the simulator's /ground_truth: the conventional name wins
        log.info("%d %s topics; using %s", len(found), msgtype, CONVENTIONAL[msgtype])
        return CONVENTIONAL[msgtype]
    if len(found) > 1:
        raise BagError(f"{len(found)} {msgtype} topics, name the {what} topic to use; topics: {listing}")
    return found[0]


def read_bag(path: str | os.PathLike[str], scan_topic: str | None = None,
             odom_topic: str | None = None, *, reader: str | None = None) -> BagData:
    """Read scans, odometry, the reference (REFERENCE_TOPIC) and the laser mounting of a ROS 1 bag.

    Args:
        path: the ``.bag`` file.
        scan_topic, odom_topic: None = the only LaserScan / Odometry topic in the bag.
        reader: "rosbags" or "rosbag"; None = the first installed (see :func:`pick_reader`).

    Raises:
        BagError: no bag library, unreadable bag, or the topics are missing or ambiguous
            (the message lists every topic and its type).
    """
    reader = pick_reader(reader)
    path = Path(path)
    if not path.is_file():
        raise BagError(f"no bag at {path}")
    topics: dict[str, str] = {}
    chosen: list[str] = []

    def choose(found: dict[str, str]) -> set[str]:
        topics.update(found)
        chosen.append(_pick(found, SCAN_TYPE, scan_topic, "scan"))
        chosen.append(_pick(found, ODOM_TYPE, odom_topic, "odometry"))
        reference = [REFERENCE_TOPIC] if found.get(REFERENCE_TOPIC) == ODOM_TYPE else []
        return {*chosen, *reference, "/tf", "/tf_static"}

    messages = _rosbags_messages if reader == "rosbags" else _rosbag_messages
    data = _collect(messages(path, choose), choose_result=chosen)
    return BagData(scans=data[0], odoms=data[1], mount=data[3], scan_topic=chosen[0], odom_topic=chosen[1],
                   topics=topics, reference=data[2], reader=reader, bad_tf=data[4])


def _collect(messages: Iterable[Message], choose_result: list[str]
             ) -> tuple[list[ScanRecord], list[OdomRecord], list[OdomRecord], LaserMount, list[tuple[str, str]]]:
    """Records from (topic, type, message) in bag order, each list then sorted by stamp."""
    scans: list[ScanRecord] = []
    odoms: list[OdomRecord] = []
    reference: list[OdomRecord] = []
    static_edges: dict[tuple[str, str], NDArray[np.float64]] = {}
    dynamic_edges: dict[tuple[str, str], NDArray[np.float64]] = {}
    bad_tf: set[tuple[str, str]] = set()
    for topic, msgtype, msg in messages:
        scan_topic, odom_topic = choose_result
        if topic == scan_topic:
            scans.append(_scan_record(msg))
        elif topic == odom_topic:
            odoms.append(_odom_record(msg))
        elif topic == REFERENCE_TOPIC and msgtype == ODOM_TYPE:
            reference.append(_odom_record(msg))
        elif msgtype == TF_TYPE:
            edges = static_edges if topic == "/tf_static" else dynamic_edges
            for tf in msg.transforms:
                key = (tf.header.frame_id, tf.child_frame_id)
                if key in edges:
                    continue
                try:
                    edges[key] = _tf_matrix(tf.transform)
                except ValueError:  # a zero quaternion: the edge is unusable, not the bag
                    bad_tf.add(key)
    scans.sort(key=lambda s: s.t)
    odoms.sort(key=lambda o: o.t)
    reference.sort(key=lambda o: o.t)
    base = (odoms[0].child_frame_id if odoms else "") or DEFAULT_BASE_FRAME   # the frame the odometry moves
    laser = scans[0].frame_id if scans else "laser"
    odom_frame = odoms[0].frame_id if odoms else "odom"
    # the odometry edge itself is dynamic and must not be part of the mounting chain
    edges = {k: v for k, v in dynamic_edges.items() if k[1] != base and k != (odom_frame, base)}
    edges.update(static_edges)
    return scans, odoms, reference, laser_mount(edges, base, laser), sorted(bad_tf - set(edges))


def _scan_record(msg: Any) -> ScanRecord:
    return ScanRecord(t=_stamp(msg.header), ranges=np.asarray(msg.ranges, dtype=np.float32).copy(),
                      angle_min=float(msg.angle_min), angle_increment=float(msg.angle_increment),
                      range_min=float(msg.range_min), range_max=float(msg.range_max),
                      frame_id=msg.header.frame_id)


def _odom_record(msg: Any) -> OdomRecord:
    from fastslam.geometry import yaw_from_quaternion

    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    return OdomRecord(t=_stamp(msg.header), x=float(p.x), y=float(p.y),
                      yaw=yaw_from_quaternion(q.x, q.y, q.z, q.w),
                      child_frame_id=msg.child_frame_id, frame_id=msg.header.frame_id)


def _tf_matrix(transform: Any) -> NDArray[np.float64]:
    t, q = transform.translation, transform.rotation
    return transform_matrix((t.x, t.y, t.z), (q.x, q.y, q.z, q.w))


def laser_mount(edges: dict[tuple[str, str], NDArray[np.float64]], base_frame: str,
                laser_frame: str) -> LaserMount:
    """Pose of ``laser_frame`` in ``base_frame`` from (parent, child) -> 4x4 transforms.

    The chain may go up and down the tree (edges are used in either direction). With
    no chain, the laser is assumed at the base origin (``found=False``, logged).
    """
    if base_frame == laser_frame:
        return mount_from_matrix(np.eye(4), base_frame, laser_frame, found=True)
    neighbours: dict[str, list[tuple[str, NDArray[np.float64]]]] = {}
    for (parent, child), m in edges.items():
        neighbours.setdefault(parent, []).append((child, m))
        neighbours.setdefault(child, []).append((parent, np.linalg.inv(m)))
    # breadth-first from the base, carrying the base->frame transform
    seen = {base_frame: np.eye(4)}
    queue = deque([base_frame])
    while queue:
        frame = queue.popleft()
        for nxt, m in neighbours.get(frame, []):
            if nxt not in seen:
                seen[nxt] = seen[frame] @ m
                queue.append(nxt)
    if laser_frame not in seen:
        log.warning("no transform chain %s -> %s in the bag; assuming the laser at the base origin",
                    base_frame, laser_frame)
        return mount_from_matrix(np.eye(4), base_frame, laser_frame, found=False)
    return mount_from_matrix(seen[laser_frame], base_frame, laser_frame, found=True)
