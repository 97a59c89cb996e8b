"""Frontend: odometry interpolated at each scan's stamp, kidnaps, time going backwards, drop reasons."""
import numpy as np
import pytest

from fastslam.config import SlamConfig
from fastslam.filter.frontend import Dropped, Frontend, Kidnap, Reset
from fastslam.filter.scan import Scan
from fastslam.filter.slam import FastSlam

ANGLES = np.radians(np.arange(0, 360, 10.0))


def scan(t, r=1.0):
    return Scan(ranges=np.full(36, r), angles=ANGLES, range_min=0.1, range_max=3.5, stamp=t)


def front():
    return Frontend(FastSlam(SlamConfig(particles=3, seed=0, toggle_noise=0)))


def test_scan_uses_odometry_interpolated_at_its_stamp():
    f = front()
    f.add_odom(1.0, np.array([0.0, 0.0, 0.0]))
    f.add_odom(2.0, np.array([1.0, 0.0, 0.0]))
    f.add_scan(scan(1.0))
    f.add_scan(scan(1.5))
    np.testing.assert_allclose(f.slam.poses[:, 0], 0.5)
    np.testing.assert_allclose(f.last_odom, [0.5, 0.0, 0.0])


def test_drop_reasons():
    f = front()
    with pytest.raises(Dropped, match="no odometry received yet"):
        f.add_scan(scan(1.0))
    f.add_odom(1.0, np.zeros(3))
    with pytest.raises(Dropped, match="no odometry at the scan's time"):
        f.add_scan(scan(2.0))
    with pytest.raises(Dropped, match="stamped zero"):
        f.add_scan(scan(0.0))
    with pytest.raises(Dropped, match="NaN"):
        f.add_odom(1.1, np.array([np.nan, 0, 0]))


def test_kidnap_is_not_integrated():
    f = front()
    f.add_odom(1.0, np.zeros(3))
    f.add_scan(scan(1.0))
    f.add_odom(1.1, np.array([10.0, 0.0, 0.0]))   # 100 m/s
    f.add_odom(1.2, np.array([10.1, 0.0, 0.0]))
    f.add_scan(scan(1.2))
    (event,) = f.events
    assert isinstance(event, Kidnap)
    assert event.jump == pytest.approx(10.0) and event.seconds == pytest.approx(0.1)
    assert "kidnap" in str(event) and "10.00 m in 0.100 s" in str(event)
    np.testing.assert_allclose(f.slam.poses[:, 0], 0.0, atol=1e-12)  # the 10 m jump is not applied


def test_slow_sparse_odometry_is_not_a_kidnap():
    f = front()
    f.add_odom(1.0, np.zeros(3))
    f.add_scan(scan(1.0))
    f.add_odom(3.0, np.array([1.2, 0.0, 0.0]))    # 0.6 m/s over 2 s, like the Intel log
    f.add_scan(scan(3.0))
    assert f.events == []
    np.testing.assert_allclose(f.slam.poses[:, 0], 1.2)


def test_time_going_backwards_resets():
    f = front()
    for t in (1.0, 2.0):
        f.add_odom(t, np.array([t, 0.0, 0.0]))
        f.add_scan(scan(t))
    assert f.slam.updates == 2
    f.add_odom(0.5, np.array([0.0, 0.0, 0.0]))      # older than the buffer: ignored
    with pytest.raises(Dropped):
        f.add_scan(scan(0.5))                       # reset, then no odometry yet
    assert f.events == [Reset(previous=2.0, stamp=0.5)] and f.slam.updates == 0
    assert "time went backwards (2.00 -> 0.50 s)" in str(f.events[0])
    f.add_odom(0.5, np.zeros(3))
    assert f.add_scan(scan(0.5)).processed


def test_drop_key_counts_reasons_with_different_values_as_one():
    from fastslam.filter.frontend import drop_key

    a = drop_key("no odometry at the scan's time (latest odometry is +0.61 s newer)")
    b = drop_key("no odometry at the scan's time (latest odometry is -1.20 s newer)")
    assert a == b == "no odometry at the scan's time"      # the detail in parentheses is not the kind
    assert drop_key("no transform base -> 'laser' in tf: would extrapolate") == "no transform base -> 'laser' in tf"
    assert drop_key("odometry with NaN or inf") == "odometry with NaN or inf"


def test_a_scan_with_no_beam_in_the_field_of_view_is_dropped_with_the_reason():
    # the README's -30..30 degree tip with a laser mounted facing backwards
    slam = FastSlam(SlamConfig(fov_min=-30, fov_max=30, seed=0))
    fe = Frontend(slam)
    fe.add_odom(1.0, np.zeros(3))
    rear = Scan.from_laser(np.full(360, 1.0), -np.pi / 4, np.radians(0.25), 0.1, 3.5, mount=(0, 0, np.pi), stamp=1.0)
    with pytest.raises(Dropped, match=r"no beam in the field of view fov_min..fov_max = -30..30 deg "
                                      r"\(the scan sweeps from 135 to -135 deg"):
        fe.add_scan(rear)
    assert slam.updates == 0
    # the filter itself survives such a scan too (drivers that bypass the frontend)
    assert slam.step(np.zeros(3), rear).processed
    assert np.count_nonzero(slam.grid.logodds) == 0
