"""Message conversions of the node (rospy message classes, no master needed)."""
from __future__ import annotations

import math

import numpy as np
import pytest
import rospy
from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import LaserScan

from assign5.convert import (
    BadMessage,
    check_scan,
    grid_msgs,
    mount_from_transform,
    occupancy_msgs,
    odom_pose,
    path_msg,
    pose_array,
    pose_msg,
    quaternion_from_yaw,
    scan_from_msg,
    transform_msg,
)
from fastslam.filter.grid import GridMaps
from fastslam.geometry import yaw_from_quaternion

pytestmark = pytest.mark.ros


def transform(x, y, q):
    t = TransformStamped()
    t.transform.translation.x, t.transform.translation.y = x, y
    r = t.transform.rotation
    r.x, r.y, r.z, r.w = q
    return t


def test_upright_and_upside_down_mounts():
    yaw = 0.3
    mount, flipped = mount_from_transform(transform(-0.032, 0.01, (0, 0, math.sin(yaw / 2), math.cos(yaw / 2))))
    assert not flipped and mount == pytest.approx((-0.032, 0.01, 0.3))
    # roll pi, then yaw 0.3: Rz(yaw) Rx(pi) = (cos(yaw/2), sin(yaw/2), 0, 0)
    mount, flipped = mount_from_transform(transform(0.1, 0.0, (math.cos(yaw / 2), math.sin(yaw / 2), 0, 0)))
    assert flipped and mount == pytest.approx((0.1, 0.0, 0.3))
    with pytest.raises(BadMessage, match="planar"):
        mount_from_transform(transform(0, 0, (math.sin(0.4), 0, 0, math.cos(0.4))))  # tilted 46 degrees


def test_upside_down_laser_sees_the_world_mirrored():
    msg = LaserScan(angle_min=0.0, angle_increment=math.pi / 2, angle_max=math.pi * 1.5,
                    range_min=0.1, range_max=5.0, ranges=[1.0, 2.0, 3.0, 4.0])
    msg.header.stamp = rospy.Time(5)
    up = scan_from_msg(msg, (0.0, 0.0, 0.0), False)
    down = scan_from_msg(msg, (0.0, 0.0, 0.0), True)
    np.testing.assert_allclose(np.cos(up.angles), [1, 0, -1, 0], atol=1e-12)
    np.testing.assert_allclose(np.sin(up.angles), [0, 1, 0, -1], atol=1e-12)
    np.testing.assert_allclose(np.sin(down.angles), [0, -1, 0, 1], atol=1e-12)  # beam 1 points right
    assert up.stamp == 5.0


def test_odometry_pose_and_bad_odometry():
    o = Odometry()
    o.pose.pose.position.x, o.pose.pose.position.y = 1.0, 2.0
    q = o.pose.pose.orientation
    q.z, q.w = 2 * math.sin(0.25), 2 * math.cos(0.25)  # heading 0.5, not normalised
    np.testing.assert_allclose(odom_pose(o), [1.0, 2.0, 0.5])
    q.z = q.w = 0.0
    with pytest.raises(BadMessage, match="zero quaternion"):
        odom_pose(o)
    o.pose.pose.position.x = float("nan")
    with pytest.raises(BadMessage, match="NaN"):
        odom_pose(o)


def test_check_scan_rejects_geometry_not_readings():
    ok = LaserScan(angle_min=0.0, angle_increment=0.1, angle_max=0.9, range_min=0.1, range_max=3.0,
                   ranges=[float("nan")] * 10)
    check_scan(ok)
    ok.angle_max = 5.0
    with pytest.raises(BadMessage, match="10 ranges"):
        check_scan(ok)


def test_grid_message_layout():
    grid = GridMaps(2, (3, 4), 0.5, (-1.0, -0.5))
    grid.logodds[1, 0, 3] = 127
    grid.logodds[1, 2, 0] = -127
    msg, meta = grid_msgs(grid, 1, "map", rospy.Time(1))
    assert (meta.width, meta.height, meta.resolution) == (4, 3, 0.5)
    assert (meta.origin.position.x, meta.origin.position.y) == (-1.0, -0.5)
    data = np.array(msg.data).reshape(3, 4)  # row-major, row 0 at the origin
    assert data[0, 3] == 99 and data[2, 0] == 1 and (data == -1).sum() == 10
    assert msg.header.frame_id == "map"


def test_published_maps_are_the_same_with_dense_and_tiled_storage():
    # /map, dynamic_map and ~particle_map_<i> are grid_msgs of the best and other
    # particles: the filter on shared tiles publishes what the dense grids did.
    from fastslam import simrun
    from fastslam.config import SlamConfig
    from fastslam.filter.slam import FastSlam
    from fastslam.filter.tiles import TileMaps

    cfg = SlamConfig(particles=5, seed=2)
    runs = {}
    for storage in (GridMaps, TileMaps):
        saved, FastSlam.maps_type = FastSlam.maps_type, storage
        try:
            runs[storage] = simrun.run("room", cfg, seed=2, max_time=20.0).slam
        finally:
            FastSlam.maps_type = saved
    dense, tiled = runs[GridMaps], runs[TileMaps]
    assert isinstance(tiled.grid, TileMaps) and tiled.best == dense.best
    for i in range(cfg.particles):
        a, meta_a = grid_msgs(dense.grid, i, "map", rospy.Time(3))
        b, meta_b = grid_msgs(tiled.grid, i, "map", rospy.Time(3))
        assert a == b and meta_a == meta_b
    assert (np.array(b.data) >= 0).sum() > 1000                            # a map, not an empty one


def test_planar_poses_and_transforms():
    q = quaternion_from_yaw(0.5)
    assert (q.x, q.y, q.z, q.w) == (0.0, 0.0, math.sin(0.25), math.cos(0.25))
    p = pose_msg(1, 2, -3.0)
    assert (p.position.x, p.position.y, p.position.z) == (1.0, 2.0, 0.0)
    assert yaw_from_quaternion(p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w) == \
        pytest.approx(-3.0)
    t = transform_msg(rospy.Time(2, 5), "map", "odom", 0.5, -0.5, math.pi, z=0.1)
    assert (t.header.frame_id, t.child_frame_id, t.header.stamp) == ("map", "odom", rospy.Time(2, 5))
    assert (t.transform.translation.x, t.transform.translation.y, t.transform.translation.z) == (0.5, -0.5, 0.1)
    assert t.transform.rotation.z == pytest.approx(1.0)
    # the node's mounting rule reads it back
    assert mount_from_transform(t) == ((0.5, -0.5, pytest.approx(math.pi)), False)


def test_particles_and_path_messages():
    poses = np.array([[0.0, 1.0, 0.0], [2.0, 3.0, math.pi / 2]])
    msg = pose_array(poses, "map", rospy.Time(3))
    assert len(msg.poses) == 2 and msg.header.frame_id == "map" and msg.header.stamp == rospy.Time(3)
    assert (msg.poses[1].position.x, msg.poses[1].position.y) == (2.0, 3.0)
    assert msg.poses[1].orientation.z == pytest.approx(math.sqrt(0.5))
    path = path_msg(np.array([[10.5, 0.0, 0.0, 0.0], [11.0, 1.0, 0.5, 0.2]]), "map", rospy.Time(12))
    assert [p.header.stamp for p in path.poses] == [rospy.Time(10, 500000000), rospy.Time(11)]
    assert path.poses[1].pose.position.y == 0.5 and path.header.stamp == rospy.Time(12)


def test_occupancy_message_carries_values_as_they_are():
    occ = np.array([[-1, 0], [50, 100]], dtype=np.int8)
    msg, meta = occupancy_msgs(occ, 0.1, np.array([2.0, -3.0]), "map", rospy.Time(4))
    assert list(msg.data) == [-1, 0, 50, 100]
    assert (meta.width, meta.height, meta.resolution, meta.map_load_time) == (2, 2, 0.1, rospy.Time(4))
    assert (meta.origin.position.x, meta.origin.position.y, meta.origin.orientation.w) == (2.0, -3.0, 1.0)
    assert msg.info is meta
