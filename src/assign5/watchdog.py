"""What a user would otherwise meet as silence, warned once each, naming the cause:
a /clock publisher while the node runs on wall time (or sim time without one), and
no scan on the node's topic a few seconds after start.

The rules are pure functions (tested without ROS); ``Watchdog`` asks the master once a
second on a wall-clock thread (sim time may stand still, which is one of the problems).
"""
from __future__ import annotations

import threading
import time
from typing import Callable, Mapping, Sequence


def clock_problem(sim_time: bool, clock_publishers: Sequence[str], waited: float, grace: float) -> str | None:
    """Why time is wrong, or None. sim_time: the node runs on /clock (use_sim_time was
    true when it started); waited: seconds of wall time without a /clock publisher."""
    if clock_publishers and not sim_time:
        return (f"/clock is published (by {', '.join(sorted(clock_publishers))}) but this node runs on wall "
                "time: /use_sim_time was false when it started, so its tf and maps are stamped in wall time "
                "while the scans come in sim time. Restart it with use_sim_time:=true.")
    if sim_time and not clock_publishers and waited >= grace:
        return (f"/use_sim_time is true but nothing has published /clock for {waited:.0f} s: time stands "
                "still and no scan can be matched with odometry. Start the simulator or "
                "`rosbag play --clock`, or restart with use_sim_time:=false.")
    return None


def scan_problem(topic: str, seconds: float, lasers: Mapping[str, Sequence[str]]) -> str:
    """The warning for no scan on topic after seconds; lasers: LaserScan topic -> publishers."""
    if lasers:
        there = "; ".join(f"{t} (from {', '.join(sorted(p)) or 'nobody now'})" for t, p in sorted(lasers.items()))
        hint = f"LaserScan topics there are: {there}. Remap with scan:=<topic> (slam.launch) or _scan_topic:=<topic>."
    else:
        hint = "No topic carries sensor_msgs/LaserScan: is the laser driver, simulator or bag running?"
    return f"no scan received on {topic} for {seconds:.0f} s. {hint}"


class Watchdog:
    """Checks the time source and the scan topic once a second until shutdown."""

    def __init__(self, scan_topic: str, no_scan_after: float, scans_seen: Callable[[], int]) -> None:
        import rosgraph
        import rospy

        self.rospy = rospy
        self.master = rosgraph.Master(rospy.get_name())
        self.scan_topic, self.after, self.scans_seen = scan_topic, no_scan_after, scans_seen
        self.sim_time = not rospy.rostime.is_wallclock()
        self.start = self.clock_seen = time.monotonic()
        self.warned: set[str] = set()
        threading.Thread(target=self._run, name="watchdog", daemon=True).start()

    def _run(self) -> None:
        while not self.rospy.is_shutdown():
            time.sleep(1.0)
            if self.rospy.is_shutdown():
                return  # nodes that leave first are no problem of ours
            try:
                self.check()
            except Exception as err:  # the master went away: shutting down
                self.rospy.logdebug(f"watchdog: {err}")

    def _warn(self, kind: str, text: str | None) -> None:
        if text and kind not in self.warned:
            self.warned.add(kind)
            self.rospy.logwarn(text)

    def check(self) -> None:
        now = time.monotonic()
        waited = now - self.start
        publishers, _, _ = self.master.getSystemState()
        by_topic: dict[str, list[str]] = dict(publishers)
        clocks = by_topic.get("/clock", [])
        if clocks:
            self.clock_seen = now
        self._warn("clock", clock_problem(self.sim_time, clocks, now - self.clock_seen, self.after))
        if self.after > 0 and waited >= self.after and self.scans_seen() == 0:
            lasers = {t: by_topic[t] for t, kind in self.master.getTopicTypes()
                      if kind == "sensor_msgs/LaserScan" and by_topic.get(t)}   # published, not just wanted
            self._warn("scan", scan_problem(self.scan_topic, waited, lasers))
