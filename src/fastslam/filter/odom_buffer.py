"""Recent odometry poses, interpolated at a scan's stamp."""
from __future__ import annotations

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

    def at(self, t: float, max_extrapolation: float) -> NDArray[np.float64] | None:
        """(3,) pose at time t, linear in x, y and the wrapped heading.

        None when t lies before the buffer or more than max_extrapolation after its end
        (a scan newer than the newest odometry by a little uses the newest pose).
        """
        if not self._t or t < self._t[0] or t > self._t[-1] + max_extrapolation:
            return None
        if t >= self._t[-1]:
            return self._p[-1].copy()
        ts = np.fromiter(self._t, float, len(self._t))
        i = int(np.searchsorted(ts, t, side="right"))
        t0, t1 = ts[i - 1], ts[i]
        p0, p1 = self._p[i - 1], self._p[i]
        a = 0.0 if t1 == t0 else (t - t0) / (t1 - t0)
        out = p0 + a * (p1 - p0)
        out[2] = wrap_angle(p0[2] + a * wrap_angle(p1[2] - p0[2]))
        return out
