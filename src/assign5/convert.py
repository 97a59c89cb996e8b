"""ROS messages <-> the core's numpy types. Pure functions, no node state."""
from __future__ import annotations

import math

import numpy as np
import rospy
from geometry_msgs.msg import Pose, PoseArray, PoseStamped, Quaternion, TransformStamped
from nav_msgs.msg import MapMetaData, OccupancyGrid, Path
from sensor_msgs.msg import LaserScan

from fastslam.filter.frontend import Dropped as BadMessage  # a message the node drops, str() says why
from fastslam.filter.grid import GridMaps
from fastslam.filter.scan import Scan, laser_problem
from fastslam.geometry import yaw_from_quaternion
from fastslam.transforms import mount_from_matrix, transform_matrix

from .packed import PackedGrid


def quaternion_from_yaw(yaw: float) -> Quaternion:
    return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))


def pose_msg(x: float, y: float, yaw: float) -> Pose:
    p = Pose()
    p.position.x, p.position.y = float(x), float(y)
    p.orientation = quaternion_from_yaw(float(yaw))
    return p


def transform_msg(stamp: rospy.Time, parent: str, child: str, x: float, y: float, yaw: float,
                  z: float = 0.0) -> TransformStamped:
    """A planar transform parent -> child."""
    t = TransformStamped()
    t.header.stamp, t.header.frame_id, t.child_frame_id = stamp, parent, child
    t.transform.translation.x, t.transform.translation.y, t.transform.translation.z = float(x), float(y), float(z)
    t.transform.rotation = quaternion_from_yaw(float(yaw))
    return t


def odom_pose(msg) -> np.ndarray:
    """(3,) x, y, yaw of a nav_msgs/Odometry; BadMessage if it cannot be used."""
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    values = (p.x, p.y, q.x, q.y, q.z, q.w)
    if not all(math.isfinite(v) for v in values):
        raise BadMessage("odometry with NaN or inf")
    if q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w < 1e-12:
        raise BadMessage("odometry with an all-zero quaternion")
    # A quaternion that is not normalised still has a well-defined heading.
    return np.array([p.x, p.y, yaw_from_quaternion(q.x, q.y, q.z, q.w)])


def check_scan(msg: LaserScan) -> None:
    """Rejects scans whose geometry is unusable (readings themselves are classified later)."""
    problem = laser_problem(len(msg.ranges), msg.angle_min, msg.angle_increment, msg.range_min,
                            msg.range_max, msg.angle_max)
    if problem:
        raise BadMessage(problem)


def scan_from_msg(msg: LaserScan, mount: tuple[float, float, float], upside_down: bool) -> Scan:
    return Scan.from_laser(np.asarray(msg.ranges, dtype=np.float64), msg.angle_min, msg.angle_increment,
                           msg.range_min, msg.range_max, mount=mount, upside_down=upside_down,
                           stamp=msg.header.stamp.to_sec())


def mount_from_transform(t: TransformStamped) -> tuple[tuple[float, float, float], bool]:
    """Laser pose (x, y, yaw) in the base frame and whether it is upside down (the
    offline runner's rule, fastslam.io.transforms), for a laser mounted flat."""
    tr, q = t.transform.translation, t.transform.rotation
    m = transform_matrix((tr.x, tr.y, tr.z), (q.x, q.y, q.z, q.w))
    if abs(abs(m[2, 2]) - 1) > 0.01:
        raise BadMessage("laser is not mounted planar (its z axis is not vertical)")
    mount = mount_from_matrix(m, t.header.frame_id, t.child_frame_id)
    return (mount.x, mount.y, mount.yaw), mount.upside_down


def grid_msgs(grid: GridMaps, n: int, frame: str, stamp: rospy.Time) -> tuple[OccupancyGrid, MapMetaData]:
    """OccupancyGrid and MapMetaData of particle n's map."""
    return occupancy_msgs(grid.occupancy(n), grid.resolution, grid.origin, frame, stamp)


def occupancy_msgs(occupancy: np.ndarray, resolution: float, origin: np.ndarray, frame: str,
                   stamp: rospy.Time) -> tuple[OccupancyGrid, MapMetaData]:
    """OccupancyGrid and MapMetaData of (H, W) int8 occupancy values."""
    h, w = occupancy.shape
    meta = MapMetaData(map_load_time=stamp, resolution=resolution, width=w, height=h)
    meta.origin = pose_msg(origin[0], origin[1], 0.0)
    msg = PackedGrid(info=meta)
    msg.header.frame_id, msg.header.stamp = frame, stamp
    msg.data = np.ascontiguousarray(occupancy, dtype=np.int8).ravel()   # serialised in one write
    return msg, meta


def pose_array(poses: np.ndarray, frame: str, stamp: rospy.Time) -> PoseArray:
    msg = PoseArray(poses=[pose_msg(*p) for p in poses])
    msg.header.frame_id, msg.header.stamp = frame, stamp
    return msg


def path_msg(traj: np.ndarray, frame: str, stamp: rospy.Time) -> Path:
    """traj: (T, 4) rows t, x, y, theta."""
    msg = Path()
    msg.header.frame_id, msg.header.stamp = frame, stamp
    for t, x, y, th in traj:
        ps = PoseStamped(pose=pose_msg(x, y, th))
        ps.header.frame_id, ps.header.stamp = frame, rospy.Time.from_sec(float(t))
        msg.poses.append(ps)
    return msg
