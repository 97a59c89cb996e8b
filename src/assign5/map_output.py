"""The map's outputs: /map, map_metadata, ~trajectory, ~entropy, the debug particles'
maps and the dynamic_map service.

Each takes copies under the filter lock and builds its messages after it, so a large
map holds up neither the next scan nor tf.
"""
from __future__ import annotations

import threading
from dataclasses import dataclass

import numpy as np
import rospy
from nav_msgs.msg import MapMetaData, OccupancyGrid, Path
from std_msgs.msg import Float64, Header

from fastslam.filter.frontend import Frontend
from fastslam.filter.slam import FastSlam

from . import convert
from .packed import PackedMapResponse, PathCache
from .params import NodeConfig


@dataclass(frozen=True)
class MapCopy:
    """What a map message or a save needs, copied under the lock."""

    maps: list[np.ndarray]   # (H, W) int8 occupancy: the best particle's first
    resolution: float
    origin: np.ndarray
    version: tuple[int, int]  # (resets, updates): the filter's state it shows


class MapOutput:
    """Publishes the best particle's map and path; the node tells it when (`due`, `publish`)."""

    def __init__(self, cfg: NodeConfig, slam: FastSlam, front: Frontend, lock: threading.RLock) -> None:
        self.cfg, self.slam, self.front, self.lock = cfg, slam, front, lock
        self.stamp: rospy.Time | None = None  # of the last processed scan
        self.entropy = 0.0
        self.last_stamp = -np.inf  # [s] of the last map published
        self.unpublished = False   # updates since
        self.map_lock = threading.Lock()  # one map message built at a time: concurrent requests share it
        self.cache: tuple[tuple[int, int], OccupancyGrid, MapMetaData] | None = None
        self.known_cells = 0
        self.path_cache = PathCache(cfg.map_frame)
        self.pub_map = rospy.Publisher("map", OccupancyGrid, queue_size=1, latch=True)
        self.pub_meta = rospy.Publisher("map_metadata", MapMetaData, queue_size=1, latch=True)
        self.pub_path = rospy.Publisher("~trajectory", Path, queue_size=1, latch=True)
        self.pub_entropy = rospy.Publisher("~entropy", Float64, queue_size=1, latch=True)
        self.pub_debug = [rospy.Publisher(f"~particle_map_{i}", OccupancyGrid, queue_size=1, latch=True)
                          for i in range(cfg.debug_maps)]

    def due(self, stamp: float, updated: bool) -> bool:
        """Whether a scan at stamp [s] publishes the map: every map_update_interval while
        updates wait to be published, so a robot that stops still shows its last ones."""
        self.unpublished = self.unpublished or updated
        if self.unpublished and stamp - self.last_stamp >= self.cfg.map_update_interval:
            self.last_stamp, self.unpublished = stamp, False
            return True
        return False

    def forget(self) -> None:
        """The filter was reset: the next update publishes, and the path starts again."""
        self.last_stamp, self.unpublished = -np.inf, False
        self.path_cache.forget()

    def copy(self, debug: int = 0) -> MapCopy:
        """The best particle's occupancy (and the debug best ones'): a copy, under the lock."""
        with self.lock:
            grid = self.slam.grid
            shown = [self.slam.best]
            if debug:
                shown += np.argsort(-self.slam.weights)[:debug].tolist()
            return MapCopy(maps=[grid.occupancy(int(i)) for i in shown], resolution=grid.resolution,
                           origin=grid.origin.copy(), version=(self.front.resets, self.slam.updates))

    def _msgs(self) -> tuple[OccupancyGrid, MapMetaData]:
        """The best particle's map as messages, built once per filter state."""
        with self.map_lock:
            with self.lock:
                version = (self.front.resets, self.slam.updates)
                if self.cache is not None and self.cache[0] == version:
                    return self.cache[1], self.cache[2]
                copy = self.copy()
                stamp = self.stamp if self.stamp is not None else rospy.Time.now()
            msg, meta = convert.occupancy_msgs(copy.maps[0], copy.resolution, copy.origin, self.cfg.map_frame, stamp)
            self.cache = (version, msg, meta)
            self.known_cells = int(np.count_nonzero(copy.maps[0] != -1))
            return msg, meta

    def publish(self) -> None:
        frame = self.cfg.map_frame
        with self.lock:  # copies only: the messages are built after the lock is released
            history = self.slam.history
            tail, settled = history.path(self.slam.best, self.path_cache.rows), history.settled
            debug = self.copy(len(self.pub_debug)) if self.pub_debug else None
            stamp = self.stamp if self.stamp is not None else rospy.Time.now()
        msg, meta = self._msgs()
        path = self.path_cache.message(tail, settled, Header(frame_id=frame, stamp=stamp))
        self.pub_map.publish(msg)
        self.pub_meta.publish(meta)
        self.pub_path.publish(path)
        self.pub_entropy.publish(Float64(self.entropy))  # as gmapping: with each map
        if debug is not None:
            for pub, occ in zip(self.pub_debug, debug.maps[1:]):
                pub.publish(convert.occupancy_msgs(occ, debug.resolution, debug.origin, frame, stamp)[0])

    def on_get_map(self, _req) -> PackedMapResponse:  # dynamic_map, advertised by the node
        return PackedMapResponse(map=self._msgs()[0])
