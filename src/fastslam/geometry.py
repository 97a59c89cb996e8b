"""Planar pose helpers on numpy arrays; poses are [..., 3] = (x, y, theta)."""
from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray


def wrap_angle(a: ArrayLike) -> NDArray[np.float64]:
    """Angles mapped into [-pi, pi)."""
    return (np.asarray(a, dtype=float) + np.pi) % (2 * np.pi) - np.pi


def compose(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """a (+) b: pose b expressed in a's frame, returned in a's parent frame. Broadcasts."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack([a[..., 0] + c * b[..., 0] - s * b[..., 1],
                     a[..., 1] + s * b[..., 0] + c * b[..., 1],
                     wrap_angle(a[..., 2] + b[..., 2])], axis=-1)


def inverse(a: ArrayLike) -> NDArray[np.float64]:
    """The pose p with a (+) p = identity."""
    a = np.asarray(a, dtype=float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack([-c * a[..., 0] - s * a[..., 1],
                     s * a[..., 0] - c * a[..., 1],
                     wrap_angle(-a[..., 2])], axis=-1)


def relative(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Pose b seen from pose a: inverse(a) (+) b."""
    return compose(inverse(a), b)


def circular_mean(angles: ArrayLike, weights: ArrayLike | None = None) -> float:
    """Weighted mean direction; plain averaging breaks across +-pi."""
    angles = np.asarray(angles, dtype=float)
    w = np.ones_like(angles) if weights is None else np.asarray(weights, dtype=float)
    return float(np.arctan2(np.sum(w * np.sin(angles)), np.sum(w * np.cos(angles))))


def yaw_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """Heading (rotation about z) of a quaternion; it need not be normalised."""
    # w^2 + x^2 - y^2 - z^2 rather than 1 - 2(y^2 + z^2): the same for a unit quaternion,
    # and scale-free, so a non-normalised one gives the right heading too
    return float(np.arctan2(2.0 * (w * z + x * y), w * w + x * x - y * y - z * z))
