"""Planar pose helpers on numpy arrays; poses are [..., 3] = (x, y, theta)."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike, NDArray


def wrap_angle(a: ArrayLike) -> NDArray[np.float64]:
    """Angles mapped into [-pi, pi)."""
    return (np.asarray(a, dtype=float) + np.pi) % (2 * np.pi) - np.pi


def cos_sin(angles: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """cos and sin of angles, from a contiguous copy of a strided view.

    numpy picks its vectorised or its scalar cos/sin (which differ in the last bit)
    by whether input and output memory may overlap; a strided view's extent runs past
    its last element, so the choice, and the result, depended on where the output
    happened to be allocated: runs with equal inputs gave different poses.
    """
    a = np.array(angles, dtype=float)  # a contiguous copy (0-d stays 0-d)
    return np.cos(a), np.sin(a)


def compose(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """a (+) b: pose b expressed in a's frame, returned in a's parent frame. Broadcasts."""
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    c, s = cos_sin(a[..., 2])
    return np.stack([a[..., 0] + c * b[..., 0] - s * b[..., 1],
                     a[..., 1] + s * b[..., 0] + c * b[..., 1],
                     wrap_angle(a[..., 2] + b[..., 2])], axis=-1)


def transform_points(poses: ArrayLike, local: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Points local (M, 2), given in the frame of each pose (..., 3), in the poses'
    parent frame: x and y, each (..., M)."""
    poses = np.asarray(poses, dtype=float)
    local = np.asarray(local, dtype=float)
    c, s = cos_sin(poses[..., 2, None])
    x = poses[..., 0, None] + c * local[:, 0] - s * local[:, 1]
    y = poses[..., 1, None] + s * local[:, 0] + c * local[:, 1]
    return x, y


def inverse(a: ArrayLike) -> NDArray[np.float64]:
    """The pose p with a (+) p = identity."""
    a = np.asarray(a, dtype=float)
    c, s = cos_sin(a[..., 2])
    return np.stack([-c * a[..., 0] - s * a[..., 1],
                     s * a[..., 0] - c * a[..., 1],
                     wrap_angle(-a[..., 2])], axis=-1)


def relative(a: ArrayLike, b: ArrayLike) -> NDArray[np.float64]:
    """Pose b seen from pose a: inverse(a) (+) b."""
    return compose(inverse(a), b)


def _v_terms(theta: NDArray[np.float64]) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """sin(t)/t and (1 - cos(t))/t: the entries of SE(2)'s V matrix (1 and 0 near t = 0)."""
    small = np.abs(theta) < 1e-9
    t = np.where(small, 1.0, theta)
    return np.where(small, 1.0, np.sin(t) / t), np.where(small, 0.0, (1.0 - np.cos(t)) / t)


def pose_log(a: ArrayLike) -> NDArray[np.float64]:
    """The twist (u, v, theta) whose exponential is pose a (..., 3): a motion at constant
    speed and turn rate, so pose_exp(f * pose_log(a)) is the share f of a along that arc."""
    a = np.asarray(a, dtype=float)
    p, q = _v_terms(a[..., 2])
    det = p * p + q * q
    return np.stack([(p * a[..., 0] + q * a[..., 1]) / det,
                     (p * a[..., 1] - q * a[..., 0]) / det, a[..., 2]], axis=-1)


def pose_exp(xi: ArrayLike) -> NDArray[np.float64]:
    """The pose (..., 3) reached by the twist xi (..., 3) (pose_log's inverse, |theta| < pi)."""
    xi = np.asarray(xi, dtype=float)
    p, q = _v_terms(xi[..., 2])
    return np.stack([p * xi[..., 0] - q * xi[..., 1], q * xi[..., 0] + p * xi[..., 1],
                     wrap_angle(xi[..., 2])], axis=-1)


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


# Closed forms for stacks of 3x3 matrices. numpy.linalg hands each matrix to LAPACK,
# whose results on Debian's reference build vary in the last bit with the alignment of
# its work buffer: the same inputs gave different poses from run to run.
# The adjugate's entries, row by row: co[i] = m[P[i]] m[Q[i]] - m[R[i]] m[S[i]] (m flat, row-major):
# each the same products and difference as written out, in four gathers and three calls.
_ADJUGATE = tuple(np.array(v, dtype=np.intp) for v in zip(
    (4, 8, 5, 7), (2, 7, 1, 8), (1, 5, 2, 4),
    (5, 6, 3, 8), (0, 8, 2, 6), (2, 3, 0, 5),
    (3, 7, 4, 6), (1, 6, 0, 7), (0, 4, 1, 3)))


def inv3(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """(..., 3, 3) inverses by the adjugate."""
    f = m.reshape(m.shape[:-2] + (9,))
    p, q, r, s = _ADJUGATE
    co = f[..., p] * f[..., q] - f[..., r] * f[..., s]
    det = f[..., 0] * co[..., 0] + f[..., 1] * co[..., 3] + f[..., 2] * co[..., 6]
    return co.reshape(m.shape) / det[..., None, None]


def solve3(m: NDArray[np.float64], v: NDArray[np.float64]) -> NDArray[np.float64]:
    """(..., 3) solutions x of m (..., 3, 3) x = v (..., 3)."""
    inv = inv3(m)
    return np.asarray(inv[..., 0] * v[..., 0, None] + inv[..., 1] * v[..., 1, None] + inv[..., 2] * v[..., 2, None],
                      dtype=np.float64)


def cholesky3(m: NDArray[np.float64]) -> NDArray[np.float64]:
    """(..., 3, 3) lower-triangular L with L L^T = m (m symmetric positive definite)."""
    out = np.zeros_like(m)
    out[..., 0, 0] = l00 = np.sqrt(m[..., 0, 0])
    out[..., 1, 0] = l10 = m[..., 1, 0] / l00
    out[..., 2, 0] = l20 = m[..., 2, 0] / l00
    out[..., 1, 1] = l11 = np.sqrt(m[..., 1, 1] - l10 * l10)
    out[..., 2, 1] = l21 = (m[..., 2, 1] - l20 * l10) / l11
    out[..., 2, 2] = np.sqrt(m[..., 2, 2] - l20 * l20 - l21 * l21)
    return out
