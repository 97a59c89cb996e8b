"""The warnings the SLAM node gives instead of waiting in silence."""
from __future__ import annotations

from assign5.watchdog import clock_problem, scan_problem


def test_time_source_problems_are_named():
    text = clock_problem(False, ["/simulator"], 0.0, 5.0)
    assert text is not None and text.startswith("/clock is published (by /simulator) but this node runs on wall time")
    assert "use_sim_time:=true" in text
    assert clock_problem(True, [], 4.9, 5.0) is None       # a bag may start a moment later
    assert "nothing has published /clock for 5 s" in (clock_problem(True, [], 5.0, 5.0) or "")
    assert clock_problem(True, ["/play"], 60.0, 5.0) is None and clock_problem(False, [], 60.0, 5.0) is None


def test_a_silent_scan_topic_is_named_with_the_laser_topics_there_are():
    text = scan_problem("/laser", 5.0, {"/scan": ["/simulator"], "/base_scan": ["/a", "/b"]})
    assert text == ("no scan received on /laser for 5 s. LaserScan topics there are: /base_scan (from /a, /b); "
                    "/scan (from /simulator). Remap with scan:=<topic> (slam.launch) or _scan_topic:=<topic>.")
    assert "No topic carries sensor_msgs/LaserScan" in scan_problem("/scan", 5.0, {})
