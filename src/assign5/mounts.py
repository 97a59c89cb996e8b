"""The lasers' poses on the base, looked up in tf once per frame."""
from __future__ import annotations

import time

import numpy as np
import rospy
import tf2_ros

from . import convert
from .convert import BadMessage

MOUNT_RETRY = 1.0    # [s] a laser frame not found in tf is looked up again at most this often
FAILED_FRAMES = 256  # unknown frames remembered (a flood of made-up names must not grow memory)


class LaserMounts:
    """Each laser frame's (x, y, yaw) on base_frame and whether it is upside down."""

    def __init__(self, tf_buffer: tf2_ros.Buffer, base_frame: str, tf_timeout: float) -> None:
        self.tf_buffer, self.base_frame, self.tf_timeout = tf_buffer, base_frame, tf_timeout
        self.mounts: dict[str, tuple[tuple[float, float, float], bool]] = {}
        self.mount_failed: dict[str, tuple[float, str]] = {}  # frame -> (when, why) of its last failed lookup
        self.last_mount_wait = -np.inf

    def lookup(self, frame: str) -> tuple[tuple[float, float, float], bool]:
        """The laser's pose on the base, looked up in tf once per frame. A frame not found
        is looked up again at most once per MOUNT_RETRY, without waiting: until then its
        scans are dropped at once, and cost good scans nothing. Only before any laser is
        known does a lookup wait for tf (tf_timeout, at most once per MOUNT_RETRY)."""
        known = self.mounts.get(frame)
        if known is not None:
            return known
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
            why = f"no transform {self.base_frame} -> '{frame}' in tf: {err}"
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
