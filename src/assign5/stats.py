"""What the node counts (scans, updates, drops by kind) and ~stats, which reports it.

Scans and odometry are dropped in threads of their own, so the drop counts have a lock
of their own; ~stats runs on a wall-clock thread (sim time may stand still).
"""
from __future__ import annotations

import json
import resource
import threading
import time

import numpy as np
import rospy
from std_msgs.msg import String

from fastslam.filter.frontend import Frontend, drop_key
from fastslam.filter.slam import FastSlam

from .malloc import malloc_trim
from .map_output import MapOutput

STATS_PERIOD = 1.0   # [s] of wall time between ~stats messages
DROP_KINDS = 100     # kinds of drop counted apart; more are counted together


def _logged(n: int) -> bool:
    """Whether the n-th occurrence of a thing is logged: the 1st, 10th, 100th..."""
    return n == 10 ** int(round(np.log10(n)))


class Counts:
    """Scans received, updates made, messages dropped by kind, update times."""

    def __init__(self) -> None:
        self.scans = 0
        self.updates = 0
        self.dropped: dict[str, int] = {}
        self.lock = threading.Lock()  # dropped
        self.update_ms: list[float] = []

    def drop(self, why: str) -> None:
        """Counts a dropped message by its kind; warns at the 1st, 10th, 100th... of each kind."""
        key = drop_key(why)
        with self.lock:   # scans and odometry are dropped in threads of their own
            if key not in self.dropped and len(self.dropped) >= DROP_KINDS:
                key = f"other kinds (more than {DROP_KINDS})"   # made-up frame names must not grow memory
            n = self.dropped.get(key, 0) + 1
            self.dropped[key] = n
        if _logged(n):
            rospy.logwarn(f"dropping message: {why} ({n} so far" +
                          ("; said again at the 10th, 100th, ...)" if n == 1 else ")"))

    def dropped_total(self) -> int:
        return sum(self.dropped.values())

    def update_time(self, ms: float, neff: float) -> None:
        """Notes an update's time; logs the mean every 50 updates."""
        self.update_ms.append(ms)
        if len(self.update_ms) >= 50:
            rospy.loginfo(f"{self.updates} updates, {np.mean(self.update_ms):.1f} ms mean "
                          f"({np.max(self.update_ms):.1f} max) per update, Neff {neff:.1f}, "
                          f"dropped {self.dropped_total()}")
            self.update_ms.clear()


class Stats:
    """~stats (JSON) once per STATS_PERIOD; `start` starts its thread."""

    def __init__(self, counts: Counts, slam: FastSlam, front: Frontend, lock: threading.RLock,
                 maps: MapOutput) -> None:
        self.counts, self.slam, self.front, self.lock, self.maps = counts, slam, front, lock, maps
        self.pub = rospy.Publisher("~stats", String, queue_size=1, latch=True)

    def stats(self) -> dict:
        """Counters for ~stats (JSON): what was dropped and why, the rules that fired, the map."""
        grid, lim = self.slam.grid, self.slam.limits
        with open("/proc/self/statm") as f:
            rss = int(f.read().split()[1]) * resource.getpagesize()
        with self.counts.lock:
            dropped = dict(self.counts.dropped)
        with self.lock:
            rules = dict(self.front.counts)
        return {"scans": self.counts.scans, "updates": self.counts.updates, "resets": self.front.resets,
                "dropped": dropped, "rules": rules,
                "map_growth_refused": self.slam.refusals, "match_recoveries": self.slam.recoveries,
                "match_loops": self.slam.loops,
                "match_loops_spread": self.slam.loops_spread,
                "odometry_scale": None if self.slam.odom_scale is None else self.slam.odom_scale.summary(),
                "odometry_stalls_tracked": self.slam.stalls, "matches_beyond_gate": self.slam.beyond_gate,
                "known_cells": self.maps.known_cells,
                "map_cells": list(grid.shape), "maps_mb": round(grid.nbytes / 2**20, 1),
                "maps_limit_mb": None if lim.map_bytes is None else round(lim.map_bytes / 2**20, 1),
                "rss_mb": round(rss / 2**20, 1)}

    def start(self) -> None:
        threading.Thread(target=self._loop, name="stats", daemon=True).start()

    def _loop(self) -> None:
        trim = malloc_trim()
        while not rospy.is_shutdown():
            trim()   # what large messages (maps, scans of many beams) were buffered in goes back
            try:
                self.pub.publish(String(json.dumps(self.stats())))
            except (rospy.ROSException, OSError, RuntimeError):
                return  # shutting down
            time.sleep(STATS_PERIOD)
