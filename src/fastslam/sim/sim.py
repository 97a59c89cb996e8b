"""The simulator's clockwork without ROS: fixed physics ticks, odometry and scans when due.

    world = load_world("worlds/turtlebot3_world.yaml")
    sim = Simulation(world, SimConfig(), np.random.default_rng(0))
    sim.set_cmd(0.1, 0.0)
    for _ in range(60):
        tick = sim.step()          # tick.t [s]; tick.scan (360,) every 1/scan_rate s
    sim.robot.pose, sim.odom.pose  # truth (world frame), odometry (odom frame)
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from fastslam.fields import ConfigError, check_fields, coerce
from fastslam.fields import num as _num
from fastslam.geometry import relative
from fastslam.sim.lidar import Lidar
from fastslam.sim.robot import MAX_ANGULAR, MAX_LINEAR, DiffDrive, OdometryModel
from fastslam.sim.route import RouteFollower
from fastslam.sim.world import World

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


@dataclass(frozen=True)
class SimConfig:
    """Simulator parameters (the node's private parameters, config/sim_burger.yaml)."""

    world: str = field(default="turtlebot3_world", metadata={"doc": "world name in worlds/ or a path"})
    route: str = field(default="", metadata={"doc": "waypoint file or inline YAML; empty = drive by cmd_vel"})
    worlds_dir: str = field(default="", metadata={"doc": "where world names are looked up; empty = the package's"})
    spawn: list[float] = field(default_factory=list, metadata={"doc": "[x, y, yaw_deg]; empty = the world's"})
    seed: int = _num(0, 0, 2**32 - 1, "RNG seed for laser and odometry noise")
    speed: float = _num(1.0, 0.01, 1000.0, "sim time per wall time (only with use_sim_time)")
    physics_rate: float = _num(60.0, 1.0, 2000.0, "physics ticks per second of sim time [Hz]")
    odom_rate: float = _num(30.0, 0.1, 2000.0, "odom, tf and ground_truth rate [Hz]")
    scan_rate: float = _num(5.0, 0.1, 2000.0, "laser rate [Hz] (LDS-01: 5)")
    cmd_vel_timeout: float = _num(1.0, 0.0, 3600.0, "stop after this long without cmd_vel; 0 = never [s]")
    max_linear: float = _num(MAX_LINEAR, 0.0, 10.0, "[m/s] burger limit")
    max_angular: float = _num(MAX_ANGULAR, 0.0, 100.0, "[rad/s] burger limit")
    robot_radius: float = _num(0.105, 0.0, 2.0, "[m] collision disc")
    num_beams: int = _num(360, 3, 100000, "beams per revolution")
    range_min: float = _num(0.12, 0.0, 100.0, "[m]")
    range_max: float = _num(3.5, 0.01, 1000.0, "[m]")
    range_noise: float = _num(0.01, 0.0, 1.0, "Gaussian range noise sigma [m]")
    no_return: str = field(default="inf", metadata={"choices": ("inf", "zero"),
                                                    "doc": "inf as Gazebo, zero as the LDS-01 driver"})
    laser_x: float = _num(-0.032, -10.0, 10.0, "base_link -> base_scan x [m]")
    laser_y: float = _num(0.0, -10.0, 10.0, "base_link -> base_scan y [m]")
    laser_z: float = _num(0.172, -10.0, 10.0, "base_link -> base_scan z [m]")
    base_link_z: float = _num(0.010, -10.0, 10.0, "base_footprint -> base_link z [m]")
    odom_noise: bool = field(default=True, metadata={"doc": "false = perfect odometry"})
    odom_scale_linear: float = _num(1.01, 0.5, 2.0, "odometry distance scale (wheel radius error)")
    odom_scale_angular: float = _num(0.99, 0.5, 2.0, "odometry turn scale (wheel separation error)")
    odom_slip_linear: float = _num(0.02, 0.0, 1.0, "std of distance error per metre")
    odom_slip_angular: float = _num(0.05, 0.0, 1.0, "std of turn error per radian")
    odom_drift: float = _num(0.01, -1.0, 1.0, "heading bias per metre [rad/m]")
    route_tolerance: float = _num(0.08, 0.01, 10.0, "waypoint reached within this [m]")

    def __post_init__(self) -> None:
        check_fields(self)
        if self.range_min >= self.range_max:
            raise ConfigError(f"range_min={self.range_min} must be below range_max={self.range_max}")
        if self.spawn and (len(self.spawn) != 3 or not all(isinstance(v, (int, float)) for v in self.spawn)):
            raise ConfigError(f"spawn={self.spawn!r} must be [] or [x, y, yaw_deg]")

    @classmethod
    def from_dict(cls, values: Mapping[str, Any]) -> SimConfig:
        """Checks names and types ("unknown parameter 'x'", "speed='a' must be a number")."""
        values = {k: ("" if v is None and k in ("world", "route", "worlds_dir") else v) for k, v in values.items()}
        return cls(**coerce(cls, values))


@dataclass
class Tick:
    """What happened in one physics tick: sim time t [s]; scan (M,) ranges when one was taken."""

    t: float
    odom_due: bool
    scan: NDArray[np.float64] | None = None
    route_finished: bool = False
    bumped: bool = False   # the robot ran into a wall in this tick (first tick of a contact only)


class Simulation:
    """Robot + lidar + odometry + optional route in a World, advanced in fixed ticks of 1/physics_rate s."""

    def __init__(self, world: World, cfg: SimConfig, rng: np.random.Generator,
                 route: NDArray[np.float64] | None = None) -> None:
        self.world, self.cfg, self.rng = world, cfg, rng
        spawn = (np.array([cfg.spawn[0], cfg.spawn[1], math.radians(cfg.spawn[2])])
                 if cfg.spawn else world.spawn.copy())
        self.spawn = spawn
        self.dt = 1.0 / cfg.physics_rate
        self.k = 0
        self.robot = DiffDrive(world, spawn, radius=cfg.robot_radius,
                               max_linear=cfg.max_linear, max_angular=cfg.max_angular)
        self.lidar = Lidar(world, num_beams=cfg.num_beams, range_min=cfg.range_min, range_max=cfg.range_max,
                           sigma=cfg.range_noise, mount=(cfg.laser_x, cfg.laser_y, 0.0))
        self.odom = OdometryModel(spawn, rng, perfect=not cfg.odom_noise,
                                  scale_linear=cfg.odom_scale_linear, scale_angular=cfg.odom_scale_angular,
                                  slip_linear=cfg.odom_slip_linear, slip_angular=cfg.odom_slip_angular,
                                  drift=cfg.odom_drift)
        self.route = (RouteFollower(route, tolerance=cfg.route_tolerance, max_linear=cfg.max_linear,
                                    max_angular=cfg.max_angular) if route is not None else None)
        self._cmd = (0.0, 0.0)
        self._cmd_time = -math.inf
        self._touching = False
        self.odom_twist = (0.0, 0.0)    # (v, w) as the odometry measured it over the last odom period

    @property
    def time(self) -> float:
        """Sim time [s] of the latest tick (k / physics_rate, no accumulated rounding)."""
        return self.k * self.dt

    def set_cmd(self, v: float, w: float) -> None:
        """Velocity command (v [m/s], w [rad/s]), timestamped with the current sim time."""
        self._cmd = (float(v), float(w))
        self._cmd_time = self.time

    def _due(self, rate: float) -> bool:
        return math.floor(self.k * rate * self.dt + 1e-9) > math.floor((self.k - 1) * rate * self.dt + 1e-9)

    def step(self) -> Tick:
        """Advances one tick: command (route first, else cmd_vel unless stale) -> motion -> sensors."""
        self.k += 1
        finished = False
        if self.route is not None and not self.route.done:
            v, w = self.route.command(self.robot.pose)
            finished = self.route.done
        elif self.route is not None:
            v, w = 0.0, 0.0
        elif self.cfg.cmd_vel_timeout > 0 and self.time - self._cmd_time > self.cfg.cmd_vel_timeout:
            v, w = 0.0, 0.0
        else:
            v, w = self._cmd
        self.robot.step(v, w, self.dt)
        bumped = self.robot.collided and not self._touching
        # contact lasts while the robot pushes on the wall or stands still against it
        self._touching = self.robot.collided or (self._touching and v == 0.0)
        tick = Tick(t=self.time, odom_due=self._due(self.cfg.odom_rate), route_finished=finished, bumped=bumped)
        if tick.odom_due:
            before = self.odom.pose.copy()
            after = self.odom.update(self.robot.pose)
            period = 1.0 / self.cfg.odom_rate
            dx, _, dth = relative(before, after)   # the step in the robot's frame
            self.odom_twist = (float(dx) / period, float(dth) / period)
        if self._due(self.cfg.scan_rate):
            tick.scan = self.lidar.scan(self.robot.pose, self.rng if self.cfg.range_noise > 0 else None)
        return tick
