"""OdomBuffer: recent odometry interpolated at a scan's stamp."""
from __future__ import annotations

import numpy as np

from fastslam.filter.odom_buffer import OdomBuffer


def test_odom_buffer_interpolates_and_wraps_heading():
    buf = OdomBuffer(span=10.0)
    buf.add(1.0, np.array([0.0, 0.0, 3.1]))
    buf.add(2.0, np.array([1.0, 2.0, -3.1]))
    p = buf.at(1.5, 0.5)
    np.testing.assert_allclose(p[:2], [0.5, 1.0])
    assert abs(abs(p[2]) - np.pi) < 1e-9  # through +-pi, not through 0
    np.testing.assert_allclose(buf.at(2.3, 0.5), [1.0, 2.0, -3.1])
    assert buf.at(0.5, 0.5) is None and buf.at(2.6, 0.5) is None


def test_a_sample_past_the_lookahead_is_not_interpolated_with():
    buf = OdomBuffer(span=10.0)
    buf.add(1.0, np.array([0.0, 0.0, 0.0]))
    buf.add(2.0, np.array([1.0, 0.0, 0.0]))
    np.testing.assert_allclose(buf.at(1.5, 0.5, lookahead=0.5), [0.5, 0.0, 0.0])   # exactly the limit: used
    np.testing.assert_array_equal(buf.at(1.5, 0.5, lookahead=0.4999), [0.0, 0.0, 0.0])
    np.testing.assert_array_equal(buf.at(2.0, 0.5, lookahead=0.0), [1.0, 0.0, 0.0])  # a sample's own time


def test_odom_buffer_forgets_old_samples_and_ignores_older_ones():
    buf = OdomBuffer(span=1.0)
    for t in np.arange(0.0, 3.01, 0.5):
        buf.add(t, np.array([t, 0.0, 0.0]))
    assert len(buf) == 3 and buf.at(1.0, 0.1) is None
    buf.add(0.1, np.array([9.0, 9.0, 0.0]))
    assert buf.latest[0] == 3.0


def test_linear_interpolation_by_hand():
    buf = OdomBuffer()
    buf.add(0.0, np.array([0.0, 0.0, 0.0]))
    buf.add(1.0, np.array([1.0, 2.0, 0.5]))
    buf.add(3.0, np.array([3.0, 2.0, -0.5]))
    np.testing.assert_allclose(buf.at(0.25, 0.1), [0.25, 0.5, 0.125])
    np.testing.assert_allclose(buf.at(2.5, 0.1), [2.5, 2.0, -0.25])       # 3/4 of the second interval
    np.testing.assert_array_equal(buf.at(1.0, 0.1), [1.0, 2.0, 0.5])      # a sample's own time
    np.testing.assert_array_equal(buf.at(0.0, 0.1), [0.0, 0.0, 0.0])


def test_extrapolation_up_to_the_limit_uses_the_newest_pose():
    buf = OdomBuffer()
    buf.add(1.0, np.array([1.0, 0.0, 0.2]))
    np.testing.assert_array_equal(buf.at(1.25, 0.25), [1.0, 0.0, 0.2])     # exactly the limit: still usable
    assert buf.at(1.2500001, 0.25) is None
    assert buf.at(0.9999, 0.25) is None                                    # before the first sample


def test_samples_at_equal_times():
    buf = OdomBuffer()
    for t, x in ((0.0, 0.0), (1.0, 1.0), (1.0, 5.0), (2.0, 7.0)):
        buf.add(t, np.array([x, 0.0, 0.0]))
    assert len(buf) == 4
    assert buf.at(1.0, 0.1)[0] == 5.0                                      # the later of two equal stamps
    assert buf.at(1.5, 0.1)[0] == 6.0


def test_returned_poses_are_copies_and_clear_empties():
    buf = OdomBuffer()
    buf.add(1.0, np.array([1.0, 2.0, 3.0]))
    p = buf.at(1.0, 0.0)
    p[0] = 99.0
    np.testing.assert_array_equal(buf.at(1.0, 0.0), [1.0, 2.0, 3.0])
    buf.clear()
    assert len(buf) == 0 and buf.latest is None and buf.at(1.0, 1.0) is None



def test_odom_buffer_stays_bounded_when_stamps_freeze():
    # a driver stamping every message with the same time: eviction by age never fires
    buf = OdomBuffer(10.0, max_samples=100)
    for i in range(1000):
        buf.add(5.0, np.array([0.001 * i, 0.0, 0.0]))
    assert len(buf) == 100
    np.testing.assert_array_equal(buf.latest[1], [0.999, 0.0, 0.0])   # the newest pose is kept


def test_a_late_sample_goes_in_its_place_and_a_full_buffer_makes_room():
    buf = OdomBuffer(span=10.0, max_samples=3)
    for t in (1.0, 2.0, 3.0):
        buf.add(t, np.array([t, 0.0, 0.0]))
    assert buf.insert(2.5, np.array([10.0, 0.0, 0.0]))       # the oldest (t = 1) makes room
    assert not buf.insert(1.5, np.zeros(3))                   # before the buffer now: not kept
    np.testing.assert_allclose(buf.at(2.25, 0.0), [6.0, 0.0, 0.0])   # half-way from 2.0 to the late 10.0
    np.testing.assert_allclose(buf.since(2.4), [[3.0, 0.0, 0.0], [10.0, 0.0, 0.0]])  # newest first
    np.testing.assert_allclose(buf.since(99.0), [[3.0, 0.0, 0.0]])                  # at least the newest


def test_merging_the_newest_sample_averages_time_pose_and_heading():
    buf = OdomBuffer()
    buf.add(1.0, np.array([0.0, 0.0, 3.1]))
    buf.merge_latest(1.002, np.array([0.02, 0.04, -3.1]))
    t, p = buf.latest
    assert t == 1.001
    np.testing.assert_allclose(p[:2], [0.01, 0.02], atol=1e-12)
    assert abs(p[2]) == np.pi                                          # the short way round +-pi, not 0
