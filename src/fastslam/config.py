"""One typed, validated configuration for the FastSLAM core.

Defaults are the CS-475 assignment: ~20 particles, a 10 m x 10 m grid at 0.05 m
initialised to unknown, additive pose noise switched by ``toggle_noise``, the weight
1/(||d - z|| + 1) and resampling at every step. The improved mode (scan-matching
proposal, likelihood weights, adaptive resampling, update gating) is selected by
fields that default to the assignment's behaviour.
"""
from __future__ import annotations

import builtins  # gmapping's parameter `str` below shadows the type in the class body
import dataclasses
import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Mapping

import numpy as np

from fastslam.fields import ConfigError, check_fields, coerce
from fastslam.fields import choice as _choice
from fastslam.fields import num as _num

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


__all__ = ["ConfigError", "SlamConfig", "parse_override", "translate_gmapping"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SlamConfig:
    """FastSLAM parameters; units in each field's doc."""

    # Filter
    particles: int = _num(20, 1, 10000, "number of particles N")
    # -1, not null: the ROS parameter server cannot hold a None
    seed: int = _num(-1, -1, 2**32 - 1, "RNG seed; -1 = a fresh one each run")
    # Map (assignment 3.1): a grid centred on the start pose, all cells unknown
    map_resolution: float = _num(0.05, 0.005, 1.0, "cell size [m]")
    map_width: float = _num(10.0, 0.5, 2000.0, "initial map extent along x [m]")
    map_height: float = _num(10.0, 0.5, 2000.0, "initial map extent along y [m]")
    map_grow: bool = field(default=True, metadata={"doc": "grow the grid when the robot nears its edge"})
    map_grow_fraction: float = _num(0.5, 0.0, 10.0,
                                    "a side of the grid that grows adds at least this share of its size")
    init_sigma_xy: float = _num(0.0, 0.0, 10.0, "spread of the initial particle positions [m]")
    init_sigma_theta: float = _num(0.0, 0.0, math.pi, "spread of the initial headings [rad]")
    # Motion (assignment 3.2)
    motion_model: str = _choice("assignment", ("assignment", "odometry"),
                                "assignment: dr along the old heading; odometry: rot1-trans-rot2")
    toggle_noise: int = _num(1, 0, 1, "1 adds motion noise, 0 moves particles exactly by odometry")
    sigma_x: float = _num(0.005, 0.0, 10.0, "std-dev of the additive x noise per update [m]")
    sigma_y: float = _num(0.005, 0.0, 10.0, "std-dev of the additive y noise per update [m]")
    sigma_theta: float = _num(0.005, 0.0, math.pi, "std-dev of the additive heading noise per update [rad]")
    srr: float = _num(0.1, 0.0, 10.0, "odometry model: translation noise from translation")
    srt: float = _num(0.2, 0.0, 10.0, "odometry model: translation noise from rotation [m/rad]")
    str: float = _num(0.1, 0.0, 10.0, "odometry model: rotation noise from translation [rad/m]")
    stt: float = _num(0.2, 0.0, 10.0, "odometry model: rotation noise from rotation")
    # Grid update (assignment 3.3), log-odds
    l_free: float = _num(-0.4, -20.0, -1e-6, "log-odds added to cells a beam crosses")
    l_occ: float = _num(0.85, 1e-6, 20.0, "log-odds added to the cell a beam ends in")
    l_min: float = _num(-5.0, -100.0, -1e-6, "lower clamp of a cell's log-odds")
    l_max: float = _num(5.0, 1e-6, 100.0, "upper clamp of a cell's log-odds")
    # Beams (assignment tip 1): field of view and every k-th beam
    fov_min: float = _num(-180.0, -180.0, 180.0, "first beam angle used, robot frame [deg]")
    fov_max: float = _num(180.0, -180.0, 180.0, "last beam angle used, robot frame [deg]")
    beam_step: int = _num(1, 1, 10000, "use every k-th beam")
    free_beam_step: int = _num(1, 1, 10000, "likelihood mode: clear free space along every k-th used beam only "
                                            "(all mark their end cells)")
    free_beam_spacing: float = _num(0.0, 0.0, 180.0, "likelihood mode: and only along beams at least this far "
                                    "apart, whatever the laser's resolution (a larger k than free_beam_step "
                                    "where the beams lie closer); 0 = off [deg]")
    max_range: float = _num(3.5, 0.1, 200.0, "ranges are used up to this distance [m]")
    mark_range: float = _num(0.0, 0.0, 200.0, "likelihood mode: returns past max_range and short of this "
                             "mark their end cells, weigh and match, but clear free space to max_range only; "
                             "0 = off [m]")
    no_return_range: float = _num(3.5, 0.0, 200.0,
                                  "a beam with no return clears free space this far; 0 = not at all [m]")
    # Weights (assignment 3.4) and resampling (3.5)
    weight_model: builtins.str = _choice("assignment", ("assignment", "likelihood"),
                                "assignment: 1/(||d-z||+1); likelihood: endpoint model in log-weights")
    likelihood_sigma: float = _num(0.05, 1e-3, 10.0, "likelihood model: endpoint std-dev [m]")
    likelihood_max_dist: float = _num(0.3, 1e-3, 10.0, "likelihood model: distance cap per beam [m]")
    likelihood_gain: float = _num(1.0, 1e-6, 1.0, "likelihood model: exponent on the scan likelihood (smoothing)")
    likelihood_free: float = _num(0.0, 0.0, 100.0, "likelihood model: extra cost (as a beam's log-likelihood) of "
                                  "an end point in known free space with no wall within likelihood_max_dist")
    resample_threshold: float = _num(1.0, 0.0, 1.0, "resample when Neff < threshold*N; 1.0 = every update")
    best_particle: builtins.str = _choice("weight", ("weight", "medoid"),
                                          "the particle whose map and path are published: weight: the highest "
                                          "weight; medoid: the medoid of the particles' paths (summed distances "
                                          "between their positions at every update), each weighed by its "
                                          "weight since the start, carried through resampling")
    # Proposal (improved mode)
    proposal: builtins.str = _choice("odometry", ("odometry", "scan_match"), "how particle poses are proposed")
    match_min_score: float = _num(0.5, 0.0, 1.0, "scan-match score (fraction of beams on the map) needed to trust it")
    match_min_known: int = _num(100, 0, 10**9,
                                "occupied 4x4-cell blocks a particle's map needs within scan reach before matching")
    match_beams: int = _num(60, 4, 10000, "scan-match with at most this many returns, evenly spread")
    match_search_gain: float = _num(1.0, 0.01, 10.0, "the searches weigh each end point on a wall as this many "
                                    "nats against the odometry prior (1: every end point independent; "
                                    "neighbouring returns on one wall are not)")
    match_icp_beams: int = _num(0, 0, 10000, "match_refine: icp: on at most this many returns (the ICP costs little "
                                "per end point, the search and the weights much); 0 = match_beams")
    match_weight: builtins.str = _choice("likelihood", ("likelihood", "match", "normaliser"),
                                         "weight of a particle whose match is trusted: likelihood: the scan's "
                                         "at its new pose (the sample round the match); match: at the matched "
                                         "pose (gmapping's); normaliser: the improved proposal's (Grisetti et "
                                         "al. 2007), the likelihood at the match times the motion prior "
                                         "integrated round it (weight_model: likelihood, match_refine: icp, "
                                         "match_prior: motion)")
    match_icp_from_prior: bool = field(default=False, metadata={
        "doc": "match_refine: icp: also start the ICP from the prior's centre (match_prior: motion: the motion's "
               "prediction) and keep the better fit (the searches' heading steps exceed the ICP's reach)"})
    match_icp_iterations: int = _num(3, 1, 20, "match_refine: icp: Gauss-Newton steps of the ICP, the matcher's "
                                     "and track_scans' (each goes only part of the rest of the way)")
    match_xy_range: float = _num(0.2, 0.0, 5.0, "scan-match search half-width in x and y [m]")
    match_theta_range: float = _num(0.1, 0.0, math.pi, "scan-match search half-width in heading [rad]")
    match_sigma_xy: float = _num(0.01, 0.0, 1.0, "spread of the sample around a matched pose [m]")
    match_sigma_theta: float = _num(0.005, 0.0, 1.0, "spread of the sample around a matched pose [rad]")
    match_prior: builtins.str = _choice("window", ("window", "motion"),
                               "odometry prior of the match: window: centred on the particle's sample, "
                               "std-dev half the search window; motion: centred on the noise-free "
                               "prediction, std-dev from srr/srt/str/stt for this step")
    match_spread: builtins.str = _choice("fixed", ("fixed", "match"),
                                "spread of the sample around a match: fixed: match_sigma_*; match: the "
                                "ICP's covariance (inverse Hessian with the prior; match_refine: icp only)")
    match_refine: builtins.str = _choice("hill", ("hill", "icp"),
                                "last stage of the match: hill: climb the interpolated evidence; "
                                "icp: Gauss-Newton on end point to nearest occupied cell, with the prior")
    match_max_free: float = _num(1.0, 0.0, 1.0, "the matcher counts end points in known free space against a "
                                 "candidate and distrusts a match with a larger share of them; 1 = neither")
    match_short_free: float = _num(0.0, 0.0, 100.0, "end points in known free space in a run of neighbouring "
                                   "returns spanning less than this (a person, a door) do not count against a "
                                   "match (match_max_free) [m]; 0 = all count")
    match_floor_xy: float = _num(0.025, 0.0, 10.0, "match_prior: motion: least std-dev along and across of the "
                                 "matcher's odometry prior, window and gate (odometry jitter) [m]")
    match_floor_theta: float = _num(0.01, 0.0, math.pi, "... and of the heading [rad]")
    match_prior_arc: float = _num(0.0, 0.0, 100.0, "match_prior: motion, motion_model: odometry: for a step of at "
                                  "least this much travel [m], the searches' prior and the gate take the odometry "
                                  "model in its own terms (rot1, trans, rot2: an arc for a long step turned wrong), "
                                  "not a Gaussian along and across the predicted heading; 0 = off")
    match_prior_bearing: float = _num(0.0, 0.0, 1.4, "match_prior: motion, match_refine: icp: the ICP's prior is "
                                      "centred the step's travel out along the bearing the search found from the "
                                      "step's start, for bearings turned up to this much from the prediction's [rad] "
                                      "(further: this much), not at the prediction; 0 = off")
    match_good_score: float = _num(1.0, 0.0, 1.0, "a match with at least this share of its end points on "
                                   "occupied cells is not held to match_gate")
    match_window: float = _num(0.0, 0.0, 100.0, "match_prior: motion: search half-widths of this many std-devs of "
                               "the motion model for the step, around its noise-free prediction, at most "
                               "match_xy_range / match_theta_range; 0 = those fixed half-widths around each "
                               "particle's motion sample")
    match_recover: float = _num(0.0, 0.0, 100.0, "match_prior: motion: when no particle's match is trusted, "
                                "search again with this many times the motion model's std-devs (window, prior "
                                "and gate) and trust only matches with match_recover_score; 0 = off")
    match_recover_score: float = _num(1.0, 0.0, 1.0, "match_recover: trust only the matches with at least this "
                                      "share of their end points on occupied cells")
    match_recover_share: float = _num(0.0, 0.0, 1.0, "match_recover: trust its matches only when at least this "
                                      "share of the particles found one (a few: an ambiguity, as along a "
                                      "corridor, not a place found again); 0 = any")
    match_loop: float = _num(0.0, 0.0, 1.0, "match_prior: motion: each update, also search the best particle's "
                             "map match_loop_xy / match_loop_theta round its prediction; when that match scores this "
                             "much above its own window's, and at least match_good_score, search every particle so "
                             "and move those whose match there scores this much above their own, when at least "
                             "match_recover_share of them do (a place seen long ago, found again beyond the "
                             "window); 0 = off")
    match_loop_xy: float = _num(1.0, 0.0, 10.0, "match_loop: search half-width in x and y [m]")
    match_loop_theta: float = _num(0.15, 0.0, math.pi, "match_loop: search half-width in heading [rad]")
    loop_spread: bool = field(default=False, metadata={
        "doc": "match_loop (nothing without it): a loop found is closed along the path: the best particle's jump "
               "spread back along its path since it was last at that place (as a traverse is adjusted), its map "
               "written again from the scans kept (9 bytes a beam per update) at the new poses, and every particle "
               "takes that path and map"})
    loop_spread_radius: float = _num(3.0, 0.0, 100.0, "loop_spread: the path's pose nearest the place found lies "
                                     "within this [m], and the path between came no nearer a place seen before "
                                     "it (else the jump stays)")
    loop_spread_recent: float = _num(20.0, 0.0, 10000.0, "loop_spread: the loop's start is sought more than this "
                                     "travel [m] before the jump (and an inner loop's return, as far)")
    path_match_scale: float = _num(0.0, 0.0, 1000.0, "published paths (scan_match): each particle's last path "
                                   "pose moved by the odometry (track_scans: the tracked motion), corrected by its "
                                   "match with the ICP's information scaled by this (ICP counts every end point as "
                                   "independent); 0 = the match as is")
    match_gate: float = _num(0.0, 0.0, 100.0, "distrust a match farther from the noise-free motion prediction than "
                             "this many std-devs of the motion model (match_prior: motion); 0 = off")
    track_scans: bool = field(default=False, metadata={
        "doc": "proposal: scan_match: between updates, match each scan against the best particle's map (no map "
               "write, no resampling): map->odom and trajectory_scans follow the scans, not the raw odometry"})
    track_search: builtins.str = _choice("refine", ("refine", "search"),
                                         "track_scans: refine: ICP from the odometry's prediction only; search: "
                                         "the whole matcher (window round the prediction, then ICP)")
    track_beams: int = _num(60, 4, 10000, "track_scans: match with at most this many returns, evenly spread (one "
                            "map: more end points cost little and sharpen the pose)")
    odom_scale: bool = field(default=False, metadata={
        "doc": "proposal: scan_match with match_refine: icp: learn how far the odometry misreads travel from the "
               "matches (where the scan pins the motion down) and move the particles by the odometry so scaled"})
    odom_scale_prior: float = _num(20.0, 0.0, 1e6, "odom_scale: odometry travel at scale 1 the estimate starts "
                                   "from [m]")
    # Update gating (improved mode); zeros process every scan as the assignment does
    linear_update: float = _num(0.0, 0.0, 100.0, "process a scan after this much travel [m]")
    angular_update: float = _num(0.0, 0.0, 2 * math.pi, "... or this much rotation [rad]")
    temporal_update: float = _num(-1.0, -1.0, 3600.0, "... or this much time; < 0 disables [s]")

    def __post_init__(self) -> None:
        check_fields(self)
        if self.fov_min >= self.fov_max:
            raise ConfigError(f"fov_min={self.fov_min} must be less than fov_max={self.fov_max}")
        if self.l_min >= self.l_max:
            raise ConfigError(f"l_min={self.l_min} must be less than l_max={self.l_max}")
        for name in ("match_gate", "match_window", "match_recover", "match_loop"):
            if getattr(self, name) > 0 and self.match_prior != "motion":
                raise ConfigError(f"{name} needs match_prior=motion (it works round the noise-free prediction, "
                                  f"in the motion model's std-devs)")
        if self.match_short_free > 0 and self.match_max_free >= 1.0:
            raise ConfigError(f"match_short_free={self.match_short_free} needs match_max_free < 1 (the free-space "
                              f"check it relaxes)")
        if self.loop_spread and self.match_loop > 0 and self.weight_model != "likelihood":
            raise ConfigError("loop_spread needs weight_model=likelihood (it writes the maps again as that model's "
                              "updates do)")
        if self.track_scans and self.proposal != "scan_match":
            raise ConfigError("track_scans needs proposal=scan_match (it uses the scan matcher)")
        if 0 < self.mark_range <= self.max_range:
            raise ConfigError(f"mark_range={self.mark_range} must be 0 (off) or beyond max_range={self.max_range}")
        if self.mark_range > self.max_range and self.weight_model != "likelihood":
            raise ConfigError(f"mark_range={self.mark_range} needs weight_model=likelihood (the assignment's "
                              "expected ranges end at max_range)")
        if self.match_weight != "likelihood" and (self.weight_model != "likelihood" or self.proposal != "scan_match"):
            raise ConfigError(f"match_weight={self.match_weight} needs weight_model=likelihood and proposal=scan_match")
        if self.match_weight == "normaliser" and (self.match_refine != "icp" or self.match_prior != "motion"):
            raise ConfigError("match_weight=normaliser needs match_refine=icp (the ICP's information) and "
                              "match_prior=motion (the prior it integrates)")
        if self.match_spread == "match" and self.match_refine != "icp":
            raise ConfigError("match_spread=match needs match_refine=icp (the hill climb has no covariance)")
        icp_with_motion_prior = (self.proposal == "scan_match" and self.match_refine == "icp"
                                 and self.match_prior == "motion")
        for name, on, why in (("odom_scale", self.odom_scale,
                               "weighs the matches by the ICP's information against the motion prior"),
                              ("match_prior_bearing", self.match_prior_bearing > 0, "moves the ICP's motion prior")):
            if on and not icp_with_motion_prior:
                raise ConfigError(f"{name} needs proposal=scan_match, match_refine=icp and match_prior=motion (it "
                                  f"{why})")
        for name in ("map_width", "map_height"):
            if getattr(self, name) < 4 * self.map_resolution:
                raise ConfigError(f"{name}={getattr(self, name)} must be at least 4 cells of map_resolution")

    # Derived values, computed once
    @property
    def grid_shape(self) -> tuple[int, int]:
        """(H, W) cells of the initial grid."""
        return (int(round(self.map_height / self.map_resolution)),
                int(round(self.map_width / self.map_resolution)))

    @property
    def rng_seed(self) -> int | None:
        """The seed for numpy's default_rng: None (fresh entropy) for seed -1."""
        return None if self.seed < 0 else self.seed

    @property
    def motion_sigmas(self) -> NDArray[np.float64]:
        """(3,) additive noise std-devs, zero when the noise toggle is off."""
        return np.array([self.sigma_x, self.sigma_y, self.sigma_theta]) * float(self.toggle_noise)

    @classmethod
    def from_dict(cls, values: Mapping[builtins.str, Any], *, notices: list[builtins.str] | None = None) -> SlamConfig:
        """Build from a flat mapping; unknown keys and bad values raise ConfigError.

        slam_gmapping's parameter names are read as ours (translate_gmapping); each one
        read gives a one-line notice, appended to notices if given, else logged.
        """
        ours, said = translate_gmapping(values)
        if notices is not None:
            notices.extend(said)
        else:
            for line in said:
                log.warning(line)
        return cls(**coerce(cls, ours))

    @classmethod
    def from_yaml(cls, path: builtins.str | Path, overrides: Mapping[builtins.str, Any] | None = None, *,
                  notices: list[builtins.str] | None = None) -> SlamConfig:
        import yaml  # only file loading needs it

        try:
            data = yaml.safe_load(Path(path).read_text()) or {}
        except yaml.YAMLError as err:
            where = getattr(err, "problem_mark", None)
            line = f" line {where.line + 1}" if where is not None else ""
            raise ConfigError(f"{path}:{line}: not valid YAML ({getattr(err, 'problem', None) or err})") from None
        if not isinstance(data, dict):
            raise ConfigError(f"{path}: expected a mapping of parameters, got {type(data).__name__}")
        data.update(overrides or {})
        return cls.from_dict(data, notices=notices)

    def replace(self, **changes: Any) -> SlamConfig:
        return self.from_dict({**self.to_dict(), **changes})

    def to_dict(self) -> dict[builtins.str, Any]:
        return dataclasses.asdict(self)


def parse_override(text: str) -> tuple[str, Any]:
    """'key=value' from a command line, the value read as YAML (numbers, true, null)."""
    import yaml

    key, sep, value = text.partition("=")
    if not sep or not key:
        raise ConfigError(f"override '{text}' must look like key=value")
    return key.strip(), yaml.safe_load(value)


# slam_gmapping's names of parameters we have under another name (same unit unless a
# conversion is given). Its names that are ours too (particles, srr, srt, str, stt, the
# frames, map_update_interval, ...) need nothing.
GMAPPING_NAMES: dict[str, str] = {
    "delta": "map_resolution",
    "maxUrange": "max_range",
    "linearUpdate": "linear_update",
    "angularUpdate": "angular_update",
    "temporalUpdate": "temporal_update",
    "resampleThreshold": "resample_threshold",
    "lsigma": "likelihood_sigma",
    "lskip": "beam_step",            # gmapping skips lskip beams after each used one: k = lskip + 1
}
# gmapping's initial map extent (absolute, default -100..100 m); ours is centred on the start pose
GMAPPING_EXTENT = {"xmin": ("map_width", -100.0), "xmax": ("map_width", 100.0),
                   "ymin": ("map_height", -100.0), "ymax": ("map_height", 100.0)}
# gmapping's parameters without a counterpart: accepted and ignored, saying what is closest
GMAPPING_IGNORED: dict[str, str] = {
    "sigma": "the matcher has no end-point sigma; see likelihood_sigma",
    "kernelSize": "the matcher searches match_xy_range / match_theta_range",
    "lstep": "the matcher's steps follow match_xy_range", "astep": "the matcher's steps follow match_theta_range",
    "iterations": "the matcher refines with match_refine",
    "ogain": "see likelihood_gain (an exponent, not a divisor)",
    "minimumScore": "see match_min_score (a share of end points, not an absolute score)",
    "llsamplerange": "no likelihood sampling around the match", "llsamplestep": "no likelihood sampling",
    "lasamplerange": "no likelihood sampling", "lasamplestep": "no likelihood sampling",
    "maxRange": "readings at or past the laser's range_max are no-returns (no_return_range)",
    "throttle_scans": "see linear_update / angular_update / temporal_update",
    "occ_thresh": "the map is published as occupancy percentages (map_saver thresholds when saved)",
}


def translate_gmapping(values: Mapping[str, Any]) -> tuple[dict[str, Any], list[str]]:
    """values with slam_gmapping's parameter names replaced by ours (converted where the
    units differ) and its names without a counterpart removed; plus one notice per name
    read. A gmapping name and ours both given with different values is a ConfigError."""
    out = {k: v for k, v in values.items()
           if k not in GMAPPING_NAMES and k not in GMAPPING_EXTENT and k not in GMAPPING_IGNORED}
    notices: list[str] = []

    def put(ours: str, value: Any, said: str, why: str = "") -> None:
        if ours in values and values[ours] != value:
            raise ConfigError(f"{said} (slam_gmapping's) disagrees with {ours}={values[ours]!r}: give one of them")
        out[ours] = value
        notices.append(f"{said} (slam_gmapping's) read as {ours}={value!r}{why}")

    for name, ours in GMAPPING_NAMES.items():
        if name in values:
            v = values[name]
            if name == "lskip":
                if not (isinstance(v, int) and not isinstance(v, bool) and v >= 0):
                    raise ConfigError(f"lskip={v!r} must be an integer >= 0")
                put(ours, v + 1, f"lskip={v!r}", " (every (lskip + 1)-th beam)")
                continue
            put(ours, v, f"{name}={v!r}")
    for ours in ("map_width", "map_height"):
        names = [n for n, (o, _) in GMAPPING_EXTENT.items() if o == ours]
        if any(n in values for n in names):
            lo, hi = (values.get(n, GMAPPING_EXTENT[n][1]) for n in names)
            if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in (lo, hi)) or hi <= lo:
                raise ConfigError(f"{names[0]}={lo!r}, {names[1]}={hi!r}: need numbers with {names[0]} < {names[1]}")
            put(ours, float(hi - lo), f"{names[0]}={lo!r}, {names[1]}={hi!r}",
                f" ({names[1]} - {names[0]}: the grid starts centred on the robot and grows)")
    for name, hint in GMAPPING_IGNORED.items():
        if name in values:
            notices.append(f"{name}={values[name]!r} (slam_gmapping's) has no counterpart here and is ignored: {hint}")
    return out, notices
