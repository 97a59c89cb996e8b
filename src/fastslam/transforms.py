"""3D rigid transforms (quaternions, 4x4 matrices) reduced to a 2D laser mounting."""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike, NDArray


@dataclass(frozen=True)
class StaticTransform:
    """``child`` pose in ``parent``: translation (x, y, z) [m], rotation quaternion (x, y, z, w)."""

    parent: str
    child: str
    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotation: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 1.0)

    @classmethod
    def planar(cls, parent: str, child: str, x: float = 0.0, y: float = 0.0, yaw: float = 0.0, *,
               z: float = 0.0, upside_down: bool = False) -> StaticTransform:
        """A yaw (then optionally a roll of pi: the child's z axis pointing down) and a shift."""
        c, s = math.cos(yaw / 2), math.sin(yaw / 2)
        # Rz(yaw) * Rx(pi) as a quaternion is (x, y, z, w) = (c, s, 0, 0)
        q = (c, s, 0.0, 0.0) if upside_down else (0.0, 0.0, s, c)
        return cls(parent, child, (x, y, z), q)


@dataclass(frozen=True)
class LaserMount:
    """Laser pose in the base frame, in 2D.

    ``upside_down`` means the laser's z axis points down (roll ~ pi): a beam at angle
    a in the laser frame then points at ``yaw - a`` in the base frame, not ``yaw + a``.
    ``found`` is False when the bag had no transform chain and identity was assumed.
    """

    x: float = 0.0
    y: float = 0.0
    yaw: float = 0.0
    upside_down: bool = False
    base_frame: str = "base_link"
    laser_frame: str = "laser"
    found: bool = True


def quaternion_matrix(q: ArrayLike) -> NDArray[np.float64]:
    """(x, y, z, w) quaternion (need not be unit) -> 3x3 rotation matrix.

    Raises:
        ValueError: a zero (or not finite) quaternion, which is no rotation at all.
    """
    norm = float(np.linalg.norm(q))
    if not (np.isfinite(norm) and norm > 1e-12):
        raise ValueError(f"quaternion {tuple(np.asarray(q, dtype=np.float64).tolist())} is not a rotation")
    x, y, z, w = np.asarray(q, dtype=np.float64) / norm
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def transform_matrix(translation: ArrayLike, rotation: ArrayLike) -> NDArray[np.float64]:
    """Translation (3,) + quaternion (x, y, z, w) -> 4x4 homogeneous matrix."""
    m = np.eye(4)
    m[:3, :3] = quaternion_matrix(rotation)
    m[:3, 3] = np.asarray(translation, dtype=np.float64)
    return m


def mount_from_matrix(m: NDArray[np.float64], base_frame: str, laser_frame: str, *,
                      found: bool = True) -> LaserMount:
    """4x4 base->laser transform -> LaserMount (the laser's x axis gives the yaw)."""
    yaw = math.atan2(m[1, 0], m[0, 0])
    return LaserMount(x=float(m[0, 3]), y=float(m[1, 3]), yaw=yaw, upside_down=bool(m[2, 2] < 0),
                      base_frame=base_frame, laser_frame=laser_frame, found=found)
