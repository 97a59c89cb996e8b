"""The records bags are read into and written from: one laser scan, one odometry pose."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

ROSBAGS_HINT = ("reading/writing bags needs the Python package rosbags>=0.10, which Debian does not ship: "
                "run the tool with the .venv that `make setup` makes (.venv/bin/python -m ...), or install it "
                "for /usr/bin/python3: pip3 install --user --break-system-packages 'rosbags>=0.10'")


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
