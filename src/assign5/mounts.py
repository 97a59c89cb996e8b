"""The lasers' poses on the base, looked up in tf once per frame."""
from __future__ import annotations

import time

import numpy as np
import rospy
import tf2_ros

from fastslam.io.bag_reader import DEFAULT_BASE_FRAME

from . import convert
from .convert import BadMessage

MOUNT_RETRY = 1.0    # [s] a laser frame not found in tf is looked up again at most this often
FAILED_FRAMES = 256  # unknown frames remembered (a flood of made-up names must not grow memory)


class LaserMounts:
    """Each laser frame's (x, y, yaw) on the base frame and whether it is upside down.

    The base frame is base_frame if set, else the frame the odometry moves (its
    child_frame_id, told by `odometry_frame`): bags and robots name it base_link,
    base_footprint or otherwise, and the odometry is what the laser's pose composes with.
    """

    def __init__(self, tf_buffer: tf2_ros.Buffer, base_frame: str, tf_timeout: float) -> None:
        self.tf_buffer, self.tf_timeout = tf_buffer, tf_timeout
        self.configured = base_frame            # "" : the odometry's
        self.base_frame = base_frame            # "" until the first odometry
        self.odometry_child = ""                # the first odometry's child_frame_id
        self.warned_frame = False
        self.mounts: dict[str, tuple[tuple[float, float, float], bool]] = {}
        self.mount_failed: dict[str, tuple[float, str]] = {}  # frame -> (when, why) of its last failed lookup
        self.last_mount_wait = -np.inf

    def odometry_frame(self, child: str) -> str | None:
        """Takes note of an odometry message's child_frame_id; returns a warning the first
        time it differs from the base frame (set by hand, or the first odometry's)."""
        child = child.lstrip("/") or DEFAULT_BASE_FRAME   # tf1-era bags: tf2 takes no leading slash
        if not self.odometry_child:
            self.odometry_child = child
            self.base_frame = self.configured or child
        if child == self.base_frame or self.warned_frame:
            return None
        self.warned_frame = True
        return (f"the odometry moves '{child}' while the laser's mount is read on '{self.base_frame}'"
                + (" (base_frame)" if self.configured else " (the first odometry's frame)")
                + ": if the two differ by more than a height, set base_frame to the odometry's frame (warned once)")

    def lookup(self, frame: str) -> tuple[tuple[float, float, float], bool]:
        """The laser's pose on the base, looked up in tf once per frame. A frame not found
        is looked up again at most once per MOUNT_RETRY, without waiting: until then its
        scans are dropped at once, and cost good scans nothing. Only before any laser is
        known does a lookup wait for tf (tf_timeout, at most once per MOUNT_RETRY)."""
        known = self.mounts.get(frame)
        if known is not None:
            return known
        if not self.base_frame:
            raise BadMessage("no odometry received yet")   # the frontend's words: its child frame is the base
        now = time.monotonic()
        failed = self.mount_failed.get(frame)
        if failed is not None and now - failed[0] < MOUNT_RETRY:
            raise BadMessage(failed[1])
        wait = 0.0
        if not self.mounts and now - self.last_mount_wait >= MOUNT_RETRY:
            wait, self.last_mount_wait = self.tf_timeout, now
        try:
            t = self.tf_buffer.lookup_transform(self.base_frame, frame, rospy.Time(0), rospy.Duration(wait))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                tf2_ros.ExtrapolationException, tf2_ros.InvalidArgumentException) as err:
            why = f"no transform {self.base_frame} -> '{frame}' in tf: {err}" + self._hint()
            self.mount_failed.pop(frame, None)
            self.mount_failed[frame] = (time.monotonic(), why)
            while len(self.mount_failed) > FAILED_FRAMES:
                del self.mount_failed[next(iter(self.mount_failed))]
            raise BadMessage(why) from None
        self.mounts[frame] = convert.mount_from_transform(t)
        self.mount_failed.pop(frame, None)
        rospy.loginfo(f"laser '{frame}' on '{self.base_frame}': x y yaw = "
                      f"{np.round(self.mounts[frame][0], 3).tolist()}, upside down: {self.mounts[frame][1]}")
        return self.mounts[frame]

    def _hint(self) -> str:
        """What to set when the laser is not found on the base frame."""
        if self.configured:
            child = self.odometry_child
            other = f"; the odometry moves '{child}'" if child not in ("", self.base_frame) else ""
            return f" (base_frame is set to '{self.base_frame}'{other})"
        return f" (base_frame: empty, so the odometry's frame '{self.base_frame}'; set base_frame:=FRAME to another)"
