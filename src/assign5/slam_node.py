"""The FastSLAM ROS node: messages in, one core call per scan, messages out."""
from __future__ import annotations

import threading
import traceback

import numpy as np
import rospy
import tf2_ros
from geometry_msgs.msg import PoseArray, PoseWithCovarianceStamped
from nav_msgs.msg import MapMetaData, OccupancyGrid, Odometry, Path
from nav_msgs.srv import GetMap, GetMapResponse
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Float64
from std_srvs.srv import Trigger, TriggerResponse

from fastslam.config import SlamConfig
from fastslam.filter.frontend import Dropped, Frontend, Reset, drop_key
from fastslam.filter.slam import FastSlam
from fastslam.geometry import compose, inverse
from fastslam.io.map_files import MapSaveError, save_map

from . import convert
from .convert import BadMessage
from .params import NodeConfig, map_path
from .watchdog import Watchdog


class SlamNode:
    """Owns the filter; the scan callback runs it, the others only read or buffer."""

    def __init__(self, cfg: NodeConfig, slam_cfg: SlamConfig) -> None:
        self.cfg = cfg
        self.slam = FastSlam(slam_cfg)
        self.lock = threading.RLock()  # the filter, the odometry buffer, map->odom
        self.odom_arrived = threading.Condition(self.lock)
        self.front = Frontend(self.slam, odom_timeout=cfg.odom_timeout, odom_buffer=cfg.odom_buffer,
                              max_odom_speed=cfg.max_odom_speed, max_odom_jump=cfg.max_odom_jump)
        self.map_to_odom = np.zeros(3)
        self.mounts: dict[str, tuple[tuple[float, float, float], bool]] = {}
        self.last_map_stamp = -np.inf
        self.last_tf_time = rospy.Time(0)
        self.warned_clip = False
        self.updates = 0
        self.scans_seen = 0
        self.entropy = 0.0
        self.dropped: dict[str, int] = {}
        self.update_ms: list[float] = []

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
        self.pub_debug = [rospy.Publisher(f"~particle_map_{i}", OccupancyGrid, queue_size=1, latch=True)
                          for i in range(cfg.debug_maps)]
        self.srv_map = rospy.Service("dynamic_map", GetMap, self.on_get_map)
        self.srv_save = rospy.Service("~save_map", Trigger, self.on_save_map)
        self.sub_odom = rospy.Subscriber(cfg.odom_topic, Odometry, self.on_odom, queue_size=50)
        self.sub_scan = rospy.Subscriber(cfg.scan_topic, LaserScan, self.on_scan,
                                         queue_size=cfg.queue_size, buff_size=2**24)
        if cfg.transform_publish_period > 0:
            self.tf_timer = rospy.Timer(rospy.Duration(cfg.transform_publish_period), self.on_tf_timer)
        rospy.on_shutdown(self.on_shutdown)
        self.watchdog = Watchdog(self.sub_scan.resolved_name, cfg.no_scan_warning, lambda: self.scans_seen)
        rospy.loginfo(f"FastSLAM: {slam_cfg.particles} particles, {slam_cfg.map_resolution} m cells, "
                      f"{cfg.scan_topic} + {cfg.odom_topic} -> map in '{cfg.map_frame}'")

    # -- inputs ----------------------------------------------------------------------
    def on_odom(self, msg: Odometry) -> None:
        try:
            pose = convert.odom_pose(msg)
            with self.lock:
                self.front.add_odom(msg.header.stamp.to_sec(), pose)
                self._log_events()
                self.odom_arrived.notify_all()
        except Dropped as err:  # convert's BadMessage is Dropped too
            self._drop(f"odometry: {err}")

    def on_scan(self, msg: LaserScan) -> None:
        self.scans_seen += 1
        try:
            self._process(msg)
        except Dropped as err:  # convert's BadMessage is Dropped too
            self._drop(str(err))
        except Exception:  # a callback must never take the node down
            rospy.logerr_throttle(5.0, "scan update failed:\n" + traceback.format_exc())

    def _process(self, msg: LaserScan) -> None:
        convert.check_scan(msg)
        stamp = msg.header.stamp.to_sec()
        now = rospy.Time.now().to_sec()
        if now > 0 and stamp > now + self.cfg.max_future:
            raise BadMessage(f"scan stamped {stamp - now:.1f} s in the future")
        self._wait_for_odom(stamp)
        mount, upside_down = self._mount(msg.header.frame_id)  # may wait for tf: not under the lock
        with self.lock:
            try:
                info = self.front.add_scan(convert.scan_from_msg(msg, mount, upside_down))
            finally:
                self._log_events()
            # the live pose: the best particle at an update, tracked (track_scans) or moved by
            # odometry between updates, as the offline tool's live_poses.txt
            self.map_to_odom = compose(self.slam.live_pose, inverse(self.front.scan_odom))
            if not info.processed:
                return
            if info.clipped and not self.warned_clip:
                self.warned_clip = True
                rospy.logwarn("the robot is near the map's edge and map_grow is false: beams past the "
                              "edge are clipped from now on (warned once)")
            self.updates += 1
            self.entropy = info.entropy
        self._publish_update(msg.header.stamp, info)
        if stamp - self.last_map_stamp >= self.cfg.map_update_interval:
            self.last_map_stamp = stamp
            self.publish_map(msg.header.stamp)

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
                self.map_to_odom = np.zeros(3)
                self.last_map_stamp = -np.inf
        self.front.events.clear()

    def _mount(self, frame: str) -> tuple[tuple[float, float, float], bool]:
        """The laser's pose on the base, looked up in tf once per frame."""
        if frame not in self.mounts:
            try:
                t = self.tf_buffer.lookup_transform(self.cfg.base_frame, frame, rospy.Time(0),
                                                    rospy.Duration(self.cfg.tf_timeout))
            except (tf2_ros.LookupException, tf2_ros.ConnectivityException,
                    tf2_ros.ExtrapolationException, tf2_ros.InvalidArgumentException) as err:
                raise BadMessage(f"no transform {self.cfg.base_frame} -> '{frame}' in tf: {err}") from None
            self.mounts[frame] = convert.mount_from_transform(t)
            rospy.loginfo(f"laser '{frame}' on '{self.cfg.base_frame}': x y yaw = "
                          f"{np.round(self.mounts[frame][0], 3).tolist()}, upside down: {self.mounts[frame][1]}")
        return self.mounts[frame]

    def _drop(self, why: str) -> None:
        key = drop_key(why)
        self.dropped[key] = self.dropped.get(key, 0) + 1
        rospy.logwarn_throttle(5.0, f"dropping message: {why} ({self.dropped[key]} so far)")

    # -- outputs ---------------------------------------------------------------------
    def _publish_update(self, stamp: rospy.Time, info) -> None:
        frame = self.cfg.map_frame
        with self.lock:
            poses = self.slam.poses.copy()
            mean, cov = self.slam.mean_pose(), self.slam.covariance()
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

    def publish_map(self, stamp: rospy.Time | None = None) -> None:
        stamp = stamp or rospy.Time.now()
        frame = self.cfg.map_frame
        with self.lock:  # copies only: the messages are built after the lock is released
            grid = self.slam.grid
            shown = [self.slam.best]
            if self.pub_debug:
                shown += np.argsort(-self.slam.weights)[:len(self.pub_debug)].tolist()
            maps = [grid.occupancy(int(i)) for i in shown]
            resolution, origin = grid.resolution, grid.origin.copy()
            trajectory = self.slam.trajectory()
        msg, meta = convert.occupancy_msgs(maps[0], resolution, origin, frame, stamp)
        debug = [convert.occupancy_msgs(m, resolution, origin, frame, stamp)[0] for m in maps[1:]]
        path = convert.path_msg(trajectory, frame, stamp)
        self.pub_map.publish(msg)
        self.pub_meta.publish(meta)
        self.pub_path.publish(path)
        self.pub_entropy.publish(Float64(self.entropy))  # as gmapping: with each map
        for pub, m in zip(self.pub_debug, debug):
            pub.publish(m)

    def on_tf_timer(self, _event) -> None:
        now = rospy.Time.now()
        if now.is_zero() or now == self.last_tf_time:
            return  # sim time not started, or not moved on: no stamp 0, no repeated stamp
        self.last_tf_time = now
        with self.lock:
            x, y, yaw = self.map_to_odom
        t = convert.transform_msg(now + rospy.Duration(self.cfg.tf_delay), self.cfg.map_frame,
                                  self.cfg.odom_frame, x, y, yaw)
        try:
            self.tf_out.sendTransform(t)
        except rospy.ROSException:
            pass  # shutting down

    def on_get_map(self, _req) -> GetMapResponse:
        with self.lock:
            msg, _ = convert.grid_msgs(self.slam.grid, self.slam.best, self.cfg.map_frame, rospy.Time.now())
        return GetMapResponse(map=msg)

    def save(self) -> tuple[bool, str]:
        if self.updates == 0:
            why = (f"nothing mapped yet: no scan processed ({self.scans_seen} received on "
                   f"{self.sub_scan.resolved_name}, {sum(self.dropped.values())} messages dropped)")
            rospy.logwarn(f"map not saved: {why}")
            return False, why
        path = map_path(self.cfg.map_file)
        with self.lock:
            grid, best = self.slam.grid, self.slam.best
            occ = grid.occupancy(best)
            origin = (float(grid.origin[0]), float(grid.origin[1]), 0.0)
        try:
            _, yaml_path = save_map(path, occ, grid.resolution, origin)
        except MapSaveError as err:
            rospy.logerr(f"could not save the map: {err}")
            return False, str(err)
        rospy.loginfo(f"map saved: {yaml_path}")
        return True, str(yaml_path)

    def on_save_map(self, _req) -> TriggerResponse:
        ok, message = self.save()
        return TriggerResponse(success=ok, message=message)

    def on_shutdown(self) -> None:
        if self.cfg.save_on_exit and self.updates > 0:
            self.save()
