"""Frontend: odometry interpolated at each scan's stamp, kidnaps, time going backwards, drop reasons."""
import numpy as np
import pytest

from fastslam.config import SlamConfig
from fastslam.filter.frontend import Dropped, Frontend, Kidnap, Notice, Reset
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
    assert event.jump == pytest.approx(10.0) and event.max_jump == 5.0 and event.count == 1
    assert str(event) == ("odometry jumped 10.00 m (> max_odom_jump 5.0 m): treating it as a kidnap, "
                          "the jump is not integrated")
    np.testing.assert_allclose(f.slam.poses[:, 0], 0.0, atol=1e-12)  # the 10 m jump is not applied


def test_a_kidnap_is_judged_by_distance_whatever_the_time():
    f = front()
    f.add_odom(1.0, np.zeros(3))
    f.add_scan(scan(1.0))
    f.add_odom(201.0, np.array([1000.0, 0.0, 0.0]))   # 1 km after 200 s of silence: 5 m/s
    f.add_odom(201.1, np.array([1000.1, 0.0, 0.0]))
    f.add_scan(scan(201.1))
    assert f.counts == {"odometry kidnap": 1} and isinstance(f.events[0], Kidnap)
    np.testing.assert_allclose(f.slam.poses[:, 0], 0.0, atol=1e-12)


def test_a_fast_step_with_made_up_stamps_is_motion():
    # A log without stamps (spaced 1 ms by the converter) steps 3.5 m between scans.
    f = front()
    for i in range(4):
        f.add_odom(1.0 + 0.001 * i, np.array([3.5 * i, 0.0, 0.0]))
        f.add_scan(scan(1.0 + 0.001 * i))
    np.testing.assert_allclose(f.slam.poses[:, 0], 10.5)           # every step integrated
    assert f.counts == {"odometry out of step": 3} and len(f.events) == 1
    assert isinstance(f.events[0], Notice) and f.events[0].rule == "odometry out of step"


def test_two_interleaved_sources_are_merged_not_discarded():
    # Wheel odometry published twice: the second copy 2 ms later and 3 cm to the side.
    f = front()
    for i in range(50):
        t = 1.0 + 0.1 * i
        f.add_odom(t, np.array([0.1 * i, 0.0, 0.0]))
        f.add_odom(t + 0.002, np.array([0.1 * i, 0.03, 0.0]))
        f.add_scan(scan(t - 0.05 if i else t + 0.01))
    assert f.counts == {"odometry out of step": 50}
    assert len(f.events) == 2 and "10 times" in str(f.events[1])   # at the 1st and 10th firing only
    # The scans saw the mean of the two sources (merged at t + 1 ms): no 3 cm jitter,
    # no motion lost. The last scan, at 5.85 s, lies 0.049 s after the mean at 5.801 s.
    np.testing.assert_allclose(f.slam.poses, [[4.8 + 0.049, 0.015, 0.0]] * 3, atol=1e-9)


def test_an_older_message_is_put_in_its_place():
    f = front()
    f.add_odom(1.0, np.zeros(3))
    f.add_odom(2.0, np.array([1.0, 0.0, 0.0]))
    f.add_odom(1.5, np.array([0.3, 0.0, 0.0]))      # late: between the two
    f.add_scan(scan(1.25))
    np.testing.assert_allclose(f.slam.poses[:, 0], 0.15)
    assert f.counts == {"odometry out of order": 1}


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
    assert slam.grid.known_cells().sum() == 0
