"""The rules between raw sensor streams and the filter, shared by the node and the
offline runner so that a live replay and an offline run treat every message alike.

Odometry is buffered and interpolated at each scan's stamp, with odometry stamped at
most odom_lookahead after it (scan_wait.py: where the node and the offline runner hand
the scan over); with none that soon, the pose before the scan is used. A kidnap is judged by
distance, whatever the time: a pose farther than max_odom_jump from every pose of the
last JUMP_WINDOW seconds (not integrated). Odometry out of step (faster than
max_odom_speed since the previous message, as two sources interleaved on one topic
give, or a log's made-up stamps) is kept: two such messages with no scan between them
become one, their mean; a message older than the newest is put in its place, or, older
by more than reset_backwards, starts the odometry again (a restart). A scan stamped
before the previous one by at most reset_backwards is out of order (dropped, counted);
by more, or after the caller reports that the clock started again (`restart`), the
filter resets, after `before_reset` had a look at what was mapped.
Scans of more than max_beams beams are evenly subsampled; unusable scans are dropped
with a reason. Each rule is counted (`counts`) and reported at its 1st, 10th, 100th...
firing, as typed events (Kidnap, Notice; Reset at every reset) for the caller to log
and act on.
"""
from __future__ import annotations

import dataclasses
import re
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Callable, Union

import numpy as np

from fastslam.filter.budget import MAX_BEAMS
from fastslam.filter.odom_buffer import OdomBuffer
from fastslam.filter.scan import Scan, fov_problem
from fastslam.filter.scan_wait import ODOM_WAIT
from fastslam.filter.slam import FastSlam, StepInfo

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray

JUMP_WINDOW = 1.0  # [s] a kidnap is far from every pose of this window (a second source lags a little)


class Dropped(ValueError):
    """A message that is not used; str() says why."""


@dataclass(frozen=True)
class Kidnap:
    """Odometry jumped farther than max_odom_jump from all of the last second's: the
    jump is not integrated. count: how many kidnaps so far."""

    jump: float      # [m]
    max_jump: float  # [m]
    count: int = 1

    def __str__(self) -> str:
        text = (f"odometry jumped {self.jump:.2f} m (> max_odom_jump {self.max_jump} m): treating it as a kidnap, "
                "the jump is not integrated")
        return text if self.count == 1 else f"odometry kidnap: {self.count} times so far (last: {text})"


@dataclass(frozen=True)
class Reset:
    """Scan time went backwards by more than reset_backwards, or the clock started again:
    the filter starts again (the caller clears what it keeps from before, e.g. tf and
    map->odom)."""

    previous: float  # stamp of the last scan before [s]
    stamp: float     # the scan that went back [s]
    clock: bool = False  # the caller saw the clock start again

    def __str__(self) -> str:
        if self.clock:
            return (f"resetting the filter: the clock started again (last scan {self.previous:.2f} s, "
                    f"this one {self.stamp:.2f} s): bag or simulator restarted?")
        return (f"resetting the filter: time went backwards ({self.previous:.2f} -> "
                f"{self.stamp:.2f} s): bag restarted or looped?")


@dataclass(frozen=True)
class Notice:
    """A stream rule fired (odometry out of order, out of step): kept, but worth knowing;
    reported at its 1st, 10th, 100th... firing, so thousands are an alarm, not a flood."""

    rule: str
    detail: str
    count: int = 1

    def __str__(self) -> str:
        return self.detail if self.count == 1 else f"{self.rule}: {self.count} times so far (last: {self.detail})"


Event = Union[Kidnap, Reset, Notice]


def drop_key(why: str) -> str:
    """The kind of drop a reason names, to count by: without the detail after a colon
    or in parentheses, and with numbers replaced, so "latest odometry is +0.61 s" and "+0.72 s" count as one."""
    return re.sub(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?", "#", re.split(r"[:(]", why)[0]).strip()


@dataclass
class Frontend:
    slam: FastSlam
    odom_timeout: float = 0.5    # a scan this much newer than the newest odometry is dropped [s]
    # odometry stamped up to this much after a scan is interpolated with; later, the pose
    # before the scan is used, whenever the later one arrived (scan_wait.py) [s]
    odom_lookahead: float = ODOM_WAIT
    odom_buffer: float = 10.0    # [s] of odometry kept
    max_odom_speed: float = 5.0  # [m/s] a step between two odometry messages faster than this is out of step
    max_odom_jump: float = 5.0   # [m] farther from the recent odometry is a kidnap (the logs step <= 3.5 m)
    reset_backwards: float = 1.0  # [s] a scan this much older than the previous one is out of order; more: reset
    max_beams: int = MAX_BEAMS   # scans with more beams are evenly subsampled to this many
    # called with the Reset before the filter forgets, if it had mapped anything (to save the map)
    before_reset: Callable[[Reset], None] | None = None
    events: list[Event] = field(default_factory=list)  # for the caller to log and act on, oldest first
    counts: dict[str, int] = field(default_factory=dict)  # how often each rule fired

    def __post_init__(self) -> None:
        self.odom = OdomBuffer(self.odom_buffer)
        self.last_stamp: float | None = None
        self.last_odom: NDArray[np.float64] | None = None  # odometry pose of the last processed scan
        self.scan_odom: NDArray[np.float64] | None = None  # odometry pose of the last scan the filter saw
        self.resets = 0
        self._rebase = False
        self._scan_since_odom = True  # a scan used the odometry since the newest message
        self._restart = False         # the clock started again: the next scan resets

    def add_odom(self, t: float, pose: NDArray[np.float64]) -> None:
        """Buffers an odometry pose (x, y, theta) stamped t; raises Dropped if unusable."""
        pose = np.asarray(pose, dtype=np.float64)
        if not (np.all(np.isfinite(pose)) and np.isfinite(t)):
            raise Dropped("odometry with NaN or inf")
        latest = self.odom.latest
        if latest is None:
            self._accept(t, pose)
            return
        if t < latest[0] - self.reset_backwards:
            # older than the newest by more than reset_backwards: the odometry started again
            # (a bag, driver or simulator restarted); the buffer starts again with it
            self._fire("odometry restarted", lambda n: Notice(
                "odometry restarted", f"odometry stamped {latest[0] - t:.2f} s before the newest message "
                f"(> reset_backwards {self.reset_backwards:g} s): taken as a restart, the older odometry dropped", n))
            self.odom.clear()
            self._accept(t, pose)
            return
        if t < latest[0]:
            # older than the newest: in its place if the buffer still covers it
            if self.odom.insert(t, pose):
                self._fire("odometry out of order", lambda n: Notice(
                    "odometry out of order", f"odometry stamped {latest[0] - t:.3f} s before the newest "
                    "message: put in its place", n))
            return
        recent = self.odom.since(t - JUMP_WINDOW)
        jump = float(np.min(np.hypot(recent[:, 0] - pose[0], recent[:, 1] - pose[1])))
        if jump > self.max_odom_jump:
            self._fire("odometry kidnap", lambda n: Kidnap(jump, self.max_odom_jump, n))
            self.odom.clear()
            self._rebase = True
            self._accept(t, pose)
            return
        step = float(np.hypot(*(pose[:2] - latest[1][:2])))
        if step > self.max_odom_speed * max(t - latest[0], 1e-3):
            self._fire("odometry out of step", lambda n: Notice(
                "odometry out of step", f"odometry stepped {step:.3f} m in {t - latest[0]:.3f} s "
                f"(> max_odom_speed {self.max_odom_speed} m/s): two sources on one topic, or wrong stamps? "
                "Kept; merged with the previous message when no scan lies between them", n))
            if not self._scan_since_odom:
                self.odom.merge_latest(t, pose)
                return
        self._accept(t, pose)

    def _accept(self, t: float, pose: NDArray[np.float64]) -> None:
        self.odom.add(t, pose)
        self._scan_since_odom = False

    def _fire(self, rule: str, event: Callable[[int], Event], once: bool = False) -> None:
        """Counts a rule; reports it (event(count)) at its 1st, 10th, 100th... firing
        (only the 1st if once)."""
        n = self.counts.get(rule, 0) + 1
        self.counts[rule] = n
        if n == 1 or (not once and n == 10 ** int(round(np.log10(n)))):
            self.events.append(event(n))

    def restart(self) -> None:
        """The clock started again (a bag or simulator restarted): the next scan resets the
        filter, however close its stamp is to the last one. Odometry from now on is the
        new run's."""
        self.odom.clear()
        self._restart = True

    def add_scan(self, scan: Scan) -> StepInfo:
        """Runs one filter step with the odometry at the scan's stamp; raises Dropped."""
        t = scan.stamp
        if not t > 0:
            raise Dropped("scan stamped zero")
        scan = self._limit_beams(scan)
        problem = fov_problem(scan, self.slam.cfg)
        if problem:
            raise Dropped(problem)
        if self.last_stamp is not None and (self._restart or t < self.last_stamp):
            back = self.last_stamp - t
            if not self._restart and back <= self.reset_backwards:
                raise Dropped(f"scan stamped {back:.3f} s before the previous one (out of order: within "
                              f"reset_backwards {self.reset_backwards:g} s, so not a restart)")
            event = Reset(self.last_stamp, t, clock=self._restart)
            if self.before_reset is not None and self.slam.updates > 0:
                self.before_reset(event)
            self.events.append(event)
            latest = self.odom.latest   # the new run's odometry (near the scan) is kept, the old one's not
            self.reset(keep_odometry=latest is not None and latest[0] - t <= self.reset_backwards)
        self._restart = False
        odom = self.odom.at(t, self.odom_timeout, self.odom_lookahead)
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
        self._scan_since_odom = True
        if info.processed:
            self.last_odom = odom
        return info

    def _limit_beams(self, scan: Scan) -> Scan:
        """The scan, or max_beams of its beams evenly spread over it."""
        m = len(scan.ranges)
        if m <= self.max_beams:
            return scan
        self._fire("scan beams subsampled", lambda n: Notice(
            "scan beams subsampled", f"scans of {m} beams (> max_beams {self.max_beams}) are evenly subsampled "
            f"to {self.max_beams} beams (said once)", n), once=True)
        keep = np.arange(self.max_beams) * m // self.max_beams
        return dataclasses.replace(scan, ranges=scan.ranges[keep], angles=scan.angles[keep])

    def reset(self, keep_odometry: bool = False) -> None:
        """Forgets the filter and, unless keep_odometry (the new run's, after a restart), the odometry."""
        self.slam.reset()
        if not keep_odometry:
            self.odom.clear()
        self.last_stamp = None
        self.last_odom = None
        self.scan_odom = None
        self._rebase = False
        self._scan_since_odom = True
        self.resets += 1
