"""FastSLAM with per-particle occupancy grids (CS-475 assignment 5, algorithm 1).

One update, in the assignment's order: move every particle by odometry, weigh it by
how well its map (before this scan) predicts the scan, write the scan into its map,
resample. The improved mode slots into the same steps: update gating, a scan-matching
proposal after the motion, likelihood log-weights, resampling only when Neff is low.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING, Callable

import numpy as np

from fastslam.config import SlamConfig
from fastslam.filter import raycast, trimmed
from fastslam.filter.best import pairwise_distances, weighted_medoid
from fastslam.filter.budget import Limits
from fastslam.filter.grid import GridMaps
from fastslam.filter.history import History
from fastslam.filter.loop import ScanStore, loop_start, spread_jump
from fastslam.filter.motion import (
    OdometryArc,
    odometry_std,
    odometry_step,
    sample_motion_assignment,
    sample_motion_odometry,
)
from fastslam.filter.odom_scale import OdometryScale
from fastslam.filter.proposal import (
    fuse_with_motion,
    gate_match,
    match_request,
    motion_arc,
    motion_spread,
    normaliser_log_terms,
    taken,
)
from fastslam.filter.resample import entropy, low_variance_indices, neff, slot_parents
from fastslam.filter.scan import Beams, Scan, returns_subset, select_beams
from fastslam.filter.tiles import TileMaps
from fastslam.filter.track import Tracker
from fastslam.filter.weights import Weighing, assignment_log_weights, normalise_log
from fastslam.geometry import cholesky3, circular_mean, compose, transform_points, wrap_angle
from fastslam.match import Match, MatchParams, match_poses
from fastslam.match.matcher import PRIOR_FLOOR
from fastslam.match.refine import ICP_SIGMA, prior_information

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


# Likelihood weights need no expected ranges, so the map update traces each beam only
# about as far as it reaches, in this many groups of beams of similar length.
TRIM_GROUPS = 4


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
    refused: str = ""  # why the maps were not grown, at the first refusal of this filter's life


@dataclass(frozen=True)
class UpdateTrace:
    """One processed update as FastSlam.trace sees it (bench/lineage.py): arrays over the
    particles in their order before this update's resampling, except path (after it).

    predicted: (N, 3) noise-free motion predictions (None: the first update, or no matcher prior).
    match: the update's match (trusted, recovered), None when the scan was not matched.
    log_w_step: (N,) what this scan added to the log-weights; weights: (N,) before resampling.
    parent: (N,) each particle's slot before resampling; path: (N, 3) the paths' new poses.
    """

    stamp: float
    predicted: NDArray[np.float64] | None
    match: Match | None
    log_w_step: NDArray[np.float64]
    weights: NDArray[np.float64]
    n_eff: float
    resampled: bool
    parent: NDArray[np.intp]
    path: NDArray[np.float64]


class FastSlam:
    """The particle set: poses (N, 3), log-weights (N,), maps (N, H, W), trajectories."""

    maps_type: type[GridMaps] = TileMaps   # the maps' storage: shared copy-on-write tiles (GridMaps: dense)

    def __init__(self, cfg: SlamConfig, rng: np.random.Generator | None = None, *,
                 limits: Limits | None = None, tracker: Tracker | None = None) -> None:
        self.cfg = cfg
        # the live pose between updates (map->odom); filter/pipeline.py's runs in a second process
        self.tracker = tracker if tracker is not None else Tracker(cfg, self.track_params(cfg))
        self.rng = rng if rng is not None else np.random.default_rng(cfg.rng_seed)
        self.limits = limits if limits is not None else Limits()
        self.refusals = 0  # growths refused (max_map_extent, memory), over every life
        self.recoveries = 0  # updates where the wider search (match_recover) found a trusted match
        self.beyond_gate = 0  # updates where a match beyond match_gate was trusted for its score
        self.loops = 0        # updates where match_loop moved particles to a place found again
        self.loops_spread = 0  # ... and the jump was spread back along the path (loop_spread)
        self.trace: Callable[[UpdateTrace], None] | None = None   # called after each update (diagnostics)
        # odom_scale: the odometry's scale, learnt from the matches; kept through reset() (same wheels)
        self.odom_scale = OdometryScale(cfg.odom_scale_prior) if cfg.odom_scale else None
        self.reset()

    def reset(self) -> None:
        """Forgets everything: particles back near the map centre, maps unknown."""
        cfg = self.cfg
        n = cfg.particles
        h, w = cfg.grid_shape
        self.tracker.clear()
        # the tracker reads them from another process (dense maps cannot be shared: it then works here)
        shared = {"shared": True} if self.tracker.shares_maps and issubclass(self.maps_type, TileMaps) else {}
        self.grid = self.maps_type(n, (h, w), cfg.map_resolution,
                             (-w * cfg.map_resolution / 2, -h * cfg.map_resolution / 2),
                             l_limit=max(-cfg.l_min, cfg.l_max), **shared)
        self._steps = self.grid.steps(cfg.l_free, cfg.l_occ, cfg.l_min, cfg.l_max)
        self._match_params = MatchParams.from_config(cfg)
        self._raw_travel = 0.0   # odom_scale: the last step's travel as measured
        self._before: NDArray[np.float64] | None = None   # the particles before it (odom_scale, match_prior_bearing)
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
        self._arc: OdometryArc | None = None         # and the step in its own terms (match_prior_arc)
        self._stamp = -np.inf
        self._refused = False  # a growth was refused in this life (reported once)
        self.history = History()
        self._apart = np.zeros((n, n))   # best_particle medoid: distances between the paths, summed
        self._carried = np.zeros(n)      # each path's log-weight up to the last resampling (path_log_w)
        self._match: Match | None = None              # this update's gated match (match_weight)
        self._proposed: Match | None = None           # ... trusted or not (trace, the paths)
        # This update's poses for map->odom and (path_match_scale 0) the paths: the trusted matches
        # themselves, not the samples drawn round them (those spread the particles; their noise adds to a path).
        self._centre: NDArray[np.float64] | None = None
        # path_match_scale: each path's last pose (history.latest) moved by the motion since the last update
        # (the odometry's; track_scans: the live pose's, matched at the scans between), and its next pose
        self._path_predicted: NDArray[np.float64] | None = None
        self._path_odom: NDArray[np.float64] | None = None   # ... (track_scans) to be moved to this odometry
        self._path_next: NDArray[np.float64] | None = None
        # loop_spread: every processed scan's beams, and this update's loop jump (which particles
        # moved, from where, to where)
        self._scans = ScanStore() if cfg.loop_spread else None
        self._loop_jump: tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]] | None = None

    @staticmethod
    def track_params(cfg: SlamConfig) -> MatchParams:
        """The tracker's matches: the proposal's, on track_beams returns."""
        return replace(MatchParams.from_config(cfg), beams=cfg.track_beams)

    @property
    def live_pose(self) -> NDArray[np.float64]:
        """(3,) the pose map->odom gives at the last scan seen: the best particle at an update,
        moved by odometry (and, track_scans, the scan matcher) at the scans between."""
        return self.tracker.pose

    @live_pose.setter
    def live_pose(self, pose: NDArray[np.float64]) -> None:
        self.tracker.pose = np.asarray(pose, dtype=np.float64)

    @property
    def stalls(self) -> int:
        """Scans tracked with the odometry stalled (track_scans), over every life."""
        return self.tracker.stalls

    def rebase_odometry(self, odom: NDArray[np.float64]) -> None:
        """Takes odom as the new reference without moving the particles (after a jump)."""
        if self._odom is not None:
            self._odom = np.asarray(odom, dtype=np.float64)
            self.tracker.rebase(self._odom)

    @property
    def weights(self) -> NDArray[np.float64]:
        """(N,) normalised weights."""
        return normalise_log(self.log_w)

    def step(self, odom: NDArray[np.float64], scan: Scan) -> StepInfo:
        """One FastSLAM update with the odometry pose (3,) at the scan's time."""
        odom = np.asarray(odom, dtype=np.float64)
        first = self._odom is None
        start = time.perf_counter()
        if not first and not self.due(odom, scan.stamp):
            self.tracker.track(odom, scan)
            return StepInfo(processed=False, neff=neff(self.weights), best=self.best,
                            seconds=time.perf_counter() - start)
        beams = select_beams(scan, self.cfg)
        if self._scans is not None:
            self._scans.append(beams)
        if first:
            self._anchor(odom)
        else:
            self._move(odom)                                    # 1. motion update
        self._odom, self._stamp = odom, scan.stamp
        grew, clipped, refused = self._cover_beams()
        matched = 0
        self._proposed = None
        proposing = self.cfg.proposal == "scan_match" and not first
        if proposing:
            matched = self._propose(beams)                      # 1b. scan-matching proposal
        log_w_before = self.log_w.copy() if self.trace is not None else None
        self._observe(beams)                                    # 2.+3. weights, then grid update
        if proposing:
            self._follow_path()
        log_w_step = None if log_w_before is None else self._log_w_step(log_w_before)
        w = self.weights
        self.best = int(np.argmax(w))
        n_eff = neff(w)
        medoid = self.cfg.best_particle == "medoid"
        if medoid:
            self._apart += pairwise_distances(self.poses[:, :2])
        resampled, parent = self._resample(w, n_eff)            # 4. low-variance resampling
        if medoid:
            self.best = weighted_medoid(self._apart, normalise_log(self.path_log_w))
        centre, self._centre = (self.poses if self._centre is None else self._centre), None
        path, self._path_next = (centre if self._path_next is None else self._path_next), None
        self.history.append(scan.stamp, path, parent)
        jump, self._loop_jump = self._loop_jump, None
        if jump is not None and self._spread_loop(jump, parent):
            centre = self.poses
        if self.trace is not None and log_w_step is not None:
            predicted = None if first or self.cfg.match_prior != "motion" else self._predicted.copy()
            self.trace(UpdateTrace(scan.stamp, predicted, self._proposed, log_w_step, w,
                                   n_eff, resampled, parent, path.copy()))   # path may be self.poses: moved later
        self.updates += 1
        self.tracker.start(centre[self.best], odom, scan.ranges, self.grid, self.best)
        return StepInfo(processed=True, neff=n_eff, resampled=resampled, best=self.best,
                        seconds=time.perf_counter() - start, grew=grew, clipped=clipped, matched=matched,
                        entropy=entropy(w), refused=refused)

    # -- the named steps -------------------------------------------------------------
    def _anchor(self, odom: NDArray[np.float64]) -> None:
        """First scan: the map frame is the odometry frame, the grid centred on the robot."""
        self.poses = compose(odom, self.poses)
        self.grid.origin = self.grid.origin + odom[:2]

    def due(self, odom: NDArray[np.float64], stamp: float) -> bool:
        """Gating: whether a scan at odometry pose odom (3,) and this stamp is processed:
        after enough travel, turn or time since the last processed one (all zero: every scan)."""
        cfg = self.cfg
        if self._odom is None:
            return True
        if cfg.linear_update == 0 and cfg.angular_update == 0:
            return True
        moved = float(np.hypot(*(odom[:2] - self._odom[:2])))
        turned = abs(float(wrap_angle(odom[2] - self._odom[2])))
        waited = cfg.temporal_update >= 0 and stamp - self._stamp >= cfg.temporal_update
        return moved >= cfg.linear_update or turned >= cfg.angular_update or waited

    def _move(self, odom: NDArray[np.float64]) -> None:
        cfg = self.cfg
        assert self._odom is not None
        moved = odom   # the odometry pose the particles move to: scaled (odom_scale) or as measured
        if self.odom_scale is not None or cfg.match_prior_bearing > 0:
            self._before = self.poses.copy()
        if self.odom_scale is not None:
            self._raw_travel = odometry_step(self._odom, odom)[0]
            moved = self.odom_scale.corrected(self._odom, odom)
        if cfg.proposal == "scan_match" and cfg.match_prior == "motion":
            # The matcher's prior: the noise-free prediction and its spread (no random draw).
            self._predicted = self.poses.copy()
            self._apply_motion(self._predicted, moved, noise=False)
            self._motion_std = (np.asarray(cfg.motion_sigmas, dtype=np.float64) if cfg.motion_model == "assignment"
                                else odometry_std(self._odom, moved, (cfg.srr, cfg.srt, cfg.str, cfg.stt)))
            self._arc = motion_arc(cfg, self._odom, moved)
        self._path_predicted = self._path_odom = None
        if cfg.path_match_scale > 0 and cfg.proposal == "scan_match" and self.history.latest is not None:
            if cfg.track_scans:   # the scans' motion since the last update (_predict_path, once the tracker is done)
                self._path_odom = odom
            else:
                self._path_predicted = self.history.latest.copy()
                self._apply_motion(self._path_predicted, moved, noise=False)
        self._apply_motion(self.poses, moved, noise=bool(cfg.toggle_noise))

    def _apply_motion(self, poses: NDArray[np.float64], odom: NDArray[np.float64], noise: bool) -> None:
        """Moves poses (N, 3) in place by the configured motion model, sampled or not."""
        cfg = self.cfg
        assert self._odom is not None
        if cfg.motion_model == "assignment":
            sigmas = cfg.motion_sigmas if noise else np.zeros(3)  # zeros: no random draw
            sample_motion_assignment(poses, self._odom, odom, sigmas, self.rng)
        else:
            sample_motion_odometry(poses, self._odom, odom, (cfg.srr, cfg.srt, cfg.str, cfg.stt), noise, self.rng)

    def _cover_beams(self) -> tuple[bool, bool, str]:
        """Grows the maps so every particle's beams stay inside, within the limits (by
        only what is missing if the usual growth would pass them); else beams past the
        edge are clipped. Returns (grew, clipped, why refused: at the first refusal)."""
        reach = self.cfg.max_range + 2 * self.cfg.map_resolution
        lo = self.poses[:, :2].min(axis=0) - reach
        hi = self.poses[:, :2].max(axis=0) + reach
        box = (float(lo[0]), float(lo[1]), float(hi[0]), float(hi[1]))
        if self.grid.covers(*box):
            return False, False, ""
        if not self.cfg.map_grow:
            return False, True, ""
        fraction = self.cfg.map_grow_fraction
        problem = self.limits.growth_problem(self.grid, box, fraction)
        if problem and fraction > 0 and self.limits.growth_problem(self.grid, box, 0.0) is None:
            problem, fraction = None, 0.0
        if problem is None:
            try:
                return self.grid.grow_to(*box, fraction=fraction), False, ""
            except MemoryError:
                problem = f"the allocation of {self.grid.growth_bytes(*box, fraction=fraction) / 2**20:.0f} MB failed"
        self.refusals += 1
        first = not self._refused
        self._refused = True
        return False, True, (f"map growth refused: {problem}; mapping goes on inside the map "
                             "(beams past its edge are clipped)") if first else ""

    def _beam_frames(self, beams: Beams, poses: NDArray[np.float64] | None = None
                     ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(N, 2) beam origins and (N, M) beam directions at poses (N, 3) (default every
        particle's), map frame."""
        poses = self.poses if poses is None else poses
        x, y = transform_points(poses, np.array([beams.mount], dtype=np.float64))
        return np.concatenate([x, y], axis=1), poses[:, 2, None] + beams.angles[None, :]

    def _write_trimmed(self, grid: GridMaps, origins: NDArray[np.float64], angles: NDArray[np.float64],
                       beams: Beams, weighing: Weighing | None = None,
                       writer: trimmed.Writer | None = None) -> NDArray[np.float64] | None:
        """The likelihood model's map update of grid's particles (trimmed.update_trimmed), as every
        update writes it (and loop_spread writes it again); weighing: the weights first; writer:
        the second process that writes some particles."""
        cfg = self.cfg
        return trimmed.update_trimmed(grid, origins, angles, beams, self._steps, max_range=cfg.max_range,
                                      groups=TRIM_GROUPS,
                                      free_step=trimmed.clearing_step(beams.angles, cfg.free_beam_step,
                                                                      cfg.free_beam_spacing),
                                      weighing=weighing, writer=writer)

    def _propose(self, beams: Beams) -> int:
        """Moves each particle whose scan match is trusted to a sample around the match."""
        match = self._match_gated(beams)
        if self.odom_scale is not None:
            self._learn_scale(match)
        if self.cfg.match_loop > 0 and self.updates > 1:     # (after one scan nothing was seen long ago)
            match = self._loop(beams, match)
        if not match.trusted.any() and self.cfg.match_recover > 0:
            match = self._recover(beams)
        self._proposed = match
        if match.trusted.any():
            self._sample_around(match)
            self._match = match
            self.beyond_gate += int(match.beyond_gate is not None and bool(match.beyond_gate.any()))   # all trusted
        return int(match.trusted.sum())

    def _follow_path(self) -> None:
        """path_match_scale: each path's next pose, its own last pose moved by its motion
        (_move; track_scans: the live pose's, matched at the scans between, as real odometry
        jitters by degrees), corrected by a trusted match where the scan pins the pose down.
        Taken after the maps are written: a tracker in another process works on meanwhile."""
        if self._path_odom is not None:
            assert self.history.latest is not None
            self._path_predicted = compose(self.history.latest, self.tracker.motion_since_update(self._path_odom))
            self._path_odom = None
        match = self._proposed
        if match is None or not match.trusted.any():
            # nothing to correct them: the paths follow their motion, not the noisy particles
            self._path_next = self._path_predicted
        elif self._path_predicted is not None and match.scan_information is not None:
            # ICP's information scaled down: it counts every end point as independent
            fused = fuse_with_motion(match.poses, self._path_predicted, motion_spread(self.cfg, self._motion_std),
                                     self.cfg.path_match_scale * match.scan_information)
            self._path_next = np.where(match.trusted[:, None], fused, self._path_predicted)

    def _matcher_spread(self) -> NDArray[np.float64]:
        """(3,) std-devs of the prior the matcher used this update (as its _prior floors them)."""
        return np.maximum(motion_spread(self.cfg, self._motion_std), PRIOR_FLOOR)

    def _learn_scale(self, match: Match) -> None:
        """odom_scale: the step's trusted matches within the gate (a match beyond it found
        a place again: not motion) tell the odometry's scale where their scans pin it down."""
        assert self.odom_scale is not None and self._before is not None
        if match.scan_information is None:   # nothing matched (too few returns)
            return
        ok = match.trusted if match.beyond_gate is None else match.trusted & ~match.beyond_gate
        spread = self._matcher_spread()
        self.odom_scale.observe(self._raw_travel, self._before[ok], match.poses[ok], match.scan_information[ok],
                                prior_information(self._predicted[ok], spread))

    def _log_w_step(self, before: NDArray[np.float64]) -> NDArray[np.float64]:
        """(N,) what _observe added to the log-weights (it shifts them to a maximum of 0)."""
        step = self.log_w - before
        return step - step.max()

    def _recover(self, beams: Beams) -> Match:
        """No match trusted (drift has made the maps disagree with the scan, as on
        returning to a place seen long ago): one wider search, match_recover times the
        motion model, trusting only the matches that explain the scan well, and only when
        at least match_recover_share of the particles find one."""
        match = self._match_gated(beams, wider=self.cfg.match_recover)
        good = match.trusted if match.score is None else match.trusted & (match.score >= self.cfg.match_recover_score)
        if good.mean() < self.cfg.match_recover_share:
            good = np.zeros_like(good)  # a few particles' maps only: an ambiguity, not a place found again
        self.recoveries += int(good.any())
        return replace(match, trusted=good)

    def _loop(self, beams: Beams, match: Match) -> Match:
        """match_loop: the window's match (N particles) with the wide search's where that
        scores match_loop higher. Back at a place seen long ago, the window round the
        prediction holds only the walls written since the robot came back (drifted); the
        old ones lie beyond it (ACES: 0.8 m, scoring 0.73-0.97 against 0.47-0.63). Only the
        best particle is searched wide first (one map: cheap); the others only then."""
        cfg, b = self.cfg, self.best
        if match.score is None or match.score[b] + cfg.match_loop > 1.0:   # no score could be that much more
            return match
        one = self._wide_match(beams, b, b + 1)
        assert one.score is not None
        if not (one.trusted[0] and one.score[0] >= max(match.score[b] + cfg.match_loop, cfg.match_good_score)):
            return match
        wide = self._wide_match(beams, 0, len(self.poses))
        assert wide.score is not None
        own = np.where(match.trusted, match.score, 0.0)
        take = wide.trusted & (wide.score >= own + cfg.match_loop)
        if not take.any() or take.mean() < cfg.match_recover_share:
            return match
        self.loops += 1
        if cfg.loop_spread:
            self._loop_jump = (take, match.poses.copy(), wide.poses.copy())
        return taken(match, wide, take)

    def _spread_loop(self, jump: tuple[NDArray[np.bool_], NDArray[np.float64], NDArray[np.float64]],
                     parent: NDArray[np.intp]) -> bool:
        """loop_spread (filter/loop.py): the best particle's jump spread back along its path
        since the loop's start, its map written again along the new path, and every particle
        given that path and map (the weights even). False where the jump stays: the best
        particle did not jump, or its path holds no single loop back to the place found."""
        cfg = self.cfg
        moved, before, after = jump
        b = self.best
        src = int(parent[b])            # the best particle's slot before resampling
        if not moved[src]:
            return False
        path = self.history.path(b)[:, 1:]
        start, _ = loop_start(path, cfg.loop_spread_radius, cfg.loop_spread_recent)
        if start is None:
            return False
        path = spread_jump(path, start, before[src], after[src])
        self.poses[:] = self.poses[b]
        self.log_w[:] = 0.0
        self._carried[:] = 0.0
        self._apart[:] = 0.0
        self.history.collapse(b)
        self.history.rewrite(start, path[start:-1])
        self._write_again(path)
        self.loops_spread += 1
        return True

    def _write_again(self, path: NDArray[np.float64]) -> None:
        """Every map rebuilt from the scans kept, the k-th written at path[k] (T, 3), one
        map written and shared by all (they hold the same path)."""
        scans = self._scans
        assert scans is not None and len(scans) == len(path), "one kept scan per processed update"
        self.grid.clear()
        one = self.grid.view(0)
        for k in range(len(path)):   # as the updates wrote them, in order
            beams = scans.beams(k)
            self._write_trimmed(one, *self._beam_frames(beams, path[k:k + 1]), beams)
        self.grid.reorder(np.zeros(len(self.poses), dtype=np.intp))

    def _wide_match(self, beams: Beams, first: int, stop: int) -> Match:
        """Particles first..stop-1 matched over match_loop_xy / match_loop_theta round their
        predictions (a prior as wide), held to the step's gate."""
        cfg = self.cfg
        params = replace(self._match_params, xy_range=cfg.match_loop_xy, theta_range=cfg.match_loop_theta)
        predicted = self._predicted[first:stop]
        spread = np.array([cfg.match_loop_xy, cfg.match_loop_xy, cfg.match_loop_theta])
        match = match_poses(self.grid.view(first, stop), predicted, beams, params, prior=(predicted, spread))
        return gate_match(cfg, match, predicted, self._motion_std, self._arc)

    def _match_gated(self, beams: Beams, wider: float = 1.0) -> Match:
        """Every particle's match in the window and prior of the step's motion model (its
        Gaussian, or its arc: match_prior_arc), wider times as wide, round its prediction,
        held to the gate of the same std-devs."""
        motion_std = self._motion_std * wider
        arc = None if self._arc is None else self._arc.widened(wider)
        start, params, prior = match_request(self.cfg, self._match_params, self.poses, self._predicted, motion_std)
        origin = None if self._before is None else self._before[:, :2]   # where the step began
        match = match_poses(self.grid, start, beams, params, prior=prior, arc=arc, origin=origin,
                            helper=self.tracker.helper)
        return gate_match(self.cfg, match, self._predicted, motion_std, arc)

    def _sample_around(self, match: Match) -> None:
        """Trusted particles take a sample around their match: with the match's covariance,
        or the fixed match_sigma_*.

        The fixed spread is the default: one taken from the posterior of the cell-level
        search (often a few cm) blurred the maps and doubled the Intel ATE. The ICP's
        covariance is narrow across surfaces and wide only along them.
        """
        cfg = self.cfg
        z = self.rng.normal(0.0, 1.0, (len(match.poses), 3))
        if match.covariance is None:
            sample = match.poses + z * np.array([cfg.match_sigma_xy, cfg.match_sigma_xy, cfg.match_sigma_theta])
        else:
            sample = match.poses + (cholesky3(match.covariance) * z[:, None, :]).sum(axis=2)  # L z
        sample[:, 2] = wrap_angle(sample[:, 2])
        self._centre = np.where(match.trusted[:, None], match.poses, self.poses)
        self._centre[:, 2] = wrap_angle(self._centre[:, 2])
        self.poses[match.trusted] = sample[match.trusted]

    def _observe(self, beams: Beams) -> None:
        """Weighs every particle against its map before this scan, then writes the scan in."""
        cfg = self.cfg
        weigh = bool(beams.hit.any())  # with no return to compare, weights stay as they are
        log_w = None
        origins, angles = self._beam_frames(beams)
        match, self._match = self._match, None
        if cfg.weight_model == "likelihood":
            weighing = None
            if weigh:
                sub = returns_subset(beams, cfg.match_beams)  # the matcher's end points
                if cfg.match_weight == "likelihood":
                    match = None
                at = self.poses if match is None else np.where(match.trusted[:, None], match.poses, self.poses)
                weighing = Weighing(at, sub, cfg.likelihood_sigma, cfg.likelihood_max_dist, cfg.likelihood_gain,
                                    cfg.likelihood_free)
            # each particle weighed against its map before this scan, then the scan written in
            log_w = self._write_trimmed(self.grid, origins, angles, beams, weighing, self.tracker.writer)
            if weighing is not None and log_w is not None and match is not None and cfg.match_weight == "normaliser":
                # times the prior round the match
                log_w = log_w + self._normaliser_terms(match, int(np.count_nonzero(weighing.beams.hit)))
        else:
            d = raycast.observe(self.grid, origins, angles, beams, self._steps, max_range=cfg.max_range,
                                expected=weigh)
            if d is not None:
                log_w = assignment_log_weights(d, beams.ranges, beams.hit)
        if log_w is not None:
            self.log_w = self.log_w + log_w
            self.log_w -= self.log_w.max()  # only differences matter; keep them small

    def _normaliser_terms(self, match: Match, points: int) -> NDArray[np.float64]:
        """(N,) what the improved proposal's weight adds to the likelihood at the match of
        each trusted particle (0 for the others): normaliser_log_terms with the ICP's
        information on the weights' scale (likelihood_gain, likelihood_sigma, their
        `points` end points against the ICP's)."""
        cfg = self.cfg
        assert match.scan_information is not None
        scale = (cfg.likelihood_gain * points / max(match.icp_points, 1)
                 * (ICP_SIGMA / cfg.likelihood_sigma) ** 2)
        spread = self._matcher_spread()
        terms = normaliser_log_terms(match.poses, self._predicted, spread, scale * match.scan_information)
        return np.where(match.trusted, terms, 0.0)

    def _resample(self, w: NDArray[np.float64], n_eff: float) -> tuple[bool, NDArray[np.intp]]:
        """Low-variance resampling when due; returns whether, and each slot's parent slot."""
        n = len(w)
        if self.cfg.resample_threshold < 1.0 and n_eff >= self.cfg.resample_threshold * n:
            return False, np.arange(n)
        parent = slot_parents(low_variance_indices(w, self.rng))
        self.poses = self.poses[parent]
        if self._centre is not None:
            self._centre = self._centre[parent]
        if self._path_next is not None:
            self._path_next = self._path_next[parent]
        self.grid.reorder(parent)
        self._carried = self.path_log_w[parent]     # children inherit their parent's path: its weight,
        if self.cfg.best_particle == "medoid":
            self._apart = self._apart[parent][:, parent]   # its distances to the others' paths
        self.log_w = np.zeros(n)
        return True, parent

    @property
    def path_log_w(self) -> NDArray[np.float64]:
        """(N,) each particle's path's log-weight since the start: the log-weights carried
        through resampling (not reset there, as gmapping's weightSum), up to a constant."""
        return self._carried + self.log_w

    # -- results ---------------------------------------------------------------------
    def trajectory(self, particle: int | None = None) -> NDArray[np.float64]:
        """(T, 4) rows t, x, y, theta: the path of a particle (default the best) through
        every processed scan, following its ancestors back through resampling."""
        return self.history.path(self.best if particle is None else int(particle))

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
