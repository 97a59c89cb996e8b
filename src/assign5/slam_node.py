"""The FastSLAM ROS node: messages in, one core call per scan, messages out.

rospy runs every subscriber, service and timer in a thread of its own. The scan
callback owns the filter (under `lock`); the others buffer odometry, or copy what they
need under the lock and build their messages after it. map->odom is a tuple the tf
timer reads without the lock, so tf waits neither for an update nor for a service.
An error that stops processing (not a bad message: those are dropped and counted)
saves the map and stops the node with exit code 1, so that `required="true"` fires.

The map's outputs are in map_output.py, its files in map_saves.py, the counters and
~stats in stats.py, the lasers' mounts in mounts.py.
"""
from __future__ import annotations

import threading
import traceback

import numpy as np
import rospy
import tf2_ros
from geometry_msgs.msg import PoseArray, PoseWithCovarianceStamped
from nav_msgs.msg import Odometry
from nav_msgs.srv import GetMap
from rosgraph_msgs.msg import Clock
from rospy.numpy_msg import numpy_msg
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Float64
from std_srvs.srv import Trigger

from fastslam.config import SlamConfig
from fastslam.filter.frontend import Dropped, Frontend, Reset
from fastslam.filter.scan_wait import ODOM_DELIVERY
from fastslam.filter.slam import FastSlam
from fastslam.geometry import compose, inverse

from . import convert
from .convert import BadMessage
from .map_output import MapOutput
from .map_saves import MapSaves
from .mounts import LaserMounts
from .params import NodeConfig, limits
from .stats import Counts, Stats
from .watchdog import Watchdog


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
                              odom_lookahead=cfg.odom_wait, before_reset=self._before_reset)
        self.map_to_odom = (0.0, 0.0, 0.0)  # replaced whole: the tf timer reads it without the lock
        self.last_tf_time = rospy.Time(0)
        self.last_clock: float | None = None
        self.warned_clip = False
        self.warned_odom_frame = False
        self.fatal: str | None = None
        self.counts = Counts()
        # before the subscribers: a scan may publish, save or reset at once
        self.maps = MapOutput(cfg, self.slam, self.front, self.lock)
        self.saves = MapSaves(cfg, self.maps, self.counts, self.lock, scan_topic=rospy.resolve_name(cfg.scan_topic))
        self.stats = Stats(self.counts, self.slam, self.front, self.lock, self.maps)

        self.tf_buffer = tf2_ros.Buffer(rospy.Duration(30.0))
        self.tf_listener = tf2_ros.TransformListener(self.tf_buffer)
        self.tf_out = tf2_ros.TransformBroadcaster()
        self.mounts = LaserMounts(self.tf_buffer, cfg.base_frame, cfg.tf_timeout)
        self.pub_particles = rospy.Publisher("particles", PoseArray, queue_size=1)
        # one pose per update, each delivered: with a queue of 1 two quick updates lost the first
        self.pub_pose = rospy.Publisher("~pose", PoseWithCovarianceStamped, queue_size=10)
        self.pub_neff = rospy.Publisher("~neff", Float64, queue_size=1)
        self.pub_time = rospy.Publisher("~update_time", Float64, queue_size=1)
        # the services after every publisher: a client that waited for one may stop the node at
        # once (faults.test does), and a SIGTERM earlier in here was seen to hang the exit
        self.srv_map = rospy.Service("dynamic_map", GetMap, self.maps.on_get_map)
        self.srv_save = rospy.Service("~save_map", Trigger, self.saves.on_save_map)
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
        rospy.on_shutdown(self.saves.on_shutdown)
        self.watchdog = Watchdog(self.sub_scan.resolved_name, cfg.no_scan_warning, lambda: self.counts.scans)
        self.stats.start()
        maps = self.slam.limits.map_bytes
        rospy.loginfo(f"FastSLAM: {slam_cfg.particles} particles, {slam_cfg.map_resolution} m cells, "
                      f"{cfg.scan_topic} + {cfg.odom_topic} -> map in '{cfg.map_frame}'; maps up to "
                      f"{cfg.max_map_extent:g} m a side" + (f" and {maps / 2**20:.0f} MB" if maps is not None else ""))

    # -- inputs ----------------------------------------------------------------------
    def on_odom(self, msg: Odometry) -> None:
        try:
            pose = convert.odom_pose(msg)
            self._check_frames(msg)
            with self.lock:
                self.front.add_odom(msg.header.stamp.to_sec(), pose)
                self._log_events()
                self.odom_arrived.notify_all()
        except Dropped as err:  # convert's BadMessage is Dropped too
            self.counts.drop(str(err))  # "odometry with NaN or inf", "... an all-zero quaternion": kinds apart

    def _check_frames(self, msg: Odometry) -> None:
        """The odometry's frames against the node's: its child frame is the base (unless
        base_frame is set); map->odom is published to odom_frame, which should be its parent."""
        warning = self.mounts.odometry_frame(msg.child_frame_id)
        if warning:
            rospy.logwarn(warning)
        parent = msg.header.frame_id.lstrip("/")
        if parent and parent != self.cfg.odom_frame.lstrip("/") and not self.warned_odom_frame:
            self.warned_odom_frame = True
            rospy.logwarn(f"the odometry is in '{parent}' but map->odom is published to odom_frame "
                          f"'{self.cfg.odom_frame}': the map does not join the robot's tf tree; set "
                          f"odom_frame:={parent} (warned once)")

    def on_clock(self, msg: Clock) -> None:
        t = msg.clock.to_sec()
        last, self.last_clock = self.last_clock, t
        if last is not None and t < last:
            with self.lock:
                self.front.restart()
            rospy.logwarn(f"/clock went back from {last:.2f} to {t:.2f} s (a bag or simulator restarted?): "
                          "the next scan starts a new map, the one so far is saved first")

    def on_scan(self, msg: LaserScan) -> None:
        self.counts.scans += 1
        if self.fatal:
            return
        try:
            self._process(msg)
        except Dropped as err:  # convert's BadMessage is Dropped too
            self.counts.drop(str(err))
        except rospy.ROSException as err:
            # a publisher closes only when the node shuts down (Ctrl-C during an update): no fault
            if not (rospy.is_shutdown() or "closed topic" in str(err)):
                self._die(traceback.format_exc())
        except Exception:  # the filter may be half-updated: stop, and let roslaunch see it
            self._die(traceback.format_exc())

    def _process(self, msg: LaserScan) -> None:
        convert.check_scan(msg)
        stamp = msg.header.stamp.to_sec()
        now = rospy.Time.now().to_sec()
        if now > 0 and stamp > now + self.cfg.max_future:
            raise BadMessage(f"scan stamped {stamp - now:.1f} s in the future")
        self._wait_for_odom(stamp)
        mount, upside_down = self.mounts.lookup(msg.header.frame_id)  # may wait for tf: not under the lock
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
                update = self._take_update(info, msg.header.stamp) if info.processed else None
        finally:
            self.saves.write_reset_saves()
        if update is not None:
            self._publish_update(msg.header.stamp, info, *update)
        if self.maps.due(stamp, updated=update is not None):
            self.maps.publish()

    def _take_update(self, info, stamp: rospy.Time) -> tuple:
        """Under the lock, after an update: its warnings and counts, and copies of what
        its messages show (poses, mean, covariance), built after the lock is released."""
        if info.refused:
            rospy.logerr(info.refused)
        if info.clipped and not self.slam.cfg.map_grow and not self.warned_clip:
            self.warned_clip = True
            rospy.logwarn("the robot is near the map's edge and map_grow is false: beams past the "
                          "edge are clipped from now on (warned once)")
        self.counts.updates += 1
        self.maps.entropy = info.entropy
        self.maps.stamp = stamp
        return self.slam.poses.copy(), self.slam.mean_pose(), self.slam.covariance()

    def _wait_for_odom(self, stamp: float) -> None:
        """Gives odometry stamped at or after the scan a moment to arrive, so the odometry
        is interpolated at the scan's stamp when the next message is stamped within
        odom_wait (the Frontend's odom_lookahead), as the offline runner does: up to
        odom_wait, and ODOM_DELIVERY for its delivery, of wall time."""
        def arrived() -> bool:
            latest = self.front.odom.latest
            return latest is not None and latest[0] >= stamp

        with self.odom_arrived:  # on_odom notifies
            self.odom_arrived.wait_for(arrived, timeout=self.cfg.odom_wait + ODOM_DELIVERY)

    def _log_events(self) -> None:
        for event in self.front.events:
            rospy.logwarn(str(event))
            if isinstance(event, Reset):
                self.tf_buffer.clear()
                self.map_to_odom = (0.0, 0.0, 0.0)
                self.maps.forget()
        self.front.events.clear()

    def _die(self, trace: str) -> None:
        if self.fatal:
            return
        self.fatal = trace.strip().splitlines()[-1]
        saving = "; the map is saved first" if self.cfg.save_on_exit and self.counts.updates > 0 else ""
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
        self.counts.update_time(ms, info.neff)

    def _before_reset(self, event: Reset) -> None:
        self.saves.before_reset(event)  # the frontend is made before the saves: it holds this

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
