"""Synthetic wheel odometry from a reference trajectory, with a known noise model.

Logs such as the corrected Intel log hold scan-matched poses, not raw odometry. We
re-integrate the motion between consecutive poses, perturbed with the odometry motion
model of Probabilistic Robotics (``sample_motion_model_odometry``, Table 5.6): each
step is split into a robot-frame (rot1, trans, rot2) and each part gets zero-mean
Gaussian noise whose standard deviation grows linearly with the motion (gmapping's
srr/srt/str/stt convention, with standard deviations rather than variances):

    sigma_rot1  = level * (A_RR * |rot1| + A_RT * |trans|)
    sigma_trans = level * (A_TT * |trans| + A_TR * (|rot1| + |rot2|))
    sigma_rot2  = level * (A_RR * |rot2| + A_RT * |trans|)

with A_RR = 0.1 [rad/rad], A_RT = 0.1 [rad/m], A_TT = 0.1 [m/m], A_TR = 0.05 [m/rad]
(``DEFAULT_ALPHAS``). One deviation from the textbook, for the noise scale only: a step
shorter than ``MIN_TRANS`` (0.1 m) counts as a turn on the spot, (|rot1|, |rot2|) =
(0, |dtheta|). The Intel poses shift 2-10 cm sideways when the robot turns in place
(their reference point is off the rotation axis), and the exact decomposition turns
such a shift into two large opposite rotations (on that log the sum of |rot1| + |rot2|
is 3.5x the sum of |dtheta|), which would drown the rotation noise in artefacts. The
mean motion always uses the exact decomposition, so level 0 reproduces the reference
(up to rounding). Backward steps (|rot1| > pi/2) are modelled as reversing, as amcl does.

Level 1 on the whole Intel log: dead-reckoning ATE 12-15 m (seeds 0-2), RPE ~0.11 m and
~7 deg per scan step: clearly wrong globally, plausible locally.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from fastslam.filter.motion import step_sigmas
from fastslam.geometry import wrap_angle

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike, NDArray


class OdomNoise(NamedTuple):
    """Linear noise coefficients of the odometry motion model."""

    rot_per_rot: float = 0.1      # A_RR [rad/rad]
    rot_per_trans: float = 0.1    # A_RT [rad/m]
    trans_per_trans: float = 0.1  # A_TT [m/m]
    trans_per_rot: float = 0.05   # A_TR [m/rad]


DEFAULT_ALPHAS = OdomNoise()
MIN_TRANS = 0.1  # [m] shorter steps are turns on the spot for the noise scale (see above)
_STILL = 1e-9  # [m] below this a step is a turn on the spot: rot1 is undefined, use 0


def odometry_deltas(poses: ArrayLike) -> NDArray[np.float64]:
    """(T, 3) poses -> (T-1, 3) robot-frame steps (rot1, trans, rot2).

    ``trans`` is negative for a backward step, then rot1 is measured from the
    reversed heading (keeps |rot1| <= pi/2).
    """
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    dx, dy = np.diff(p[:, 0]), np.diff(p[:, 1])
    dth = wrap_angle(np.diff(p[:, 2]))
    trans = np.hypot(dx, dy)
    rot1 = np.where(trans > _STILL, wrap_angle(np.arctan2(dy, dx) - p[:-1, 2]), 0.0)
    backward = np.abs(rot1) > np.pi / 2
    rot1 = np.where(backward, wrap_angle(rot1 - np.pi), rot1)
    trans = np.where(backward, -trans, trans)
    rot2 = wrap_angle(dth - rot1)
    return np.stack([rot1, trans, rot2], axis=1)


def integrate_deltas(start: ArrayLike, deltas: ArrayLike) -> NDArray[np.float64]:
    """Compose (T-1, 3) (rot1, trans, rot2) steps from ``start`` (3,) -> (T, 3) poses.

    Vectorised with cumulative sums: the heading is the running sum of the turns and
    each translation is taken along the heading after its rot1.
    """
    s = np.asarray(start, dtype=np.float64)
    d = np.asarray(deltas, dtype=np.float64).reshape(-1, 3)
    turns = np.concatenate([[0.0], np.cumsum(d[:, 0] + d[:, 2])])
    heading = s[2] + turns[:-1] + d[:, 0]      # direction of travel in step k
    x = s[0] + np.concatenate([[0.0], np.cumsum(d[:, 1] * np.cos(heading))])
    y = s[1] + np.concatenate([[0.0], np.cumsum(d[:, 1] * np.sin(heading))])
    return np.stack([x, y, wrap_angle(s[2] + turns)], axis=1)


def noise_sigmas(deltas: ArrayLike, level: float, alphas: OdomNoise = DEFAULT_ALPHAS) -> NDArray[np.float64]:
    """(T-1, 3) standard deviations of (rot1, trans, rot2) for (T-1, 3) steps."""
    d = np.asarray(deltas, dtype=np.float64).reshape(-1, 3)
    tr = np.abs(d[:, 1])
    turn = tr < MIN_TRANS
    r1 = np.where(turn, 0.0, np.abs(d[:, 0]))
    r2 = np.where(turn, np.abs(wrap_angle(d[:, 0] + d[:, 2])), np.abs(d[:, 2]))
    model = (alphas.trans_per_trans, alphas.trans_per_rot, alphas.rot_per_trans, alphas.rot_per_rot)
    return level * np.stack(step_sigmas(r1, tr, r2, model), axis=1)  # the filter's own law


def perturb_deltas(deltas: ArrayLike, level: float, rng: np.random.Generator,
                   alphas: OdomNoise = DEFAULT_ALPHAS) -> NDArray[np.float64]:
    """Add the model's Gaussian noise to (T-1, 3) (rot1, trans, rot2) steps."""
    d = np.asarray(deltas, dtype=np.float64).reshape(-1, 3)
    # always draw (even at level 0) so a seed gives the same stream for every level
    return d + noise_sigmas(d, level, alphas) * rng.standard_normal(d.shape)


def noisy_odometry(poses: ArrayLike, level: float, rng: np.random.Generator,
                   alphas: OdomNoise = DEFAULT_ALPHAS) -> NDArray[np.float64]:
    """(T, 3) reference poses -> (T, 3) dead-reckoned odometry poses starting at poses[0].

    Args:
        poses: reference trajectory (x, y, theta), world frame.
        level: noise multiplier; 0 = exact re-integration.
        rng: seeded generator; the same seed gives the same odometry.
        alphas: noise coefficients (``DEFAULT_ALPHAS``).
    """
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    if level < 0:
        raise ValueError(f"odometry noise level must be >= 0, got {level}")
    if len(p) == 0:
        return p.copy()
    deltas = perturb_deltas(odometry_deltas(p), level, rng, alphas)
    return integrate_deltas(p[0], deltas)
