"""Message conversions of the node (rospy message classes, no master needed)."""
import math

import numpy as np
import pytest
import rospy
from geometry_msgs.msg import TransformStamped
from nav_msgs.msg import Odometry
from sensor_msgs.msg import LaserScan

from assign5.convert import BadMessage, check_scan, grid_msgs, mount_from_transform, odom_pose, scan_from_msg
from fastslam.filter.grid import GridMaps

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
