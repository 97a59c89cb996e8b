"""Recent odometry poses, interpolated at a scan's stamp."""
from __future__ import annotations

import bisect
from collections import deque
from typing import TYPE_CHECKING

import numpy as np

from fastslam.geometry import wrap_angle

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


# Samples kept at most, whatever their stamps: a driver whose stamps freeze would
# otherwise grow the buffer without end (10 s of odometry at 1 kHz fit).
MAX_SAMPLES = 10_000


class OdomBuffer:
    """Time-ordered (t, x, y, theta) samples covering the last `span` seconds, at most
    max_samples of them."""

    def __init__(self, span: float = 10.0, max_samples: int = MAX_SAMPLES) -> None:
        self.span = span
        self._t: deque[float] = deque(maxlen=max_samples)
        self._p: deque[NDArray[np.float64]] = deque(maxlen=max_samples)

    def __len__(self) -> int:
        return len(self._t)

    @property
    def latest(self) -> tuple[float, NDArray[np.float64]] | None:
        return (self._t[-1], self._p[-1]) if self._t else None

    def clear(self) -> None:
        self._t.clear()
        self._p.clear()

    def add(self, t: float, pose: NDArray[np.float64]) -> None:
        """Appends a sample; one older than the newest is ignored (caller decides resets)."""
        if self._t and t < self._t[-1]:
            return
        self._t.append(float(t))
        self._p.append(np.asarray(pose, dtype=np.float64))
        while self._t[-1] - self._t[0] > self.span:
            self._t.popleft()
            self._p.popleft()

    def insert(self, t: float, pose: NDArray[np.float64]) -> bool:
        """Puts a sample older than the newest in its place; False if the buffer no
        longer covers its time (then it is not kept)."""
        if not self._t or t < self._t[0]:
            return False
        if len(self._t) == self._t.maxlen:   # full: the oldest sample makes room
            self._t.popleft()
            self._p.popleft()
        i = bisect.bisect_right(self._t, t)
        self._t.insert(i, float(t))
        self._p.insert(i, np.asarray(pose, dtype=np.float64))
        return True

    def merge_latest(self, t: float, pose: NDArray[np.float64]) -> None:
        """Replaces the newest sample by its mean with (t, pose): two readings of one
        instant from sources out of step become one (heading the short way round)."""
        t0, p0 = self._t[-1], self._p[-1]
        p = np.asarray(pose, dtype=np.float64)
        mean = (p0 + p) / 2
        mean[2] = wrap_angle(p0[2] + wrap_angle(p[2] - p0[2]) / 2)
        self._t[-1] = (t0 + t) / 2
        self._p[-1] = mean

    def since(self, t: float) -> NDArray[np.float64]:
        """(K, 3) poses stamped t or later, at least the newest (K >= 1 unless empty)."""
        out: list[NDArray[np.float64]] = []
        for j in range(len(self._t) - 1, -1, -1):   # from the newest: only the window is visited
            if self._t[j] < t and out:
                break
            out.append(self._p[j])
        return np.array(out).reshape(-1, 3)

    def at(self, t: float, max_extrapolation: float, lookahead: float = np.inf) -> NDArray[np.float64] | None:
        """(3,) pose at time t, linear in x, y and the wrapped heading.

        None when t lies before the buffer or more than max_extrapolation after its end
        (a scan newer than the newest odometry by a little uses the newest pose). A
        sample stamped more than lookahead after t is not interpolated with: the pose
        before t is used, as when that sample had not come yet.
        """
        if not self._t or t < self._t[0] or t > self._t[-1] + max_extrapolation:
            return None
        if t >= self._t[-1]:
            return self._p[-1].copy()
        ts = np.fromiter(self._t, float, len(self._t))
        i = int(np.searchsorted(ts, t, side="right"))
        t0, t1 = ts[i - 1], ts[i]
        p0, p1 = self._p[i - 1], self._p[i]
        if t1 > t + lookahead:   # the very comparison of ScanWait.due
            return p0.copy()
        a = 0.0 if t1 == t0 else (t - t0) / (t1 - t0)
        out = p0 + a * (p1 - p0)
        out[2] = wrap_angle(p0[2] + a * wrap_angle(p1[2] - p0[2]))
        return out
