"""The laser's mounting, read in tf on the frame the odometry moves (tf2's buffer, no master)."""
from __future__ import annotations

import pytest
import rospy
import tf2_ros

from assign5.convert import BadMessage, transform_msg
from assign5.mounts import LaserMounts

pytestmark = pytest.mark.ros


def buffer_with(parent: str, child: str, x: float) -> tf2_ros.Buffer:
    buf = tf2_ros.Buffer(debug=False)   # debug: a service, which needs a master
    buf.set_transform_static(transform_msg(rospy.Time(0), parent, child, x, 0.0, 0.0), "test")
    return buf


def test_an_empty_base_frame_is_the_odometrys_child_frame():
    mounts = LaserMounts(buffer_with("base_link", "laser", 0.2), "", 0.0)
    with pytest.raises(BadMessage, match="no odometry received yet"):
        mounts.lookup("laser")
    assert mounts.odometry_frame("/base_link") is None          # a tf1-era leading slash is dropped
    (x, y, yaw), upside_down = mounts.lookup("laser")
    assert (x, y, yaw) == pytest.approx((0.2, 0.0, 0.0)) and not upside_down
    assert mounts.base_frame == "base_link"
    # a second source naming another frame is reported once; the base stays the first one's
    warning = mounts.odometry_frame("base_footprint")
    assert warning is not None and "'base_footprint'" in warning and "'base_link'" in warning
    assert mounts.odometry_frame("base_footprint") is None and mounts.base_frame == "base_link"


def test_odometry_without_a_child_frame_means_base_link():
    mounts = LaserMounts(buffer_with("base_link", "laser", -0.1), "", 0.0)
    mounts.odometry_frame("")
    assert mounts.lookup("laser")[0][0] == pytest.approx(-0.1)


def test_a_base_frame_set_by_hand_is_kept_and_named_when_tf_lacks_it():
    mounts = LaserMounts(buffer_with("base_link", "laser", 0.2), "base_footprint", 0.0)
    warning = mounts.odometry_frame("base_link")
    assert warning is not None and "set base_frame" in warning
    with pytest.raises(BadMessage) as err:
        mounts.lookup("laser")
    assert "no transform base_footprint -> 'laser'" in str(err.value)
    assert "base_frame is set to 'base_footprint'; the odometry moves 'base_link'" in str(err.value)
