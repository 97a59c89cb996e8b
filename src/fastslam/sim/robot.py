"""Diff-drive TurtleBot3 burger: clamped kinematics, collision stop, noisy odometry.

Poses are (3,) float64 [x, y, theta]; the robot's in the world frame, the odometry's in
the odom frame, which starts at the spawn pose (odometry (0, 0, 0) at start).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from fastslam.geometry import compose, relative, wrap_angle
from fastslam.sim.world import World

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike, NDArray
    Array = NDArray[np.float64]


MAX_LINEAR = 0.22    # [m/s] burger limit (turtlebot3_teleop_key, e-manual)
MAX_ANGULAR = 2.84   # [rad/s]
RADIUS = 0.105       # [m] footprint radius used for collisions


def clamp_cmd(v: float, w: float, max_linear: float = MAX_LINEAR,
              max_angular: float = MAX_ANGULAR) -> tuple[float, float]:
    """(v, w) limited to |v| <= max_linear, |w| <= max_angular; NaN/inf become 0."""
    v = float(v) if math.isfinite(v) else 0.0
    w = float(w) if math.isfinite(w) else 0.0
    return max(-max_linear, min(max_linear, v)), max(-max_angular, min(max_angular, w))


def integrate(pose: ArrayLike, v: float, w: float, dt: float) -> Array:
    """Pose (3,) after driving v [m/s], w [rad/s] for dt [s] on the exact arc (a line if w = 0)."""
    x, y, th = np.asarray(pose, dtype=float)
    if abs(w) < 1e-9:
        return np.array([x + v * dt * math.cos(th), y + v * dt * math.sin(th), th])
    th2 = th + w * dt
    r = v / w
    return np.array([x + r * (math.sin(th2) - math.sin(th)), y - r * (math.cos(th2) - math.cos(th)),
                     float(wrap_angle(th2))])


@dataclass
class DiffDrive:
    """The robot's true state in a World; ``step`` moves it and reports collisions.

    A step that would bring the body (a disc of ``radius``) closer than ``radius`` to a
    wall is not taken, except when it increases the clearance (so a robot spawned too
    close can back off); the rotation is always applied, a disc turns freely.
    """

    world: World
    pose: Array = field(default_factory=lambda: np.zeros(3))
    radius: float = RADIUS
    max_linear: float = MAX_LINEAR
    max_angular: float = MAX_ANGULAR
    v: float = 0.0                   # velocities actually executed in the last step
    w: float = 0.0
    collided: bool = False

    def __post_init__(self) -> None:
        self.pose = np.asarray(self.pose, dtype=float).copy()

    def step(self, v_cmd: float, w_cmd: float, dt: float) -> Array:
        """Applies the clamped command for dt [s]; returns the new pose (3,)."""
        v, w = clamp_cmd(v_cmd, w_cmd, self.max_linear, self.max_angular)
        new = integrate(self.pose, v, w, dt)
        if v != 0.0:
            before, after = self.world.clearance(np.stack([self.pose[:2], new[:2]]))
            self.collided = bool(after < self.radius and after < before)
            if self.collided:
                new[:2] = self.pose[:2]
                v = 0.0
        else:
            self.collided = False
        self.pose, self.v, self.w = new, v, w
        return self.pose


@dataclass
class OdometryModel:
    """Wheel odometry with scale error, slip noise and heading drift (from a seeded Generator).

    Per step the true robot-frame motion (forward dist, turn) is distorted as
        dist' = dist * scale_linear + N(0, slip_linear * |dist|)
        turn' = turn * scale_angular + drift * |dist| + N(0, slip_angular * |turn| + slip_linear * |dist|)
    and integrated in the odom frame. ``perfect`` returns the exact pose relative to the start.
    """

    start: Array
    rng: np.random.Generator
    perfect: bool = False
    scale_linear: float = 1.0       # 1.01 = wheels 1 % larger than the model believes
    scale_angular: float = 1.0
    slip_linear: float = 0.0        # std of dist error per metre travelled
    slip_angular: float = 0.0       # std of turn error per radian turned
    drift: float = 0.0              # [rad/m] heading bias per metre (e.g. unequal wheels)
    pose: Array = field(default_factory=lambda: np.zeros(3))
    _last_true: Array = field(default_factory=lambda: np.zeros(3))

    def __post_init__(self) -> None:
        self.start = np.asarray(self.start, dtype=float).copy()
        self._last_true = self.start.copy()
        self.pose = np.zeros(3)

    def update(self, true_pose: ArrayLike) -> Array:
        """Odometry pose (3,) in the odom frame after the robot reached true_pose (3,) (world frame)."""
        true_pose = np.asarray(true_pose, dtype=float)
        if self.perfect:
            self.pose = relative(self.start, true_pose)
        else:
            delta = relative(self._last_true, true_pose)          # robot-frame motion (dx, dy, dth)
            dist = math.copysign(math.hypot(delta[0], delta[1]), delta[0])
            turn = float(delta[2])
            noise = self.rng.normal(0.0, 1.0, 2)
            dist2 = dist * self.scale_linear + noise[0] * self.slip_linear * abs(dist)
            turn2 = (turn * self.scale_angular + self.drift * abs(dist)
                     + noise[1] * (self.slip_angular * abs(turn) + self.slip_linear * abs(dist)))
            # the lateral part of the true delta (arc chord) is kept in direction, scaled with dist
            scale = dist2 / dist if dist != 0.0 else 0.0
            self.pose = compose(self.pose, np.array([delta[0] * scale, delta[1] * scale, turn2]))
        self._last_true = true_pose.copy()
        return self.pose
