"""The map's files: `map_file` on ~save_map and on exit, and a dated copy before a reset.

A reset happens under the filter lock: the map is copied there, and written once the
lock is released.
"""
from __future__ import annotations

import os
import threading
import time

import rospy
from std_srvs.srv import TriggerResponse

from fastslam.filter.frontend import Reset
from fastslam.io.map_files import MapSaveError, remove_stale, save_map

from .map_output import MapCopy, MapOutput
from .params import NodeConfig, map_path
from .stats import Counts


class MapSaves:
    """Saves the best particle's map; serves ~save_map (advertised by the node)."""

    def __init__(self, cfg: NodeConfig, maps: MapOutput, counts: Counts, lock: threading.RLock,
                 scan_topic: str) -> None:
        self.cfg, self.maps, self.counts, self.lock = cfg, maps, counts, lock
        self.scan_topic = scan_topic  # resolved, for the message when nothing was mapped
        self.reset_saves: list[MapCopy] = []
        self.map_file = map_path(cfg.map_file)
        for stale in remove_stale(self.map_file):
            rospy.loginfo(f"removed what a killed save left: {stale}")

    def before_reset(self, event: Reset) -> None:
        """The frontend is about to forget the map (under the lock): keep a copy to save."""
        self.reset_saves.append(self.maps.copy())

    def write_reset_saves(self) -> None:
        with self.lock:
            saves, self.reset_saves = self.reset_saves, []
        for copy in saves:
            stem = f"{self.map_file}-{time.strftime('%Y%m%d-%H%M%S')}"
            path, k = stem, 1
            while os.path.exists(path + ".yaml"):
                k += 1
                path = f"{stem}-{k}"
            ok, where = self._save_copy(path, copy, versioned=False)
            if ok:
                rospy.logwarn(f"the map before the reset is saved: {where}")

    def _save_copy(self, path: str, copy: MapCopy, versioned: bool) -> tuple[bool, str]:
        origin = (float(copy.origin[0]), float(copy.origin[1]), 0.0)
        try:
            _, yaml_path = save_map(path, copy.maps[0], copy.resolution, origin, versioned=versioned)
        except MapSaveError as err:
            rospy.logerr(f"could not save the map: {err}")
            return False, str(err)
        return True, str(yaml_path)

    def save(self) -> tuple[bool, str]:
        if self.counts.updates == 0:
            why = (f"nothing mapped yet: no scan processed ({self.counts.scans} received on "
                   f"{self.scan_topic}, {self.counts.dropped_total()} messages dropped)")
            rospy.logwarn(f"map not saved: {why}")
            return False, why
        # versioned: the YAML is written last and names a fresh image, so a save killed at any
        # moment leaves a consistent pair; <map_file>.pgm is that image too
        ok, where = self._save_copy(self.map_file, self.maps.copy(), versioned=True)
        if ok:
            rospy.loginfo(f"map saved: {where}")
        return ok, where

    def on_save_map(self, _req) -> TriggerResponse:
        ok, message = self.save()
        return TriggerResponse(success=ok, message=message)

    def on_shutdown(self) -> None:
        if self.cfg.save_on_exit and self.counts.updates > 0:
            self.save()
