"""FastSLAM with per-particle occupancy grids (CS-475 assignment 5, algorithm 1).

One update, in the assignment's order: move every particle by odometry, weigh it by
how well its map (before this scan) predicts the scan, write the scan into its map,
resample. The improved mode slots into the same steps: update gating, a scan-matching
proposal after the motion, likelihood log-weights, resampling only when Neff is low.
"""
from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from . import raycast
from .config import SlamConfig
from .geometry import circular_mean, compose, cos_sin, wrap_angle
from .grid import GridMaps
from .motion import odometry_std, sample_motion_assignment, sample_motion_odometry
from .resample import entropy, low_variance_indices, neff, slot_parents
from .scan import Beams, Scan, select_beams
from .weights import assignment_log_weights, likelihood_log_weights, normalise_log

# Likelihood weights need no expected ranges, so the map update traces each beam only
# about as far as it reaches, in this many groups of beams of similar length.
TRIM_GROUPS = 4


PRUNE_EVERY = 256  # updates between prunings of the trajectory history


@dataclass(frozen=True)
class StepInfo:
    """What one call of FastSlam.step did."""

    processed: bool
    neff: float = 0.0
    resampled: bool = False
    best: int = 0
    seconds: float = 0.0
    grew: bool = False
    clipped: bool = False
    matched: int = 0  # particles whose pose came from the scan matcher
    entropy: float = 0.0  # of the weights before resampling [nat]


class FastSlam:
    """The particle set: poses (N, 3), log-weights (N,), maps (N, H, W), trajectories."""

    def __init__(self, cfg: SlamConfig, rng: np.random.Generator | None = None) -> None:
        self.cfg = cfg
        self.rng = rng if rng is not None else np.random.default_rng(cfg.rng_seed)
        self.reset()

    def reset(self) -> None:
        """Forgets everything: particles back near the map centre, maps unknown."""
        cfg = self.cfg
        n = cfg.particles
        h, w = cfg.grid_shape
        self.grid = GridMaps(n, (h, w), cfg.map_resolution,
                             (-w * cfg.map_resolution / 2, -h * cfg.map_resolution / 2),
                             l_limit=max(-cfg.l_min, cfg.l_max))
        g = self.grid
        self._l_units = dict(l_free=g.quantise(cfg.l_free), l_occ=g.quantise(cfg.l_occ),
                             l_min=g.quantise(cfg.l_min), l_max=g.quantise(cfg.l_max))
        self.poses = np.zeros((n, 3))
        spread = np.array([cfg.init_sigma_xy, cfg.init_sigma_xy, cfg.init_sigma_theta])
        if np.any(spread > 0):
            self.poses += self.rng.normal(0.0, 1.0, (n, 3)) * spread
            self.poses[:, 2] = wrap_angle(self.poses[:, 2])
        self.log_w = np.zeros(n)
        self.best = 0
        self.updates = 0
        self._odom: NDArray[np.float64] | None = None
        self._predicted = self.poses.copy()          # noise-free motion of the last update
        self._motion_std = np.zeros(3)               # and its spread (match_prior: motion)
        self._stamp = -np.inf
        self._hist_poses: list[NDArray[np.float64]] = []
        self._hist_parent: list[NDArray[np.intp]] = []
        self._hist_stamps: list[float] = []
        self._trunk: list[NDArray[np.float64]] = []  # (k, 4) blocks t, x, y, theta of the one lineage left

    def rebase_odometry(self, odom: NDArray) -> None:
        """Takes odom as the new reference without moving the particles (after a jump)."""
        if self._odom is not None:
            self._odom = np.asarray(odom, dtype=np.float64)

    @property
    def weights(self) -> NDArray[np.float64]:
        """(N,) normalised weights."""
        return normalise_log(self.log_w)

    def step(self, odom: NDArray, scan: Scan) -> StepInfo:
        """One FastSLAM update with the odometry pose (3,) at the scan's time."""
        odom = np.asarray(odom, dtype=np.float64)
        first = self._odom is None
        if not first and not self._due(odom, scan.stamp):
            return StepInfo(processed=False, neff=neff(self.weights), best=self.best)
        start = time.perf_counter()
        beams = select_beams(scan, self.cfg)
        if first:
            self._anchor(odom)
        else:
            self._move(odom)                                    # 1. motion update
        self._odom, self._stamp = odom, scan.stamp
        grew, clipped = self._cover_beams()
        matched = 0
        if self.cfg.proposal == "scan_match" and not first:
            matched = self._propose(beams)                      # 1b. scan-matching proposal
        self._observe(beams)                                    # 2.+3. weights, then grid update
        w = self.weights
        self.best = int(np.argmax(w))
        n_eff = neff(w)
        resampled = self._resample(w, n_eff)                    # 4. low-variance resampling
        self._record(scan.stamp)
        self.updates += 1
        return StepInfo(processed=True, neff=n_eff, resampled=resampled, best=self.best,
                        seconds=time.perf_counter() - start, grew=grew, clipped=clipped, matched=matched,
                        entropy=entropy(w))

    # -- the named steps -------------------------------------------------------------
    def _anchor(self, odom: NDArray) -> None:
        """First scan: the map frame is the odometry frame, the grid centred on the robot."""
        self.poses = compose(odom, self.poses)
        self.grid.origin = self.grid.origin + odom[:2]

    def _due(self, odom: NDArray, stamp: float) -> bool:
        """Gating: process after enough travel, turn or time (all zero: every scan)."""
        cfg = self.cfg
        assert self._odom is not None
        if cfg.linear_update == 0 and cfg.angular_update == 0:
            return True
        moved = float(np.hypot(*(odom[:2] - self._odom[:2])))
        turned = abs(float(wrap_angle(odom[2] - self._odom[2])))
        waited = cfg.temporal_update >= 0 and stamp - self._stamp >= cfg.temporal_update
        return moved >= cfg.linear_update or turned >= cfg.angular_update or waited

    def _move(self, odom: NDArray) -> None:
        cfg = self.cfg
        assert self._odom is not None
        if cfg.proposal == "scan_match" and cfg.match_prior == "motion":
            # The matcher's prior: the noise-free prediction and its spread (no random draw).
            self._predicted = self.poses.copy()
            self._apply_motion(self._predicted, odom, noise=False)
            self._motion_std = (np.asarray(cfg.motion_sigmas, dtype=np.float64) if cfg.motion_model == "assignment"
                                else odometry_std(self._odom, odom, (cfg.srr, cfg.srt, cfg.str, cfg.stt)))
        self._apply_motion(self.poses, odom, noise=bool(cfg.toggle_noise))

    def _apply_motion(self, poses: NDArray[np.float64], odom: NDArray, noise: bool) -> None:
        """Moves poses (N, 3) in place by the configured motion model, sampled or not."""
        cfg = self.cfg
        if cfg.motion_model == "assignment":
            sigmas = cfg.motion_sigmas if noise else np.zeros(3)  # zeros: no random draw
            sample_motion_assignment(poses, self._odom, odom, sigmas, self.rng)
        else:
            sample_motion_odometry(poses, self._odom, odom, (cfg.srr, cfg.srt, cfg.str, cfg.stt), noise, self.rng)

    def _cover_beams(self) -> tuple[bool, bool]:
        """Grows the maps so every particle's beams stay inside; or reports clipping."""
        reach = self.cfg.max_range + 2 * self.cfg.map_resolution
        lo = self.poses[:, :2].min(axis=0) - reach
        hi = self.poses[:, :2].max(axis=0) + reach
        if self.grid.covers(lo[0], lo[1], hi[0], hi[1]):
            return False, False
        if self.cfg.map_grow:
            return self.grid.grow_to(lo[0], lo[1], hi[0], hi[1], fraction=self.cfg.map_grow_fraction), False
        return False, True

    def _beam_frames(self, beams: Beams) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(N, 2) beam origins and (N, M) beam directions of every particle, map frame."""
        p = self.poses
        c, s = cos_sin(p[:, 2])
        mx, my = beams.mount
        origins = np.stack([p[:, 0] + c * mx - s * my, p[:, 1] + s * mx + c * my], axis=1)
        return origins, p[:, 2, None] + beams.angles[None, :]

    def _propose(self, beams: Beams) -> int:
        from .scanmatch import refine_poses  # improved mode only

        prior = (self._predicted, self._motion_std) if self.cfg.match_prior == "motion" else None
        return int(refine_poses(self, beams, prior=prior).sum())

    def _observe(self, beams: Beams) -> None:
        """Weighs every particle against its map before this scan, then writes the scan in."""
        cfg = self.cfg
        weigh = bool(beams.hit.any())  # with no return to compare, weights stay as they are
        log_w = None
        if weigh and cfg.weight_model == "likelihood":
            from .scanmatch import endpoint_distances, returns_subset

            sub = returns_subset(beams, cfg.match_beams)  # the matcher's end points
            dist = endpoint_distances(self.grid, self.poses, sub, max_dist=cfg.likelihood_max_dist)
            log_w = likelihood_log_weights(dist, sub.hit, cfg.likelihood_sigma,
                                           cfg.likelihood_max_dist, cfg.likelihood_gain)
        origins, angles = self._beam_frames(beams)
        d = raycast.observe(self.grid, origins, angles, beams.ranges, beams.hit, beams.free_range,
                            max_range=cfg.max_range, range_min=beams.range_min,
                            expected=weigh and cfg.weight_model == "assignment", **self._l_units,
                            trim_groups=TRIM_GROUPS if cfg.weight_model == "likelihood" else 0,
                            free_step=cfg.free_beam_step)
        if d is not None:
            log_w = assignment_log_weights(d, beams.ranges, beams.hit)
        if log_w is not None:
            self.log_w = self.log_w + log_w
            self.log_w -= self.log_w.max()  # only differences matter; keep them small

    def _resample(self, w: NDArray[np.float64], n_eff: float) -> bool:
        n = len(w)
        if self.cfg.resample_threshold < 1.0 and n_eff >= self.cfg.resample_threshold * n:
            self._hist_parent.append(np.arange(n))
            return False
        parent = slot_parents(low_variance_indices(w, self.rng))
        self.poses = self.poses[parent]
        self.grid.reorder(parent)
        self.log_w = np.zeros(n)
        self._hist_parent.append(parent)
        return True

    def _record(self, stamp: float) -> None:
        self._hist_poses.append(self.poses.copy())
        self._hist_stamps.append(float(stamp))
        if len(self._hist_poses) % PRUNE_EVERY == 0:
            self._prune_history()

    def _prune_history(self) -> None:
        """Drops history no living particle descends from (gmapping prunes its tree too).

        Lineages merge within a few resamplings, so what is left is about one path:
        memory then grows by one pose per update instead of N.
        """
        keep = np.arange(len(self.poses))  # rows of step t that living particles descend from
        for t in range(len(self._hist_poses) - 1, -1, -1):
            rows = np.unique(keep)
            new_row = np.full(len(self._hist_poses[t]), -1, dtype=np.intp)
            new_row[rows] = np.arange(len(rows))
            if t + 1 < len(self._hist_parent):
                self._hist_parent[t + 1] = new_row[self._hist_parent[t + 1]]
            if len(self._hist_poses[t]) == 1:
                break  # a single lineage already: an earlier pruning compacted all before it
            keep = self._hist_parent[t][rows]
            self._hist_poses[t] = self._hist_poses[t][rows]
            self._hist_parent[t] = keep
        # The steps every living particle shares move into one compact block.
        shared = next((t for t, rows in enumerate(self._hist_poses) if len(rows) > 1), len(self._hist_poses))
        shared = min(shared, len(self._hist_poses) - 1)  # the newest step keeps its N slots
        if shared > 0:
            block = np.concatenate([np.array(self._hist_stamps[:shared])[:, None],
                                    np.concatenate(self._hist_poses[:shared])], axis=1)
            self._trunk.append(block)
            del self._hist_poses[:shared], self._hist_parent[:shared], self._hist_stamps[:shared]

    # -- results ---------------------------------------------------------------------
    def trajectory(self, particle: int | None = None) -> NDArray[np.float64]:
        """(T, 4) rows t, x, y, theta: the path of a particle (default the best) through
        every processed scan, following its ancestors back through resampling."""
        j = self.best if particle is None else int(particle)
        t_len = len(self._hist_poses)
        out = np.empty((t_len, 4))
        for t in range(t_len - 1, -1, -1):
            out[t, 0] = self._hist_stamps[t]
            out[t, 1:] = self._hist_poses[t][j]
            j = int(self._hist_parent[t][j])
        return np.concatenate(self._trunk + [out]) if self._trunk else out

    def mean_pose(self) -> NDArray[np.float64]:
        """(3,) weighted mean pose, circular mean for the heading."""
        w = self.weights
        return np.array([w @ self.poses[:, 0], w @ self.poses[:, 1],
                         circular_mean(self.poses[:, 2], w)])

    def covariance(self) -> NDArray[np.float64]:
        """(3, 3) weighted covariance of the particle poses (heading wrapped)."""
        w = self.weights
        d = self.poses - self.mean_pose()
        d[:, 2] = wrap_angle(d[:, 2])
        return (d * w[:, None]).T @ d

    def best_occupancy(self) -> NDArray[np.int8]:
        """(H, W) ROS occupancy values of the best particle's map."""
        return self.grid.occupancy(self.best)
