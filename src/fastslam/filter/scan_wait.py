"""Where in the stream the node handles a scan: after the first odometry stamped at or
after it, if that is stamped within odom_wait of it (the node, assign5/slam_node.py, waits
for it, then interpolates the odometry at the scan's stamp; the Frontend interpolates with nothing
stamped later, so when it arrives does not matter); at once when odometry of its own
stamp is in. The offline runner (BagData.records) and the simulator loop (simrun) hand scans
over in the same places, so all three give a scan the same odometry.
"""
from __future__ import annotations

from collections import deque
from typing import Generic, TypeVar

ODOM_WAIT = 0.1       # [s] the node's default odom_wait, in stamp time
ODOM_DELIVERY = 0.1   # [s] of wall time the node waits beyond odom_wait for odometry stamped within it

T = TypeVar("T")


class ScanWait(Generic[T]):
    """Scans (any item, with its stamp) held until the odometry they wait for is in."""

    def __init__(self, odom_wait: float = ODOM_WAIT) -> None:
        self.odom_wait = odom_wait
        self._held: deque[tuple[float, T]] = deque()
        self._newest = float("-inf")   # stamp of the newest odometry so far

    def due(self, now: float) -> list[T]:
        """The scans that waited in vain: nothing came within odom_wait, stream time now."""
        out = []
        while self._held and self._held[0][0] + self.odom_wait < now:
            out.append(self._held.popleft()[1])
        return out

    def odometry(self, t: float) -> list[T]:
        """After odometry stamped t is in: the scans stamped up to t."""
        self._newest = max(self._newest, t)
        out = []
        while self._held and self._held[0][0] <= t:
            out.append(self._held.popleft()[1])
        return out

    def scan(self, t: float, item: T) -> list[T]:
        """A scan stamped t: [item] if its odometry is in (or nothing is waited for), else held."""
        if self.odom_wait > 0 and self._newest < t:
            self._held.append((t, item))
            return []
        return [item]

    def rest(self) -> list[T]:
        """The end of the stream: every scan still held."""
        out = [item for _, item in self._held]
        self._held.clear()
        return out
