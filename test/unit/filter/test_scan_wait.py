"""ScanWait: a scan is handed over where the node handles it."""
from fastslam.filter.scan_wait import ScanWait


def test_a_scan_waits_for_the_next_odometry_within_odom_wait():
    w: ScanWait[str] = ScanWait(0.1)
    assert w.odometry(0.9) == []
    assert w.scan(1.0, "a") == []                      # no odometry at or after 1.0 yet
    assert w.due(1.05) == [] and w.due(1.1) == []       # waits up to 0.1 s, inclusive
    assert w.odometry(1.1) == ["a"]
    assert w.scan(1.1, "b") == ["b"]                    # odometry of its own stamp: at once
    assert w.scan(1.2, "c") == [] and w.scan(1.25, "d") == []
    assert w.due(1.31) == ["c"]                         # 0.11 s without odometry: handed over as it is
    assert w.odometry(1.3) == ["d"]
    assert w.scan(2.0, "e") == [] and w.rest() == ["e"] and w.rest() == []


def test_no_wait_hands_every_scan_over_at_once():
    w: ScanWait[str] = ScanWait(0.0)
    assert w.scan(1.0, "a") == ["a"] and w.due(5.0) == [] and w.rest() == []
