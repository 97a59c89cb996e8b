"""The rules between raw sensor streams and the filter, shared by the node and the
offline runner so that a live replay and an offline run treat every message alike.

Odometry is buffered and interpolated at each scan's stamp; a step between two
odometry messages faster than max_odom_speed is a kidnap (not integrated); time going backwards resets the filter;
unusable scans are dropped with a reason. What happened is reported as typed events
(Kidnap, Reset) for the caller to log and act on.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Union

import numpy as np

from fastslam.filter.odom_buffer import OdomBuffer
from fastslam.filter.scan import Scan, fov_problem
from fastslam.filter.slam import FastSlam, StepInfo

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


class Dropped(ValueError):
    """A message that is not used; str() says why."""


@dataclass(frozen=True)
class Kidnap:
    """Odometry jumped faster than max_odom_speed: the jump is not integrated."""

    jump: float       # [m]
    seconds: float    # between the two odometry messages
    max_speed: float  # [m/s]

    def __str__(self) -> str:
        return (f"odometry jumped {self.jump:.2f} m in {self.seconds:.3f} s (> max_odom_speed "
                f"{self.max_speed} m/s): treating it as a kidnap, the jump is not integrated")


@dataclass(frozen=True)
class Reset:
    """Scan time went backwards: the filter starts again (the caller clears what it keeps
    from before, e.g. tf and map->odom)."""

    previous: float  # stamp of the last scan before [s]
    stamp: float     # the scan that went back [s]

    def __str__(self) -> str:
        return (f"resetting the filter: time went backwards ({self.previous:.2f} -> "
                f"{self.stamp:.2f} s): bag restarted or looped?")


Event = Union[Kidnap, Reset]


def drop_key(why: str) -> str:
    """The kind of drop a reason names, to count by: without the detail after a colon
    or in parentheses, and with numbers replaced, so "latest odometry is +0.61 s" and "+0.72 s" count as one."""
    return re.sub(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?", "#", re.split(r"[:(]", why)[0]).strip()


@dataclass
class Frontend:
    slam: FastSlam
    odom_timeout: float = 0.5    # a scan this much newer than the newest odometry is dropped [s]
    odom_buffer: float = 10.0    # [s] of odometry kept
    max_odom_speed: float = 5.0  # [m/s] a step between two odometry messages faster than this is a kidnap
    events: list[Event] = field(default_factory=list)  # for the caller to log and act on, oldest first

    def __post_init__(self) -> None:
        self.odom = OdomBuffer(self.odom_buffer)
        self.last_stamp: float | None = None
        self.last_odom: NDArray[np.float64] | None = None  # odometry pose of the last processed scan
        self.scan_odom: NDArray[np.float64] | None = None  # odometry pose of the last scan the filter saw
        self.resets = 0
        self._rebase = False

    def add_odom(self, t: float, pose: NDArray[np.float64]) -> None:
        """Buffers an odometry pose (x, y, theta) stamped t; raises Dropped if unusable."""
        pose = np.asarray(pose, dtype=np.float64)
        if not (np.all(np.isfinite(pose)) and np.isfinite(t)):
            raise Dropped("odometry with NaN or inf")
        latest = self.odom.latest
        if latest is not None and t < latest[0]:
            return  # older than what we have; the scan side notices restarts
        if latest is not None:
            jump = float(np.hypot(*(pose[:2] - latest[1][:2])))
            # Sparse logs step a metre between messages; a teleport does it in no time.
            if jump > self.max_odom_speed * max(t - latest[0], 1e-3):
                self.events.append(Kidnap(jump, t - latest[0], self.max_odom_speed))
                self.odom.clear()
                self._rebase = True
        self.odom.add(t, pose)

    def add_scan(self, scan: Scan) -> StepInfo:
        """Runs one filter step with the odometry at the scan's stamp; raises Dropped."""
        t = scan.stamp
        if not t > 0:
            raise Dropped("scan stamped zero")
        problem = fov_problem(scan, self.slam.cfg)
        if problem:
            raise Dropped(problem)
        if self.last_stamp is not None and t < self.last_stamp:
            self.events.append(Reset(self.last_stamp, t))
            self.reset()
        odom = self.odom.at(t, self.odom_timeout)
        if odom is None:
            latest = self.odom.latest
            if latest is None:
                raise Dropped("no odometry received yet")
            raise Dropped(f"no odometry at the scan's time (latest odometry is {t - latest[0]:+.2f} s "
                          f"from the scan; odom_timeout {self.odom_timeout} s)")
        if self._rebase:
            self.slam.rebase_odometry(odom)
            self._rebase = False
        info = self.slam.step(odom, scan)
        self.last_stamp = t
        self.scan_odom = odom
        if info.processed:
            self.last_odom = odom
        return info

    def reset(self) -> None:
        self.slam.reset()
        self.odom.clear()
        self.last_stamp = None
        self.last_odom = None
        self.scan_odom = None
        self._rebase = False
        self.resets += 1
