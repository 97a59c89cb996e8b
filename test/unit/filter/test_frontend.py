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
    f.add_odom(1.08, np.array([0.08, 0.0, 0.0]))
    f.add_scan(scan(1.0))
    f.add_scan(scan(1.04))
    np.testing.assert_allclose(f.slam.poses[:, 0], 0.04)
    np.testing.assert_allclose(f.last_odom, [0.04, 0.0, 0.0])


def test_odometry_stamped_past_the_lookahead_is_not_used_whenever_it_came():
    # the node may have the next message by the time it handles the scan, or not: alike
    for late_first in (False, True):
        f = front()                                        # odom_lookahead 0.1 s
        f.add_odom(1.0, np.array([0.0, 0.0, 0.0]))
        if late_first:
            f.add_odom(1.3, np.array([0.3, 0.0, 0.0]))
        f.add_scan(scan(1.15))
        np.testing.assert_array_equal(f.scan_odom, [0.0, 0.0, 0.0])
    f = front()
    f.add_odom(1.0, np.array([0.0, 0.0, 0.0]))
    f.add_odom(1.2, np.array([0.4, 0.0, 0.0]))             # 0.05 s after the scan: interpolated with
    f.add_scan(scan(1.15))
    np.testing.assert_allclose(f.scan_odom, [0.3, 0.0, 0.0])


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
    f.add_odom(1.2, np.array([0.4, 0.0, 0.0]))
    f.add_odom(1.1, np.array([0.3, 0.0, 0.0]))      # late: between the two
    f.add_scan(scan(1.05))
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
    f.add_odom(0.5, np.array([0.0, 0.0, 0.0]))      # 1.5 s older than the newest: the odometry restarted
    assert f.add_scan(scan(0.5)).processed          # reset, then the new run's first update
    reset, notice = f.events[1], f.events[0]
    assert reset == Reset(previous=2.0, stamp=0.5) and f.slam.updates == 1
    assert "time went backwards (2.00 -> 0.50 s)" in str(reset)
    assert str(notice) == ("odometry stamped 1.50 s before the newest message (> reset_backwards 1 s): taken "
                           "as a restart, the older odometry dropped")
    assert f.counts == {"odometry restarted": 1}


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


# -- issue 13 item 1: a slightly stale scan is out of order, not a restart ----------------

def _mapped(f, times=(1.0, 2.0)):
    for t in times:
        f.add_odom(t, np.array([t, 0.0, 0.0]))
        f.add_scan(scan(t))
    return f


def test_a_scan_slightly_older_than_the_previous_is_dropped_and_the_filter_kept():
    saved = []
    f = _mapped(front())
    f.before_reset = saved.append
    known = f.slam.grid.known_cells().sum()
    with pytest.raises(Dropped, match=r"scan stamped 0.001 s before the previous one \(out of order: within "
                                      r"reset_backwards 1 s"):
        f.add_scan(scan(1.999))
    assert f.events == [] and saved == [] and f.resets == 0
    assert f.slam.updates == 2 and f.slam.grid.known_cells().sum() == known
    f.add_odom(2.1, np.array([2.1, 0.0, 0.0]))
    assert f.add_scan(scan(2.1)).processed and f.slam.updates == 3   # and it goes on


def test_a_scan_more_than_reset_backwards_older_resets_after_the_map_was_looked_at():
    seen = []
    f = _mapped(front())
    f.before_reset = lambda event: seen.append((event, f.slam.updates, f.slam.grid.known_cells().sum()))
    f.add_odom(0.9, np.zeros(3))                                  # 1.1 s back: the odometry restarted
    assert f.add_scan(scan(0.9)).processed                        # 1.1 s back: a restart
    (event, updates, known), = seen
    assert event == Reset(previous=2.0, stamp=0.9) and updates == 2 and known > 0
    assert f.events[-1] == event and f.resets == 1 and f.slam.updates == 1


def test_the_tolerance_is_a_parameter():
    f = _mapped(front())
    f.reset_backwards = 0.0
    with pytest.raises(Dropped, match="no odometry"):
        f.add_scan(scan(1.999))                   # the odometry of the old run is not kept
    assert isinstance(f.events[0], Reset) and f.resets == 1


def test_odometry_of_a_restarted_run_replaces_the_old_and_a_late_old_message_heals():
    # the clock went back 80 s; an old-run message arrives after the first new one
    f = _mapped(front(), times=(180.0, 181.0))
    f.restart()
    f.add_odom(100.0, np.array([0.0, 0.0, 0.0]))
    f.add_odom(181.1, np.array([181.1, 0.0, 0.0]))   # late, from the old run: 81 s "newer", 181 m away
    f.add_odom(100.1, np.array([0.1, 0.0, 0.0]))     # 81 s older than that: the odometry restarted again
    f.add_odom(100.2, np.array([0.2, 0.0, 0.0]))
    assert f.add_scan(scan(100.2)).processed and f.slam.updates == 1
    np.testing.assert_allclose(f.last_odom, [0.2, 0.0, 0.0])
    assert f.counts["odometry restarted"] == 1 and f.counts["odometry kidnap"] == 1


def test_the_clock_starting_again_resets_however_close_the_stamp():
    seen = []
    f = _mapped(front())
    f.before_reset = seen.append
    f.restart()                                     # e.g. /clock went back
    f.add_odom(1.95, np.array([5.0, 0.0, 0.0]))     # the new run's odometry is kept
    info = f.add_scan(scan(1.95))                   # 0.05 s back: within the tolerance, but a restart
    assert seen == [Reset(previous=2.0, stamp=1.95, clock=True)] and f.events == seen
    assert "the clock started again" in str(seen[0])
    assert info.processed and f.slam.updates == 1 and f.resets == 1
    np.testing.assert_allclose(f.last_odom, [5.0, 0.0, 0.0])


def test_nothing_mapped_is_not_offered_before_a_reset():
    seen = []
    f = front()
    f.before_reset = seen.append
    f.add_odom(5.0, np.zeros(3))
    with pytest.raises(Dropped):
        f.add_scan(scan(0.5))        # no odometry at 0.5: dropped, no scan was seen before
    f.restart()
    f.add_odom(1.0, np.zeros(3))
    f.add_scan(scan(1.0))
    assert seen == [] and f.resets == 0


# -- issue 13 item 3: at most max_beams beams per scan ---------------------------------------

def test_a_scan_of_too_many_beams_is_evenly_subsampled_with_one_notice():
    slam = FastSlam(SlamConfig(particles=2, seed=0, toggle_noise=0))
    f = Frontend(slam, max_beams=4)
    m = 10
    angles = np.radians(np.arange(m) * 36.0 - 180.0)
    seen = []
    real = slam.step

    def step(odom, s):
        seen.append(s)
        return real(odom, s)

    slam.step = step
    f.add_odom(1.0, np.zeros(3))
    for t in (1.0, 1.1, 1.2):
        f.add_scan(Scan(ranges=np.arange(m) + 1.0, angles=angles, range_min=0.1, range_max=20.0, stamp=t))
    # beams 0, 2, 5, 7 of 10 (k * 10 // 4): spread over the whole sweep
    for s in seen:
        np.testing.assert_array_equal(s.ranges, [1.0, 3.0, 6.0, 8.0])
        np.testing.assert_allclose(s.angles, angles[[0, 2, 5, 7]])
    assert f.counts == {"scan beams subsampled": 3}
    (notice,) = f.events
    assert str(notice) == "scans of 10 beams (> max_beams 4) are evenly subsampled to 4 beams (said once)"


def test_a_scan_of_max_beams_is_left_alone():
    f = Frontend(FastSlam(SlamConfig(particles=2, seed=0)), max_beams=36)
    f.add_odom(1.0, np.zeros(3))
    assert f.add_scan(scan(1.0)).processed and f.counts == {} and f.events == []
