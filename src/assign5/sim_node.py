"""ROS adapter of the 2D burger simulator (physics in fastslam.sim): topics, tf, /clock, pacing.

Publishes ``scan`` (LaserScan, frame base_scan), ``odom`` (Odometry odom -> base_footprint) and
the same tf, static base_footprint -> base_link -> base_scan, ``ground_truth`` (Odometry in
frame ``world``, tied to ``map`` by a static tf: a SLAM map frame starts at the spawn pose, so
RViz shows the truth where a perfect map would put it), ``route_done`` (Bool, latched) and,
with use_sim_time, ``/clock``. Driving into a wall is logged once per contact.
Subscribes ``cmd_vel`` (Twist). The simulator owns time: it advances in fixed ticks and
sleeps on the wall clock, never on rospy time (that would wait on its own /clock).
"""
from __future__ import annotations

import sys
import threading
import time
from pathlib import Path

import numpy as np
import rospy
import tf2_ros
from geometry_msgs.msg import Twist
from nav_msgs.msg import Odometry
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import LaserScan
from std_msgs.msg import Bool

from fastslam.config import ConfigError
from fastslam.geometry import inverse
from fastslam.sim import SimConfig, Simulation, World, WorldError, load_route, load_world
from fastslam.sim.lidar import driver_ranges
from fastslam.sim.sim import Tick

from . import convert


def default_worlds_dir() -> Path:
    """The package's worlds/ (source tree layout: src/assign5/ -> ../../worlds)."""
    return Path(__file__).resolve().parents[2] / "worlds"


def resolve_world(name: str, worlds_dir: Path) -> Path:
    """A world name (``room``) or path -> an existing file; WorldError listing the choices."""
    for cand in (Path(name).expanduser(), worlds_dir / name, worlds_dir / f"{name}.yaml"):
        if cand.is_file():
            return cand
    names = sorted(p.stem for p in worlds_dir.glob("*.yaml") if not p.stem.endswith(".route"))
    raise WorldError(f"world '{name}' is neither a file nor in {worlds_dir} (available: {', '.join(names)})")


def resolve_route(route: str, worlds_dir: Path) -> np.ndarray | None:
    """'' -> None; inline YAML, a path, or a name in worlds/ (``room`` -> room.route.yaml) -> waypoints (W, 2)."""
    route = route.strip()
    if not route:
        return None
    if route.startswith(("[", "{")):
        return load_route(route)
    # a world's name means its route file, not the world file of the same name
    for cand in (Path(route).expanduser(), worlds_dir / f"{route}.route.yaml", worlds_dir / route,
                 worlds_dir / f"{route}.yaml"):
        if cand.is_file():
            return load_route(str(cand))
    raise WorldError(f"route '{route}' is neither a file, nor inline YAML, nor in {worlds_dir}")


def load() -> tuple[SimConfig, World, np.ndarray | None]:
    """Private parameters -> (config, world, route); on a bad value logfatal one line and exit 2."""
    try:
        cfg = SimConfig.from_dict(rospy.get_param("~", {}))
        worlds_dir = Path(cfg.worlds_dir) if cfg.worlds_dir else default_worlds_dir()
        world = load_world(resolve_world(cfg.world, worlds_dir))
        route = resolve_route(cfg.route, worlds_dir)
    except ConfigError as err:
        rospy.logfatal(f"{rospy.get_name()}: bad parameter: {err}")
        sys.exit(2)
    except WorldError as err:
        rospy.logfatal(f"{rospy.get_name()}: {err}")
        sys.exit(2)
    return cfg, world, route


def _odometry(stamp: rospy.Time, frame: str, pose: np.ndarray, v: float, w: float, var: float) -> Odometry:
    msg = Odometry()
    msg.header.stamp, msg.header.frame_id, msg.child_frame_id = stamp, frame, "base_footprint"
    msg.pose.pose = convert.pose_msg(*pose)
    msg.twist.twist.linear.x, msg.twist.twist.angular.z = v, w
    cov = [0.0] * 36
    for i in (0, 7, 35):               # x, y, yaw; z/roll/pitch are fixed in 2D
        cov[i] = var
    msg.pose.covariance = cov
    msg.twist.covariance = cov
    return msg


class SimNode:
    """Runs a Simulation and publishes it; ``run()`` blocks until shutdown."""

    def __init__(self, cfg: SimConfig, world: World, route: np.ndarray | None) -> None:
        self.cfg = cfg
        self.sim = Simulation(world, cfg, np.random.default_rng(cfg.seed), route=route)
        self.use_sim_time = bool(rospy.get_param("/use_sim_time", False))
        self.speed = cfg.speed if self.use_sim_time else 1.0
        if not self.use_sim_time and cfg.speed != 1.0:
            rospy.logwarn("~speed=%s ignored: faster than real time needs use_sim_time", cfg.speed)
        # without sim time, stamps are wall time at start + sim time, so they stay evenly spaced
        self.t0 = 0.0 if self.use_sim_time else rospy.Time.now().to_sec()
        self.lock = threading.Lock()
        self.pub_clock = rospy.Publisher("/clock", Clock, queue_size=10) if self.use_sim_time else None
        self.pub_scan = rospy.Publisher("scan", LaserScan, queue_size=5)
        self.pub_odom = rospy.Publisher("odom", Odometry, queue_size=10)
        self.pub_truth = rospy.Publisher("ground_truth", Odometry, queue_size=10)
        self.pub_done = rospy.Publisher("route_done", Bool, queue_size=1, latch=True)
        self.tf = tf2_ros.TransformBroadcaster()
        self.tf_static = tf2_ros.StaticTransformBroadcaster()
        rospy.Subscriber("cmd_vel", Twist, self._on_cmd_vel, queue_size=1)
        self.scan_msg = self._scan_template()
        self.odom_var = 0.0 if not cfg.odom_noise else max(cfg.odom_slip_linear, cfg.odom_slip_angular) ** 2
        if route is not None:
            self.pub_done.publish(Bool(False))
        rospy.loginfo("simulator: world '%s' (%d segments, %d circles), spawn %s, %s, speed %.2f%s",
                      world.name, len(world.segments), len(world.circles), np.round(self.sim.spawn, 3).tolist(),
                      f"route of {len(route)} waypoints" if route is not None else "driven by cmd_vel",
                      self.speed, "" if self.use_sim_time else " (wall clock)")

    def _on_cmd_vel(self, msg: Twist) -> None:
        if self.sim.route is not None:
            rospy.logwarn_throttle(10.0, "simulator: a route is running; cmd_vel is ignored")
            return
        with self.lock:
            self.sim.set_cmd(msg.linear.x, msg.angular.z)

    def _scan_template(self) -> LaserScan:
        lidar = self.sim.lidar
        msg = LaserScan()
        msg.header.frame_id = "base_scan"
        msg.angle_min = lidar.angle_min
        msg.angle_increment = lidar.angle_increment
        msg.angle_max = lidar.angle_min + (lidar.num_beams - 1) * lidar.angle_increment
        msg.time_increment = 0.0          # every beam at the same instant: no motion distortion
        msg.scan_time = 1.0 / self.cfg.scan_rate
        msg.range_min, msg.range_max = lidar.range_min, lidar.range_max
        return msg

    def _stamp(self, t: float) -> rospy.Time:
        return rospy.Time.from_sec(self.t0 + t)

    def _publish_static(self, stamp: rospy.Time) -> None:
        c = self.cfg
        self.tf_static.sendTransform([
            convert.transform_msg(stamp, "base_footprint", "base_link", 0.0, 0.0, 0.0, z=c.base_link_z),
            convert.transform_msg(stamp, "base_link", "base_scan", c.laser_x, c.laser_y, 0.0, z=c.laser_z),
            convert.transform_msg(stamp, "map", "world", *inverse(self.sim.spawn))])

    def _publish(self, tick: Tick) -> None:
        stamp = self._stamp(tick.t)
        if self.pub_clock is not None:
            self.pub_clock.publish(Clock(stamp))
        sim = self.sim
        if tick.odom_due:
            odom = sim.odom.pose
            self.pub_odom.publish(_odometry(stamp, "odom", odom, *sim.odom_twist, self.odom_var))
            self.tf.sendTransform(convert.transform_msg(stamp, "odom", "base_footprint", *odom))
            self.pub_truth.publish(_odometry(stamp, "world", sim.robot.pose, sim.robot.v, sim.robot.w, 0.0))
        if tick.bumped:
            x, y, _ = sim.robot.pose
            rospy.logwarn("simulator: the robot ran into a wall at (%.2f, %.2f) (world frame) and stops "
                          "there until driven away", x, y)
        if tick.scan is not None:
            ranges = driver_ranges(tick.scan, self.cfg.range_min, self.cfg.no_return)
            self.scan_msg.header.stamp = stamp
            self.scan_msg.ranges = ranges.tolist()
            self.pub_scan.publish(self.scan_msg)
        if tick.route_finished:
            rospy.loginfo("simulator: route done at t=%.1f s (sim time)", tick.t)
            self.pub_done.publish(Bool(True))

    def run(self) -> None:
        """Tick, publish, then sleep on the wall clock until the tick's due time (dt / speed)."""
        period = self.sim.dt / self.speed
        wall0, k0 = time.monotonic(), self.sim.k
        static_sent = False
        while not rospy.is_shutdown():
            with self.lock:
                tick = self.sim.step()
            self._publish(tick)
            if not static_sent:
                self._publish_static(self._stamp(tick.t))
                static_sent = True
            delay = wall0 + (self.sim.k - k0) * period - time.monotonic()
            if delay > 0.0:
                time.sleep(delay)
            elif delay < -0.5:            # fell far behind (slow machine): do not burst to catch up
                rospy.logwarn_throttle(10.0, f"simulator: cannot keep up with speed {self.speed:.2f}")
                wall0, k0 = time.monotonic(), self.sim.k

