"""Motion update of all particles at once (assignment 3.2, and a robot-frame option)."""
from __future__ import annotations

from typing import TYPE_CHECKING, Any, NamedTuple

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


class OdometryArc(NamedTuple):
    """One step of the odometry motion model in its own terms: the step (rot1, trans,
    rot2) and their std-devs. A long step turned by a wrong first turn ends on an arc
    round its start; a Gaussian along and across the predicted heading puts that arc's
    far end several std-devs out (orebro: a 3 m step turned 65 degrees wrong, 1.8
    std-devs in these terms, lay 4.8 along and across)."""
    rot1: float
    trans: float    # negative: reversing
    rot2: float
    s_rot1: float
    s_trans: float
    s_rot2: float

    def cost(self, x: Any, y: Any, heading: Any, px: Any, py: Any, ph: Any) -> Any:
        """Squared std-devs of the poses (x, y, heading) as the end of this step from
        where it began for the noise-free prediction (px, py, ph); arrays broadcast, so
        (N, 1, T) positions and (N, A, 1) headings cost the (N, 1, T) part once."""
        start_heading = ph - self.rot1 - self.rot2
        travel = start_heading + self.rot1
        dx = x - (px - self.trans * np.cos(travel))
        dy = y - (py - self.trans * np.sin(travel))
        trans = np.hypot(dx, dy)
        if self.trans < 0:   # reversing: the turn is measured from the reversed heading
            dx, dy, trans = -dx, -dy, -trans
        rot1 = wrap_angle(np.arctan2(dy, dx) - start_heading)
        rot2 = wrap_angle(heading - start_heading - rot1)
        return ((wrap_angle(rot1 - self.rot1) / self.s_rot1) ** 2 + ((trans - self.trans) / self.s_trans) ** 2
                + (wrap_angle(rot2 - self.rot2) / self.s_rot2) ** 2)

    def widened(self, factor: float) -> OdometryArc:
        """The same step with std-devs factor times as wide."""
        return self._replace(s_rot1=self.s_rot1 * factor, s_trans=self.s_trans * factor,
                             s_rot2=self.s_rot2 * factor)


def odometry_arc(prev_odom: NDArray[np.float64], odom: NDArray[np.float64], alphas: tuple[float, float, float, float],
                 floor_xy: float, floor_theta: float) -> OdometryArc:
    """The step between two odometry poses with its std-devs, at least floor_xy [m]
    along and across its travel and floor_theta [rad] in its last turn. Needs travel:
    the first turn of a step on the spot is undefined."""
    rot1, trans, rot2 = _rot_trans_rot(prev_odom, odom)
    if trans == 0:
        raise ValueError("odometry_arc needs a step with travel")
    s_rot1, s_trans, s_rot2 = step_sigmas(rot1, trans, rot2, alphas)
    return OdometryArc(rot1, trans, rot2, max(float(s_rot1), floor_xy / abs(trans)), max(float(s_trans), floor_xy),
                       max(float(s_rot2), floor_theta))


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
