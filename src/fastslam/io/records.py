"""The records bags are read into and written from: one laser scan, one odometry pose."""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


BAG_LIBRARY_HINT = ("reading bags needs ROS's rosbag (Debian/Ubuntu: apt-get install python3-rosbag, "
                    "or source ROS Noetic) or rosbags (pip install rosbags)")
ROSBAGS_HINT = "writing bags needs rosbags: pip install rosbags (Python 3.8/3.9: 'rosbags==0.9.23')"


class BagError(RuntimeError):
    """The bag is missing, unreadable, or its topics do not say which to use."""


@dataclass(frozen=True)
class ScanRecord:
    """A laser scan: ranges (M,) float32 [m] in ``frame_id``; beam i at angle_min + i*angle_increment."""

    t: float
    ranges: NDArray[np.float32]
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    frame_id: str = "laser"


@dataclass(frozen=True)
class OdomRecord:
    """Odometry pose of ``child_frame_id`` (the base frame) in ``frame_id`` (odom) [m, m, rad]."""

    t: float
    x: float
    y: float
    yaw: float
    child_frame_id: str = "base_link"
    frame_id: str = "odom"
