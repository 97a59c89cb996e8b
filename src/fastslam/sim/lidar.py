"""Exact, vectorised 2D ray casting against segments and circles (an LDS-01-like laser).

Every beam is intersected analytically with every primitive at once ((M, K) arrays), so
the simulated ranges do not share the grid approximations of ``fastslam.filter.raycast``.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from fastslam.geometry import compose
from fastslam.sim.world import World

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike, NDArray
    Array = NDArray[np.float64]


def ray_segments(origin: ArrayLike, dirs: ArrayLike, segments: ArrayLike) -> Array:
    """Distance (M,) along unit directions dirs (M, 2) from origin (2,) to the first of segments (K, 2, 2); inf if none.

    Solves origin + t*d = a + u*(b - a) for all pairs: t >= 0, 0 <= u <= 1.
    Parallel (also collinear) pairs count as misses: a wall seen exactly edge-on has no area.
    """
    o = np.asarray(origin, dtype=float)[:2]
    d = np.asarray(dirs, dtype=float).reshape(-1, 2)
    seg = np.asarray(segments, dtype=float).reshape(-1, 2, 2)
    if not len(seg):
        return np.full(len(d), np.inf)
    a = seg[:, 0] - o                                   # (K, 2) segment starts relative to the origin
    e = seg[:, 1] - seg[:, 0]                           # (K, 2)
    denom = d[:, 0, None] * e[:, 1] - d[:, 1, None] * e[:, 0]          # cross(d, e): (M, K)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = (a[:, 0] * e[:, 1] - a[:, 1] * e[:, 0]) / denom             # cross(a, e) / cross(d, e)
        u = (a[:, 0] * d[:, 1, None] - a[:, 1] * d[:, 0, None]) / denom  # cross(a, d) / cross(d, e)
    ok = (np.abs(denom) > 1e-12) & (t >= 0.0) & (u >= -1e-12) & (u <= 1.0 + 1e-12)
    return np.where(ok, t, np.inf).min(axis=1)


def ray_circles(origin: ArrayLike, dirs: ArrayLike, circles: ArrayLike) -> Array:
    """Distance (M,) along unit directions dirs (M, 2) from origin (2,) to the first circle
    boundary (C, 3); inf if none.

    |f + t*d|^2 = r^2 with f = origin - centre: t = -b -+ sqrt(b^2 - c), b = d.f, c = |f|^2 - r^2.
    From inside a circle the far root is the hit.
    """
    o = np.asarray(origin, dtype=float)[:2]
    d = np.asarray(dirs, dtype=float).reshape(-1, 2)
    circ = np.asarray(circles, dtype=float).reshape(-1, 3)
    if not len(circ):
        return np.full(len(d), np.inf)
    f = o - circ[:, :2]                                  # (C, 2)
    b = d @ f.T                                          # (M, C)
    c = np.einsum("cj,cj->c", f, f) - circ[:, 2] ** 2    # (C,)
    disc = b * b - c
    root = np.sqrt(np.maximum(disc, 0.0))
    near, far = -b - root, -b + root
    t = np.where(near >= 0.0, near, far)
    return np.where((disc >= 0.0) & (t >= 0.0), t, np.inf).min(axis=1)


def cast_rays(world: World, pose: ArrayLike, angles: ArrayLike) -> Array:
    """True distances (M,) from sensor pose (3,) [x, y, theta] (world frame) along angles (M,) (sensor frame)."""
    p = np.asarray(pose, dtype=float)
    a = p[2] + np.asarray(angles, dtype=float)
    dirs = np.stack([np.cos(a), np.sin(a)], axis=1)
    return np.minimum(ray_segments(p[:2], dirs, world.segments), ray_circles(p[:2], dirs, world.circles))


@dataclass
class Lidar:
    """A 2D laser in a World; defaults are the LDS-01 (360 beams, 1 deg, 0.12-3.5 m, sigma 0.01 m).

    mount: (3,) [x, y, yaw] of the sensor in the robot (base) frame; the burger's base_scan is at x = -0.032.
    """

    world: World
    num_beams: int = 360
    angle_min: float = 0.0
    range_min: float = 0.12
    range_max: float = 3.5
    sigma: float = 0.01
    mount: tuple[float, float, float] = (-0.032, 0.0, 0.0)

    @property
    def angle_increment(self) -> float:
        return 2.0 * math.pi / self.num_beams

    @property
    def angles(self) -> Array:
        """Beam angles (M,) in the sensor frame: angle_min + i * increment."""
        return self.angle_min + self.angle_increment * np.arange(self.num_beams)

    def sensor_pose(self, base_pose: ArrayLike) -> Array:
        """World pose (3,) of the sensor for a robot base pose (3,)."""
        base = np.asarray(base_pose, dtype=float)
        sensor = compose(base, self.mount)
        sensor[2] = base[2] + self.mount[2]  # unwrapped, as the beams' angles are
        return sensor

    def cast(self, pose: ArrayLike, angles: ArrayLike, range_min: float, range_max: float,
             rng: np.random.Generator | None = None, sigma: float = 0.0) -> Array:
        """Measured ranges (M,) from sensor pose (3,) (world frame) along angles (M,) (sensor frame).

        Gaussian noise sigma [m] is added when rng is given; noisy values are clipped to
        [range_min, range_max]. A true distance beyond range_max is no return: inf. One
        closer than range_min comes out as that distance, below range_min, as Gazebo's
        laser gives it: a reading consumers drop, never a far no-return that would clear
        free space through the wall the robot touches.
        """
        true = cast_rays(self.world, pose, angles)
        ranges = true.copy()
        if rng is not None and sigma > 0.0:
            ranges = np.clip(ranges + rng.normal(0.0, sigma, ranges.shape), range_min, range_max)
        ranges[true > range_max] = np.inf
        short = true < range_min
        ranges[short] = true[short]
        return ranges

    def scan(self, base_pose: ArrayLike, rng: np.random.Generator | None = None) -> Array:
        """A full scan (num_beams,) from the robot at base_pose (3,), with the configured noise."""
        return self.cast(self.sensor_pose(base_pose), self.angles, self.range_min, self.range_max,
                         rng=rng, sigma=self.sigma)


def driver_ranges(ranges: Array, range_min: float, no_return: str) -> Array:
    """Readings (M,) as a driver publishes them. "inf" (Gazebo): as cast gives them;
    "zero" (the real LDS-01 driver): no return and too close both read 0.0."""
    if no_return == "inf":
        return ranges
    with np.errstate(invalid="ignore"):
        return np.where(~np.isfinite(ranges) | (ranges < range_min), 0.0, ranges)
