"""What the filter asks of the scan matcher in one update, and which answers it trusts.

The matcher (fastslam.match) is a pure function; these pure functions set its search
and prior from the motion model of the step, and check its matches against the
motion model, so the filter and the matcher bench (bench/matcher.py) do the same.
"""
from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING, Any, Tuple

import numpy as np

from fastslam.config import SlamConfig
from fastslam.filter.motion import OdometryArc, odometry_arc
from fastslam.geometry import cos_sin, inv3, solve3, wrap_angle
from fastslam.match import Match, MatchParams
from fastslam.match.refine import prior_information

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray

    Prior = Tuple[NDArray[np.float64], NDArray[np.float64]]


def motion_spread(cfg: SlamConfig, motion_std: NDArray[np.float64]) -> NDArray[np.float64]:
    """(3,) std-devs along, across and of the heading of the step's motion model, at
    least match_floor_xy / match_floor_theta (odometry jitters even between close scans)."""
    return np.maximum(motion_std, [cfg.match_floor_xy, cfg.match_floor_xy, cfg.match_floor_theta])


def motion_arc(cfg: SlamConfig, prev_odom: NDArray[np.float64], odom: NDArray[np.float64]) -> OdometryArc | None:
    """The step's odometry model in its own terms for the search's prior and the gate
    (match_prior_arc), floored as motion_spread; None for a step shorter than
    match_prior_arc, whose first turn the odometry hardly knows, or when off."""
    if cfg.match_prior_arc <= 0 or cfg.match_prior != "motion" or cfg.motion_model != "odometry":
        return None
    if float(np.hypot(*(odom[:2] - prev_odom[:2]))) < cfg.match_prior_arc:
        return None
    return odometry_arc(prev_odom, odom, (cfg.srr, cfg.srt, cfg.str, cfg.stt), cfg.match_floor_xy,
                        cfg.match_floor_theta)


def match_request(cfg: SlamConfig, params: MatchParams, samples: NDArray[np.float64],
                  predicted: NDArray[np.float64], motion_std: NDArray[np.float64]
                  ) -> tuple[NDArray[np.float64], MatchParams, Prior | None]:
    """(start poses (N, 3), search parameters, prior) of the match for particles whose
    motion samples are samples (N, 3) and noise-free predictions predicted (N, 3).

    match_window > 0: the search spans that many std-devs of the motion model round
    the prediction (at most match_xy_range / match_theta_range): narrow, and cheap,
    for the short steps of a full-rate log, as wide as the odometry may err for a
    long one. Otherwise the fixed half-widths round each particle's sample.
    """
    if cfg.match_prior != "motion":
        return samples, params, None
    std = motion_spread(cfg, motion_std)
    if cfg.match_window <= 0:
        return samples, params, (predicted, std)
    half = cfg.match_window * std
    params = replace(params, xy_range=min(cfg.match_xy_range, float(max(half[0], half[1]))),
                     theta_range=min(cfg.match_theta_range, float(half[2])))
    return predicted, params, (predicted, std)


def within_motion(poses: NDArray[np.float64], predicted: NDArray[np.float64], std: NDArray[np.float64],
                  gate: float, arc: OdometryArc | None = None) -> NDArray[np.bool_]:
    """(N,) whether each pose (N, 3) lies within gate std-devs std (3,) (along and across
    the predicted heading, heading) of its prediction (N, 3), as a Mahalanobis distance;
    arc: in the step's own terms instead."""
    if arc is not None:
        return np.asarray(arc.cost(poses[:, 0], poses[:, 1], poses[:, 2], predicted[:, 0], predicted[:, 1],
                                   predicted[:, 2]) <= gate ** 2)
    c, s = cos_sin(predicted[:, 2])
    dx, dy = poses[:, 0] - predicted[:, 0], poses[:, 1] - predicted[:, 1]
    along, across = c * dx + s * dy, c * dy - s * dx
    turn = wrap_angle(poses[:, 2] - predicted[:, 2])
    d2 = (along / std[0]) ** 2 + (across / std[1]) ** 2 + (turn / std[2]) ** 2
    return np.asarray(d2 <= gate ** 2)


def gate_match(cfg: SlamConfig, match: Match, predicted: NDArray[np.float64],
               motion_std: NDArray[np.float64], arc: OdometryArc | None = None) -> Match:
    """The match with the trust of those that moved a particle further from its motion
    prediction than match_gate std-devs withdrawn, unless match_good_score of their end
    points lie on occupied cells: a poor or ambiguous match (a turned copy of a room, the
    wrong corridor) explains the scan by a motion the odometry makes implausible, and
    the particle keeps its motion sample; a good one may correct a wheel slip. arc: the
    step's odometry model in its own terms (match_prior_arc), measured in those."""
    if cfg.match_gate <= 0 or match.score is None:
        return match
    good = match.score >= cfg.match_good_score
    near = within_motion(match.poses, predicted, motion_spread(cfg, motion_std), cfg.match_gate, arc)
    return replace(match, trusted=match.trusted & (good | near), beyond_gate=match.trusted & good & ~near)


def taken(match: Match, other: Match, take: NDArray[np.bool_]) -> Match:
    """match with other's result for the particles where take (N,) holds, trusted there;
    each per-particle field taken from the same side (covariance, score, information...)."""
    def pick(a: NDArray[Any], b: NDArray[Any]) -> NDArray[Any]:
        return np.where(take.reshape((-1,) + (1,) * (a.ndim - 1)), b, a)

    def pick_some(a: NDArray[Any] | None, b: NDArray[Any] | None) -> NDArray[Any] | None:
        return a if a is None or b is None else pick(a, b)

    return replace(match, poses=pick(match.poses, other.poses), trusted=match.trusted | take,
                   covariance=pick_some(match.covariance, other.covariance), score=pick_some(match.score, other.score),
                   scan_information=pick_some(match.scan_information, other.scan_information),
                   free=pick_some(match.free, other.free), beyond_gate=pick_some(match.beyond_gate, other.beyond_gate))


def fuse_with_motion(matched: NDArray[np.float64], predicted: NDArray[np.float64], spread: NDArray[np.float64],
                     scan_information: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N, 3) the poses that best agree with both the matches (N, 3), of information
    scan_information (N, 3, 3), and the motion predictions (N, 3), of std-devs spread (3,)
    along and across their headings and of the heading: the prediction moved towards the
    match as far as the scan knows each direction better than the motion (along a
    featureless corridor, hardly at all)."""
    prior = prior_information(predicted, spread)
    d = matched - predicted
    d[:, 2] = wrap_angle(d[:, 2])
    fused = predicted + solve3(scan_information + prior, np.einsum("nij,nj->ni", scan_information, d))
    fused[:, 2] = wrap_angle(fused[:, 2])
    return fused


def normaliser_log_terms(poses: NDArray[np.float64], predicted: NDArray[np.float64], spread: NDArray[np.float64],
                         scan_information: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N,) log of the improved proposal's normaliser (Grisetti et al. 2007) less the log
    scan likelihood at the matched poses (N, 3), up to a constant shared by all particles.

    The normaliser is what the particle's weight is multiplied by: the scan's
    likelihood integrated over the motion prior, eta = int p(z | x) p(x | x', u) dx.
    With the likelihood Gaussian about the match x* (information G = scan_information
    (N, 3, 3), the weights' own scale) and the prior N(predicted (N, 3), S) with
    std-devs spread (3,) along, across and of the heading:

        log eta = log p(z | x*) - 1/2 d^T (S + G^-1)^-1 d - 1/2 log det(I + G S),  d = x* - predicted

    (finite where G is singular, along a corridor: (S + G^-1)^-1 = (I + G S)^-1 G). A
    particle whose match lies far from its own prediction, or whose scan pins it
    down much tighter than its motion, gets less than one matched where it expected.
    """
    prior_cov = inv3(prior_information(predicted, spread))
    eye = np.eye(3)
    m = eye + scan_information @ prior_cov
    a = inv3(m) @ scan_information
    d = poses - predicted
    d[:, 2] = wrap_angle(d[:, 2])
    quad = np.einsum("ni,nij,nj->n", d, a, d)
    return np.asarray(-0.5 * quad - 0.5 * np.log(np.linalg.det(m)))
