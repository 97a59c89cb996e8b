"""Large messages serialised by numpy: a map's cells and a path's poses written as bytes.

genpy serialises an int8[] from a list (one Python int per cell: 16 M cells take
seconds and a gigabyte) and a Path pose by pose. These classes send the same bytes
(subscribers see plain nav_msgs messages) from numpy arrays, and `PathCache` packs the
poses a path can no longer change only once.
"""
from __future__ import annotations

import io
import struct
from typing import Any

import numpy as np
from nav_msgs.msg import OccupancyGrid, Path
from nav_msgs.srv import GetMapResponse


def _without_last_array(msg: Any) -> bytes:
    """msg serialised with its last field (an empty array) and that array's length left out."""
    buff = io.BytesIO()
    msg.serialize(buff)
    return buff.getvalue()[:-4]


class PackedGrid(OccupancyGrid):
    """An OccupancyGrid whose data is a numpy int8 array, serialised in one write."""

    def serialize(self, buff: Any) -> None:
        data = np.ascontiguousarray(self.data, dtype=np.int8)
        buff.write(_without_last_array(OccupancyGrid(header=self.header, info=self.info, data=[])))
        buff.write(struct.pack("<I", data.size))
        buff.write(memoryview(data).cast("B"))   # no copy before the buffer's own


class PackedMapResponse(GetMapResponse):
    """GetMap's response (its one field, the map, is all it serialises) for a PackedGrid."""

    def serialize(self, buff: Any) -> None:
        self.map.serialize(buff)


def _pose_dtype(frame: str) -> np.dtype:
    """One serialised geometry_msgs/PoseStamped: header (seq, stamp, frame_id), position, orientation."""
    return np.dtype([("seq", "<u4"), ("secs", "<u4"), ("nsecs", "<u4"), ("frame_len", "<u4"),
                     ("frame", f"S{len(frame.encode())}"), ("x", "<f8"), ("y", "<f8"), ("z", "<f8"),
                     ("qx", "<f8"), ("qy", "<f8"), ("qz", "<f8"), ("qw", "<f8")])


def pack_poses(traj: np.ndarray, frame: str) -> bytes:
    """The PoseStamped array of a Path for rows t, x, y, theta (T, 4), as genpy writes it
    (stamps as rospy.Time.from_sec: whole seconds, then nanoseconds truncated)."""
    rec = np.zeros(len(traj), dtype=_pose_dtype(frame))
    t = traj[:, 0]
    secs = t.astype(np.int64)
    rec["secs"] = secs
    rec["nsecs"] = ((t - secs) * 1e9).astype(np.int64)
    rec["frame_len"] = len(frame.encode())
    rec["frame"] = frame.encode()
    rec["x"], rec["y"] = traj[:, 1], traj[:, 2]
    rec["qz"], rec["qw"] = np.sin(traj[:, 3] / 2), np.cos(traj[:, 3] / 2)
    return rec.tobytes()


class PackedPath(Path):
    """A Path whose poses are given already serialised (pack_poses) with their count."""

    def __init__(self, *args: Any, packed: bytes = b"", count: int = 0, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.packed, self.count = packed, count

    def serialize(self, buff: Any) -> None:
        buff.write(_without_last_array(Path(header=self.header, poses=[])))
        buff.write(struct.pack("<I", self.count))
        buff.write(self.packed)


class PathCache:
    """The best particle's path as a message, with the settled rows (History.settled:
    every lineage's, never changed by a later update) packed once. Used by the one
    thread that publishes; `forget` after a reset."""

    def __init__(self, frame: str) -> None:
        self.frame = frame
        self.rows = 0        # settled rows packed: ask the history for the path from this row on
        self.packed = bytearray()

    def forget(self) -> None:
        self.rows, self.packed = 0, bytearray()

    def message(self, tail: np.ndarray, settled: int, header: Any) -> PackedPath:
        """tail: the path from row `self.rows` on (History.path(best, cache.rows));
        settled: how many rows of the path are settled."""
        new = max(min(settled - self.rows, len(tail)), 0)
        body = pack_poses(tail, self.frame)
        cut = new * _pose_dtype(self.frame).itemsize
        self.packed += body[:cut]
        self.rows += new
        return PackedPath(header=header, packed=bytes(self.packed) + body[cut:], count=self.rows + len(tail) - new)
