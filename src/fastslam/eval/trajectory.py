"""Trajectory accuracy of a 2D estimate against a reference: time matching, ATE, RPE.

- Matching: each estimated pose is paired with the reference pose nearest in time
  (kept if within ``max_dt``), or with the reference linearly interpolated at its time.
- ATE: RMS position error after the rigid 2D motion (rotation + translation, no scale)
  that best aligns the estimate to the reference (closed-form Kabsch/Umeyama in 2D).
- RPE: error of the relative motion between matched poses ``delta`` apart (default 1 =
  consecutive matched poses), ``E = (ref_i^-1 ref_j)^-1 (est_i^-1 est_j)``; translation
  as RMS of |E_xy| [m], rotation as RMS of |E_theta| [deg]. It needs no alignment.
- Relations (Kuemmerle et al. 2009, as Cartographer computes them): for each given
  true motion ``expected`` from the pose at t1 to the pose at t2 (in the t1 frame),
  ``E = (pose(t1)^-1 pose(t2)) expected^-1``; mean and standard deviation (n - 1) of
  |E_xy| [m] and of |E_theta| [deg]. Poses are interpolated between the estimate's
  stamps and clamped at its ends.
All poses are (N, 3) float64 (x, y, theta) [m, m, rad].
"""
from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import TYPE_CHECKING

import numpy as np

from fastslam.geometry import compose, inverse, relative, wrap_angle

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import ArrayLike, NDArray


def match_by_time(ref_t: ArrayLike, ref: ArrayLike, est_t: ArrayLike, est: ArrayLike, *,
                  max_dt: float = 0.05, interpolate: bool = False
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
    """Pair estimate poses with reference poses by timestamp.

    Args:
        ref_t, est_t: (R,), (E,) times [s], ascending.
        ref, est: (R, 3), (E, 3) poses.
        max_dt: nearest-neighbour pairs further apart in time are dropped [s].
        interpolate: instead, interpolate the reference at each estimate time inside its span.

    Returns:
        (times (K,), matched reference (K, 3), matched estimate (K, 3)).
    """
    rt = np.asarray(ref_t, dtype=np.float64).reshape(-1)
    rp = np.asarray(ref, dtype=np.float64).reshape(-1, 3)
    et = np.asarray(est_t, dtype=np.float64).reshape(-1)
    ep = np.asarray(est, dtype=np.float64).reshape(-1, 3)
    if len(rt) == 0 or len(et) == 0:
        return np.zeros(0), np.zeros((0, 3)), np.zeros((0, 3))
    if interpolate:
        keep = (et >= rt[0]) & (et <= rt[-1])
        t = et[keep]
        # unwrap first so the heading is interpolated the short way round across +-pi
        heading = np.interp(t, rt, np.unwrap(rp[:, 2]))
        m = np.stack([np.interp(t, rt, rp[:, 0]), np.interp(t, rt, rp[:, 1]), wrap_angle(heading)], axis=1)
        return t, m, ep[keep]
    right = np.clip(np.searchsorted(rt, et), 0, len(rt) - 1)
    left = np.clip(right - 1, 0, len(rt) - 1)
    nearest = np.where(np.abs(rt[left] - et) <= np.abs(rt[right] - et), left, right)
    keep = np.abs(rt[nearest] - et) <= max_dt
    return et[keep], rp[nearest[keep]], ep[keep]


def align_2d(src: ArrayLike, dst: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Rigid 2D motion (R (2, 2), t (2,)) minimising sum |R src_i + t - dst_i|^2.

    src, dst: (N, 2) or (N, 3) (only x, y are used). The best angle is
    atan2(sum a x b, sum a . b) over the centred points a (src) and b (dst).
    """
    a = np.asarray(src, dtype=np.float64)[:, :2]
    b = np.asarray(dst, dtype=np.float64)[:, :2]
    ma, mb = a.mean(axis=0), b.mean(axis=0)
    ac, bc = a - ma, b - mb
    angle = np.arctan2(np.sum(ac[:, 0] * bc[:, 1] - ac[:, 1] * bc[:, 0]), np.sum(ac * bc))
    c, s = np.cos(angle), np.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    return rot, mb - rot @ ma


def apply_alignment(rot: NDArray[np.float64], t: NDArray[np.float64], poses: ArrayLike) -> NDArray[np.float64]:
    """Move (N, 3) poses by the rigid motion (rot, t); headings turn with it."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    out = np.empty_like(p)
    out[:, :2] = p[:, :2] @ rot.T + t
    out[:, 2] = wrap_angle(p[:, 2] + np.arctan2(rot[1, 0], rot[0, 0]))
    return out


def ate_errors(ref: ArrayLike, est: ArrayLike) -> NDArray[np.float64]:
    """(N,) position errors [m] of matched poses after aligning ``est`` onto ``ref``."""
    r = np.asarray(ref, dtype=np.float64).reshape(-1, 3)
    e = np.asarray(est, dtype=np.float64).reshape(-1, 3)
    if len(r) == 0:
        return np.zeros(0)
    rot, t = align_2d(e, r)
    return np.linalg.norm(apply_alignment(rot, t, e)[:, :2] - r[:, :2], axis=1)


def ate(ref: ArrayLike, est: ArrayLike) -> float:
    """Absolute trajectory error: RMS position error [m] after the best rigid 2D alignment."""
    err = ate_errors(ref, est)
    return float(np.sqrt(np.mean(err ** 2))) if len(err) else float("nan")


def rpe(ref: ArrayLike, est: ArrayLike, delta: int = 1) -> tuple[float, float]:
    """Relative pose error over pairs ``delta`` poses apart -> (RMS translation [m], RMS rotation [deg])."""
    r = np.asarray(ref, dtype=np.float64).reshape(-1, 3)
    e = np.asarray(est, dtype=np.float64).reshape(-1, 3)
    if delta < 1:
        raise ValueError(f"delta must be >= 1, got {delta}")
    if len(r) <= delta:
        return float("nan"), float("nan")
    err = compose(inverse(relative(r[:-delta], r[delta:])), relative(e[:-delta], e[delta:]))
    trans = np.hypot(err[:, 0], err[:, 1])
    return float(np.sqrt(np.mean(trans ** 2))), float(np.degrees(np.sqrt(np.mean(err[:, 2] ** 2))))


@dataclass(frozen=True)
class TrajectoryScores:
    """Summary of one estimate against a reference."""

    matched: int
    ate_rmse: float      # [m]
    ate_mean: float      # [m]
    ate_max: float       # [m]
    rpe_trans: float     # [m] RMS per ``rpe_delta`` poses
    rpe_rot: float       # [deg]
    rpe_delta: int

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def score(ref_t: ArrayLike, ref: ArrayLike, est_t: ArrayLike, est: ArrayLike, *, max_dt: float = 0.05,
          interpolate: bool = False, delta: int = 1) -> TrajectoryScores:
    """Match by time, then ATE (after alignment) and RPE over ``delta`` matched poses."""
    _, r, e = match_by_time(ref_t, ref, est_t, est, max_dt=max_dt, interpolate=interpolate)
    err = ate_errors(r, e)
    nan = float("nan")
    trans, rot = rpe(r, e, delta)
    return TrajectoryScores(
        matched=len(r), ate_rmse=float(np.sqrt(np.mean(err ** 2))) if len(err) else nan,
        ate_mean=float(err.mean()) if len(err) else nan, ate_max=float(err.max()) if len(err) else nan,
        rpe_trans=trans, rpe_rot=rot, rpe_delta=delta)


def interpolate_poses(times: ArrayLike, poses: ArrayLike, query: ArrayLike) -> NDArray[np.float64]:
    """(Q, 3) poses at times query (Q,): linear between the (T,) ascending stamps of
    poses (T, 3), the heading the short way round, clamped to the first and last pose."""
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    q = np.asarray(query, dtype=np.float64).reshape(-1)
    heading = np.interp(q, t, np.unwrap(p[:, 2]))  # np.interp clamps at the ends
    return np.stack([np.interp(q, t, p[:, 0]), np.interp(q, t, p[:, 1]), wrap_angle(heading)], axis=1)


def relation_errors(times: ArrayLike, poses: ArrayLike, relations: ArrayLike) -> NDArray[np.float64]:
    """(R, 3) error poses (pose(t1)^-1 pose(t2)) expected^-1 of relations (R, 5) rows
    t1, t2, x, y, yaw against the estimate (times (T,), poses (T, 3))."""
    rel = np.asarray(relations, dtype=np.float64).reshape(-1, 5)
    a = interpolate_poses(times, poses, rel[:, 0])
    b = interpolate_poses(times, poses, rel[:, 1])
    return compose(relative(a, b), inverse(rel[:, 2:5]))


@dataclass(frozen=True)
class RelationScores:
    """The Kuemmerle metric of one estimate: translation [m] and rotation [deg] errors."""

    relations: int
    outside: int         # relations with a stamp outside the estimate's span (clamped)
    trans_mean: float    # [m]
    trans_std: float
    trans_max: float
    rot_mean: float      # [deg]
    rot_std: float
    rot_max: float

    def as_dict(self) -> dict[str, float | int]:
        return asdict(self)


def worst_relations(times: ArrayLike, poses: ArrayLike, relations: ArrayLike, count: int) -> NDArray[np.float64]:
    """(K, 6) rows t1, t2, the relation's length [m], its translation error [m] and
    rotation error [deg] against the estimate, and the speed the relation asks for
    (length / (t2 - t1), m/s; inf at t1 = t2): the count relations (at most) with the
    largest translation errors, largest first. Where a run went wrong, and a relation
    no robot could have driven (a reference's own slip) stands out by its speed."""
    rel = np.asarray(relations, dtype=np.float64).reshape(-1, 5)
    err = relation_errors(times, poses, rel)
    trans = np.hypot(err[:, 0], err[:, 1])
    order = np.argsort(-trans, kind="stable")[:max(count, 0)]
    length = np.hypot(rel[order, 2], rel[order, 3])
    span = np.abs(rel[order, 1] - rel[order, 0])
    speed = np.divide(length, span, out=np.full_like(length, np.inf), where=span > 0)
    return np.column_stack([rel[order, 0], rel[order, 1], length, trans[order],
                            np.degrees(np.abs(err[order, 2])), speed])


def relations_score(times: ArrayLike, poses: ArrayLike, relations: ArrayLike) -> RelationScores:
    """Mean, standard deviation (n - 1, as Cartographer) and maximum of the relation errors."""
    t = np.asarray(times, dtype=np.float64).reshape(-1)
    rel = np.asarray(relations, dtype=np.float64).reshape(-1, 5)
    if len(t) == 0 or len(rel) == 0:
        raise ValueError("no poses" if len(t) == 0 else "no relations")
    err = relation_errors(t, poses, rel)
    trans = np.hypot(err[:, 0], err[:, 1])
    rot = np.degrees(np.abs(err[:, 2]))
    outside = int(np.count_nonzero((rel[:, :2].min(axis=1) < t[0]) | (rel[:, :2].max(axis=1) > t[-1])))
    ddof = 1 if len(rel) > 1 else 0
    return RelationScores(relations=len(rel), outside=outside,
                          trans_mean=float(trans.mean()), trans_std=float(trans.std(ddof=ddof)),
                          trans_max=float(trans.max()), rot_mean=float(rot.mean()),
                          rot_std=float(rot.std(ddof=ddof)), rot_max=float(rot.max()))
