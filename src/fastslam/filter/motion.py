"""Motion update of all particles at once (assignment 3.2, and a robot-frame option)."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from fastslam.geometry import wrap_angle

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike, NDArray


def odometry_step(prev_odom: NDArray[np.float64], odom: NDArray[np.float64]) -> tuple[float, float]:
    """Signed travel dr and heading change dtheta between two odometry poses.

    The assignment's dr = sqrt(dx^2 + dy^2) cannot drive backwards; here dr takes the
    sign of the displacement projected on the previous odometry heading.
    """
    dx, dy = float(odom[0] - prev_odom[0]), float(odom[1] - prev_odom[1])
    forward = dx * np.cos(prev_odom[2]) + dy * np.sin(prev_odom[2])
    dr = float(np.hypot(dx, dy)) * (-1.0 if forward < 0 else 1.0)
    return dr, float(wrap_angle(odom[2] - prev_odom[2]))


def sample_motion_assignment(poses: NDArray[np.float64], prev_odom: NDArray[np.float64], odom: NDArray[np.float64],
                             sigmas: NDArray[np.float64], rng: np.random.Generator) -> None:
    """Moves poses (N, 3) in place by the assignment's model plus additive noise.

    x += dr cos(theta) + e_x,  y += dr sin(theta) + e_y,  theta += dtheta + e_theta;
    sigmas (3,) are the std-devs of e (zeros: noise off, no random draw).
    """
    dr, dth = odometry_step(prev_odom, odom)
    theta = poses[:, 2].copy()
    poses[:, 0] += dr * np.cos(theta)
    poses[:, 1] += dr * np.sin(theta)
    poses[:, 2] = theta + dth
    if np.any(sigmas > 0):
        poses += rng.normal(0.0, 1.0, poses.shape) * sigmas
    poses[:, 2] = wrap_angle(poses[:, 2])


def _rot_trans_rot(prev_odom: NDArray[np.float64], odom: NDArray[np.float64]) -> tuple[float, float, float]:
    """The odometry step as (rot1, trans, rot2), trans negative when reversing."""
    dx, dy = float(odom[0] - prev_odom[0]), float(odom[1] - prev_odom[1])
    trans = float(np.hypot(dx, dy))
    rot1 = float(wrap_angle(np.arctan2(dy, dx) - prev_odom[2])) if trans > 1e-6 else 0.0
    if abs(rot1) > np.pi / 2:  # driving backwards: turn less, travel negative
        rot1, trans = float(wrap_angle(rot1 + np.pi)), -trans
    rot2 = float(wrap_angle(odom[2] - prev_odom[2] - rot1))
    return rot1, trans, rot2


def step_sigmas(rot1: ArrayLike, trans: ArrayLike, rot2: ArrayLike, alphas: tuple[float, float, float, float]
                ) -> tuple[Any, Any, Any]:
    """Std-devs of rot1, trans, rot2 (floats or arrays alike) under the odometry motion
    model with alphas = (srr, srt, str, stt), gmapping's: translation noise from
    translation and from rotation, rotation noise from translation and from rotation."""
    srr, srt, s_rt, stt = alphas
    r1, tr, r2 = np.abs(rot1), np.abs(trans), np.abs(rot2)
    return stt * r1 + s_rt * tr, srr * tr + srt * (r1 + r2), stt * r2 + s_rt * tr


def odometry_std(prev_odom: NDArray[np.float64], odom: NDArray[np.float64], alphas: tuple[float, float, float, float]
                 ) -> NDArray[np.float64]:
    """(3,) std-devs of sample_motion_odometry's end pose for this step: along the
    direction of travel, across it [m], and of the heading [rad] (first order)."""
    rot1, trans, rot2 = _rot_trans_rot(prev_odom, odom)
    s_rot1, s_trans, s_rot2 = step_sigmas(rot1, trans, rot2, alphas)
    return np.array([s_trans, abs(trans) * s_rot1, float(np.hypot(s_rot1, s_rot2))])


def sample_motion_odometry(poses: NDArray[np.float64], prev_odom: NDArray[np.float64], odom: NDArray[np.float64],
                           alphas: tuple[float, float, float, float], noise: bool,
                           rng: np.random.Generator) -> None:
    """Moves poses (N, 3) in place by rot1-trans-rot2 odometry (Probabilistic Robotics 5.4).

    alphas = (srr, srt, str, stt) as in gmapping: translation noise from translation and
    from rotation, rotation noise from translation and from rotation.
    """
    rot1, trans, rot2 = _rot_trans_rot(prev_odom, odom)
    n = len(poses)
    r1 = np.full(n, rot1)
    tr = np.full(n, trans)
    r2 = np.full(n, rot2)
    if noise:
        s_rot1, s_trans, s_rot2 = step_sigmas(rot1, trans, rot2, alphas)
        r1 += rng.normal(0, 1, n) * s_rot1
        tr += rng.normal(0, 1, n) * s_trans
        r2 += rng.normal(0, 1, n) * s_rot2
    heading = poses[:, 2] + r1
    poses[:, 0] += tr * np.cos(heading)
    poses[:, 1] += tr * np.sin(heading)
    poses[:, 2] = wrap_angle(heading + r2)
