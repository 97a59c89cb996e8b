"""The FastSLAM ROS node: messages in, one core call per scan, messages out.

rospy runs every subscriber, service and timer in a thread of its own. The scan
callback owns the filter (under `lock`); the others buffer odometry, or copy what they
need under the lock and build their messages after it. map->odom is a tuple the tf
timer reads without the lock, so tf waits neither for an update nor for a service.
An error that stops processing (not a bad message: those are dropped and counted)
saves the map and stops the node with exit code 1, so that `required="true"` fires.
"""
from __future__ import annotations

import ctypes
import json
import os
import resource
import threading
import time
import traceback
from dataclasses import dataclass
from typing import Callable

import numpy as np
import rospy
import tf2_ros
from geometry_msgs.msg import PoseArray, PoseWithCovarianceStamped
from nav_msgs.msg import MapMetaData, OccupancyGrid, Odometry, Path
from nav_msgs.srv import GetMap
from rosgraph_msgs.msg import Clock
from rospy.numpy_msg import numpy_msg
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Float64, Header, String
from std_srvs.srv import Trigger, TriggerResponse

from fastslam.config import SlamConfig
from fastslam.filter.frontend import Dropped, Frontend, Reset, drop_key
from fastslam.filter.slam import FastSlam
from fastslam.geometry import compose, inverse
from fastslam.io.map_files import MapSaveError, remove_stale, save_map

from . import convert
from .convert import BadMessage
from .packed import PackedMapResponse, PathCache
from .params import NodeConfig, limits, map_path
from .watchdog import Watchdog

MOUNT_RETRY = 1.0    # [s] a laser frame not found in tf is looked up again at most this often
FAILED_FRAMES = 256  # unknown frames remembered (a flood of made-up names must not grow memory)
STATS_PERIOD = 1.0   # [s] of wall time between ~stats messages
DROP_KINDS = 100     # kinds of drop counted apart; more are counted together


@dataclass(frozen=True)
class MapCopy:
    """What a map message or a save needs, copied under the lock."""

    maps: list[np.ndarray]   # (H, W) int8 occupancy: the best particle's first
    resolution: float
    origin: np.ndarray
    version: tuple[int, int]  # (resets, updates): the filter's state it shows


def _logged(n: int) -> bool:
    """Whether the n-th occurrence of a thing is logged: the 1st, 10th, 100th..."""
    return n == 10 ** int(round(np.log10(n)))


class SlamNode:
    """Owns the filter; the scan callback runs it, the others only read or buffer."""

    def __init__(self, cfg: NodeConfig, slam_cfg: SlamConfig) -> None:
        self.cfg = cfg
        self.slam = FastSlam(slam_cfg, limits=limits(cfg, slam_cfg))
        self.lock = threading.RLock()  # the filter and the odometry buffer
        self.odom_arrived = threading.Condition(self.lock)
        self.front = Frontend(self.slam, odom_timeout=cfg.odom_timeout, odom_buffer=cfg.odom_buffer,
                              max_odom_speed=cfg.max_odom_speed, max_odom_jump=cfg.max_odom_jump,
                              reset_backwards=cfg.reset_backwards, max_beams=cfg.max_beams,
                              before_reset=self._before_reset)
        self.map_to_odom = (0.0, 0.0, 0.0)  # replaced whole: the tf timer reads it without the lock
        self.mounts: dict[str, tuple[tuple[float, float, float], bool]] = {}
        self.mount_failed: dict[str, tuple[float, str]] = {}  # frame -> (when, why) of its last failed lookup
        self.last_mount_wait = -np.inf
        self.last_map_stamp = -np.inf
        self.map_stamp: rospy.Time | None = None  # of the last processed scan
        self.last_tf_time = rospy.Time(0)
        self.last_clock: float | None = None
        self.warned_clip = False
        self.updates = 0
        self.scans_seen = 0
        self.entropy = 0.0
        self.dropped: dict[str, int] = {}
        self.count_lock = threading.Lock()  # dropped
        self.update_ms: list[float] = []
        self.fatal: str | None = None
        self.reset_saves: list[MapCopy] = []
        self.map_lock = threading.Lock()  # one map message built at a time: concurrent requests share it
        self.map_cache: tuple[tuple[int, int], OccupancyGrid, MapMetaData] | None = None
        self.known_cells = 0
        self.path_cache = PathCache(cfg.map_frame)
        self.map_file = map_path(cfg.map_file)
        for stale in remove_stale(self.map_file):
            rospy.loginfo(f"removed what a killed save left: {stale}")

        self.tf_buffer = tf2_ros.Buffer(rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.tf_out = tf2_ros.TransformBroadcaster()
        self.pub_particles = rospy.Publisher("particles", PoseArray, queue_size=1)
        self.pub_map = rospy.Publisher("map", OccupancyGrid, queue_size=1, latch=True)
        self.pub_meta = rospy.Publisher("map_metadata", MapMetaData, queue_size=1, latch=True)
        self.pub_pose = rospy.Publisher("~pose", PoseWithCovarianceStamped, queue_size=1)
        self.pub_path = rospy.Publisher("~trajectory", Path, queue_size=1, latch=True)
        self.pub_neff = rospy.Publisher("~neff", Float64, queue_size=1)
        self.pub_time = rospy.Publisher("~update_time", Float64, queue_size=1)
        self.pub_entropy = rospy.Publisher("~entropy", Float64, queue_size=1, latch=True)
        self.pub_stats = rospy.Publisher("~stats", String, queue_size=1, latch=True)
        self.pub_debug = [rospy.Publisher(f"~particle_map_{i}", OccupancyGrid, queue_size=1, latch=True)
                          for i in range(cfg.debug_maps)]
        self.srv_map = rospy.Service("dynamic_map", GetMap, self.on_get_map)
        self.srv_save = rospy.Service("~save_map", Trigger, self.on_save_map)
        self.sub_odom = rospy.Subscriber(cfg.odom_topic, Odometry, self.on_odom, queue_size=50)
        # numpy_msg: ranges arrive as an array, read at once (genpy would make a Python float
        # per beam while holding the interpreter: a scan of a million beams held up tf)
        self.sub_scan = rospy.Subscriber(cfg.scan_topic, numpy_msg(LaserScan), self.on_scan,
                                         queue_size=cfg.queue_size, buff_size=2**24)
        if not rospy.rostime.is_wallclock():
            self.sub_clock = rospy.Subscriber("/clock", Clock, self.on_clock, queue_size=10)
        if cfg.transform_publish_period > 0:
            # reset: the timer goes on when /clock goes back (a bag or simulator restarted)
            self.tf_timer = rospy.Timer(rospy.Duration(cfg.transform_publish_period), self.on_tf_timer, reset=True)
        rospy.on_shutdown(self.on_shutdown)
        self.watchdog = Watchdog(self.sub_scan.resolved_name, cfg.no_scan_warning, lambda: self.scans_seen)
        threading.Thread(target=self._stats_loop, name="stats", daemon=True).start()
        maps = self.slam.limits.map_bytes
        rospy.loginfo(f"FastSLAM: {slam_cfg.particles} particles, {slam_cfg.map_resolution} m cells, "
                      f"{cfg.scan_topic} + {cfg.odom_topic} -> map in '{cfg.map_frame}'; maps up to "
                      f"{cfg.max_map_extent:g} m a side" + (f" and {maps / 2**20:.0f} MB" if maps is not None else ""))

    # -- inputs ----------------------------------------------------------------------
    def on_odom(self, msg: Odometry) -> None:
        try:
            pose = convert.odom_pose(msg)
            with self.lock:
                self.front.add_odom(msg.header.stamp.to_sec(), pose)
                self._log_events()
                self.odom_arrived.notify_all()
        except Dropped as err:  # convert's BadMessage is Dropped too
            self._drop(str(err))  # "odometry with NaN or inf", "... an all-zero quaternion": kinds apart

    def on_clock(self, msg: Clock) -> None:
        t = msg.clock.to_sec()
        last, self.last_clock = self.last_clock, t
        if last is not None and t < last:
            with self.lock:
                self.front.restart()
            rospy.logwarn(f"/clock went back from {last:.2f} to {t:.2f} s (a bag or simulator restarted?): "
                          "the next scan starts a new map, the one so far is saved first")

    def on_scan(self, msg: LaserScan) -> None:
        self.scans_seen += 1
        if self.fatal:
            return
        try:
            self._process(msg)
        except Dropped as err:  # convert's BadMessage is Dropped too
            self._drop(str(err))
        except Exception:  # the filter may be half-updated: stop, and let roslaunch see it
            self._die(traceback.format_exc())

    def _process(self, msg: LaserScan) -> None:
        convert.check_scan(msg)
        stamp = msg.header.stamp.to_sec()
        now = rospy.Time.now().to_sec()
        if now > 0 and stamp > now + self.cfg.max_future:
            raise BadMessage(f"scan stamped {stamp - now:.1f} s in the future")
        self._wait_for_odom(stamp)
        mount, upside_down = self._mount(msg.header.frame_id)  # may wait for tf: not under the lock
        scan = convert.scan_from_msg(msg, mount, upside_down)
        try:
            with self.lock:
                try:
                    info = self.front.add_scan(scan)
                finally:
                    self._log_events()
                # the live pose: the best particle at an update, tracked (track_scans) or moved by
                # odometry between updates, as the offline tool's live_poses.txt
                x, y, yaw = compose(self.slam.live_pose, inverse(self.front.scan_odom))
                self.map_to_odom = (float(x), float(y), float(yaw))
                if not info.processed:
                    return
                if info.refused:
                    rospy.logerr(info.refused)
                if info.clipped and not self.slam.cfg.map_grow and not self.warned_clip:
                    self.warned_clip = True
                    rospy.logwarn("the robot is near the map's edge and map_grow is false: beams past the "
                                  "edge are clipped from now on (warned once)")
                self.updates += 1
                self.entropy = info.entropy
                self.map_stamp = msg.header.stamp
                poses = self.slam.poses.copy()
                mean, cov = self.slam.mean_pose(), self.slam.covariance()
        finally:
            self._write_reset_saves()
        self._publish_update(msg.header.stamp, info, poses, mean, cov)
        if stamp - self.last_map_stamp >= self.cfg.map_update_interval:
            self.last_map_stamp = stamp
            self.publish_map()

    def _wait_for_odom(self, stamp: float) -> None:
        """Gives odometry published with the scan a moment to arrive, so the scan is
        matched with odometry at its own stamp, as the offline runner does."""
        def arrived() -> bool:
            latest = self.front.odom.latest
            return latest is not None and latest[0] >= stamp

        with self.odom_arrived:  # on_odom notifies
            self.odom_arrived.wait_for(arrived, timeout=self.cfg.odom_wait)

    def _log_events(self) -> None:
        for event in self.front.events:
            rospy.logwarn(str(event))
            if isinstance(event, Reset):
                self.tf_buffer.clear()
                self.map_to_odom = (0.0, 0.0, 0.0)
                self.last_map_stamp = -np.inf
                self.path_cache.forget()
        self.front.events.clear()

    def _mount(self, frame: str) -> tuple[tuple[float, float, float], bool]:
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
            wait, self.last_mount_wait = self.cfg.tf_timeout, now
        try:
            t = self.tf_buffer.lookup_transform(self.cfg.base_frame, frame, rospy.Time(0), rospy.Duration(wait))
        except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                tf2_ros.ExtrapolationException, tf2_ros.InvalidArgumentException) as err:
            why = f"no transform {self.cfg.base_frame} -> '{frame}' in tf: {err}"
            self.mount_failed.pop(frame, None)
            self.mount_failed[frame] = (time.monotonic(), why)
            while len(self.mount_failed) > FAILED_FRAMES:
                del self.mount_failed[next(iter(self.mount_failed))]
            raise BadMessage(why) from None
        self.mounts[frame] = convert.mount_from_transform(t)
        self.mount_failed.pop(frame, None)
        rospy.loginfo(f"laser '{frame}' on '{self.cfg.base_frame}': x y yaw = "
                      f"{np.round(self.mounts[frame][0], 3).tolist()}, upside down: {self.mounts[frame][1]}")
        return self.mounts[frame]

    def _drop(self, why: str) -> None:
        """Counts a dropped message by its kind; warns at the 1st, 10th, 100th... of each kind."""
        key = drop_key(why)
        with self.count_lock:   # scans and odometry are dropped in threads of their own
            if key not in self.dropped and len(self.dropped) >= DROP_KINDS:
                key = f"other kinds (more than {DROP_KINDS})"   # made-up frame names must not grow memory
            n = self.dropped.get(key, 0) + 1
            self.dropped[key] = n
        if _logged(n):
            rospy.logwarn(f"dropping message: {why} ({n} so far" +
                          ("; said again at the 10th, 100th, ...)" if n == 1 else ")"))

    def _die(self, trace: str) -> None:
        if self.fatal:
            return
        self.fatal = trace.strip().splitlines()[-1]
        saving = "; the map is saved first" if self.cfg.save_on_exit and self.updates > 0 else ""
        rospy.logfatal(f"scan update failed: slam.py stops (exit code 1){saving}:\n{trace}")
        rospy.signal_shutdown(f"scan update failed: {self.fatal}")

    # -- outputs ---------------------------------------------------------------------
    def _publish_update(self, stamp: rospy.Time, info, poses: np.ndarray, mean: np.ndarray, cov: np.ndarray) -> None:
        frame = self.cfg.map_frame
        self.pub_particles.publish(convert.pose_array(poses, frame, stamp))
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id, msg.header.stamp = frame, stamp
        msg.pose.pose = convert.pose_msg(*mean)
        c = np.zeros((6, 6))
        c[np.ix_([0, 1, 5], [0, 1, 5])] = cov
        msg.pose.covariance = c.ravel().tolist()
        self.pub_pose.publish(msg)
        self.pub_neff.publish(Float64(info.neff))
        ms = 1000.0 * info.seconds
        self.pub_time.publish(Float64(ms))
        self.update_ms.append(ms)
        if len(self.update_ms) >= 50:
            rospy.loginfo(f"{self.updates} updates, {np.mean(self.update_ms):.1f} ms mean "
                          f"({np.max(self.update_ms):.1f} max) per update, Neff {info.neff:.1f}, "
                          f"dropped {sum(self.dropped.values())}")
            self.update_ms.clear()

    def _map_copy(self, debug: int = 0) -> MapCopy:
        """The best particle's occupancy (and the debug best ones'): a copy, under the lock."""
        with self.lock:
            grid = self.slam.grid
            shown = [self.slam.best]
            if debug:
                shown += np.argsort(-self.slam.weights)[:debug].tolist()
            return MapCopy(maps=[grid.occupancy(int(i)) for i in shown], resolution=grid.resolution,
                           origin=grid.origin.copy(), version=(self.front.resets, self.slam.updates))

    def _map_msgs(self) -> tuple[OccupancyGrid, MapMetaData]:
        """The best particle's map as messages, built once per filter state."""
        with self.map_lock:
            with self.lock:
                version = (self.front.resets, self.slam.updates)
                if self.map_cache is not None and self.map_cache[0] == version:
                    return self.map_cache[1], self.map_cache[2]
                copy = self._map_copy()
                stamp = self.map_stamp if self.map_stamp is not None else rospy.Time.now()
            msg, meta = convert.occupancy_msgs(copy.maps[0], copy.resolution, copy.origin, self.cfg.map_frame, stamp)
            self.map_cache = (version, msg, meta)
            self.known_cells = int(np.count_nonzero(copy.maps[0] != -1))
            return msg, meta

    def publish_map(self) -> None:
        frame = self.cfg.map_frame
        with self.lock:  # copies only: the messages are built after the lock is released
            history = self.slam.history
            tail, settled = history.path(self.slam.best, self.path_cache.rows), history.settled
            debug = self._map_copy(len(self.pub_debug)) if self.pub_debug else None
            stamp = self.map_stamp if self.map_stamp is not None else rospy.Time.now()
        msg, meta = self._map_msgs()
        path = self.path_cache.message(tail, settled, Header(frame_id=frame, stamp=stamp))
        self.pub_map.publish(msg)
        self.pub_meta.publish(meta)
        self.pub_path.publish(path)
        self.pub_entropy.publish(Float64(self.entropy))  # as gmapping: with each map
        if debug is not None:
            for pub, occ in zip(self.pub_debug, debug.maps[1:]):
                pub.publish(convert.occupancy_msgs(occ, debug.resolution, debug.origin, frame, stamp)[0])

    def on_tf_timer(self, _event) -> None:
        now = rospy.Time.now()
        if now.is_zero() or now == self.last_tf_time:
            return  # sim time not started, or not moved on: no stamp 0, no repeated stamp
        self.last_tf_time = now
        x, y, yaw = self.map_to_odom
        t = convert.transform_msg(now + rospy.Duration(self.cfg.tf_delay), self.cfg.map_frame,
                                  self.cfg.odom_frame, x, y, yaw)
        try:
            self.tf_out.sendTransform(t)
        except rospy.ROSException:
            pass  # shutting down

    def on_get_map(self, _req) -> PackedMapResponse:
        return PackedMapResponse(map=self._map_msgs()[0])

    # -- saves -----------------------------------------------------------------------
    def _before_reset(self, event: Reset) -> None:
        """The frontend is about to forget the map (under the lock): keep a copy to save."""
        self.reset_saves.append(self._map_copy())

    def _write_reset_saves(self) -> None:
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
        if self.updates == 0:
            why = (f"nothing mapped yet: no scan processed ({self.scans_seen} received on "
                   f"{self.sub_scan.resolved_name}, {sum(self.dropped.values())} messages dropped)")
            rospy.logwarn(f"map not saved: {why}")
            return False, why
        # versioned: the YAML is written last and names a fresh image, so a save killed at any
        # moment leaves a consistent pair; <map_file>.pgm is that image too
        ok, where = self._save_copy(self.map_file, self._map_copy(), versioned=True)
        if ok:
            rospy.loginfo(f"map saved: {where}")
        return ok, where

    def on_save_map(self, _req) -> TriggerResponse:
        ok, message = self.save()
        return TriggerResponse(success=ok, message=message)

    def on_shutdown(self) -> None:
        if self.cfg.save_on_exit and self.updates > 0:
            self.save()

    # -- ~stats ----------------------------------------------------------------------
    def stats(self) -> dict:
        """Counters for ~stats (JSON): what was dropped and why, the rules that fired, the map."""
        grid, lim = self.slam.grid, self.slam.limits
        with open("/proc/self/statm") as f:
            rss = int(f.read().split()[1]) * resource.getpagesize()
        with self.count_lock:
            dropped = dict(self.dropped)
        with self.lock:
            rules = dict(self.front.counts)
        return {"scans": self.scans_seen, "updates": self.updates, "resets": self.front.resets,
                "dropped": dropped, "rules": rules,
                "map_growth_refused": self.slam.refusals, "known_cells": self.known_cells,
                "map_cells": list(grid.shape), "maps_mb": round(grid.nbytes / 2**20, 1),
                "maps_limit_mb": None if lim.map_bytes is None else round(lim.map_bytes / 2**20, 1),
                "rss_mb": round(rss / 2**20, 1)}

    def _stats_loop(self) -> None:
        trim = _malloc_trim()
        while not rospy.is_shutdown():
            trim()   # what large messages (maps, scans of many beams) were buffered in goes back
            try:
                self.pub_stats.publish(String(json.dumps(self.stats())))
            except (rospy.ROSException, OSError, RuntimeError):
                return  # shutting down
            time.sleep(STATS_PERIOD)


def _malloc_trim() -> Callable[[], object]:
    """glibc's malloc_trim(0), or nothing where there is none."""
    try:
        libc = ctypes.CDLL("libc.so.6")
        return lambda: libc.malloc_trim(0)
    except (OSError, AttributeError):
        return lambda: None


M_ARENA_MAX = -8  # glibc's mallopt parameter


def one_malloc_arena() -> None:
    """Makes every thread allocate from one glibc arena (call before any thread starts).

    rospy serves each service call and connection in a thread of its own, and glibc
    gives threads arenas of their own: what they buffered (a map sent to 20 callers at
    once) then stays resident, +200 MB for a 2000 x 2000-cell map. The GIL serialises
    the threads anyway, so sharing one arena costs nothing measurable.
    """
    try:
        ctypes.CDLL("libc.so.6").mallopt(M_ARENA_MAX, 1)
    except (OSError, AttributeError):
        pass  # not glibc
