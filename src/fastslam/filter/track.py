"""The live pose between updates: what map->odom gives a user at every scan.

At an update the live pose is the best particle's. At each scan between, it moves by
the odometry since the last scan and (track_scans) is matched against the best
particle's map round that prediction, held to the gate like a proposal: no map write,
no weights. The map does not change between two updates, so the Tracker takes it at
the update (start) and keeps it until the next one.

filter/pipeline.py runs the same Tracker in a second process.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from fastslam.config import SlamConfig
from fastslam.filter.grid import GridMaps
from fastslam.filter.motion import odometry_std
from fastslam.filter.proposal import gate_match, match_request
from fastslam.filter.scan import Scan, select_beams
from fastslam.filter.trimmed import Writer
from fastslam.geometry import compose, relative, wrap_angle
from fastslam.match import MatchParams, match_poses, refine_poses
from fastslam.match.matcher import Helper

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray

# A robot whose odometry moved less than this since the last match stands and is not
# matched again; a slow one is. Skipping moves under 5 cm / 0.02 rad (round 9) cost every
# ACES seed 0-11 0.0013-0.0018 m and saved about 10 % of its time (docs/benchmarks.md round 30)
TRACK_STILL = (0.001, 0.0005)  # [m], [rad]
# A stalled odometry: its pose unchanged since the last scan while the scan changed
# (median range change over the returns of both). CSAIL's odometry repeats its pose for
# four scans while the robot turns (median change 0.11-0.38 m); standing robots: 0.0-0.1.
STALL_ODOM = 1e-6            # [m], [rad] "unchanged"
STALL_RANGE_CHANGE = 0.1     # [m]
STALL_STD = (0.05, 0.05, 0.15)   # [m], [m], [rad] the tracker's prior round the last pose in a stall


class Tracker:
    """The live pose (3,) and what moves it between updates, in this process."""

    shares_maps = False   # whether the filter's maps must live in memory other processes can map
    helper: Helper | None = None   # another process matching some particles (filter/pipeline.py)
    writer: Writer | None = None   # ... and writing the scan into some particles' maps

    def __init__(self, cfg: SlamConfig, params: MatchParams) -> None:
        self.cfg = cfg
        self.params = params       # the matcher's, on track_beams returns
        self.stalls = 0            # scans tracked with the odometry stalled, over every life
        # every pose the tracker took, in order, when a list (the offline tool's live poses: ticket)
        self.timeline: list[NDArray[np.float64]] | None = None
        self.clear()

    def clear(self) -> None:
        """Forgets the pose and the map (the filter's reset)."""
        self.pose = np.zeros(3)
        self.at_update = np.zeros(3)                           # the pose as the last update left it
        self.odom: NDArray[np.float64] | None = None           # odometry at the pose's scan
        self.match_odom: NDArray[np.float64] | None = None     # ... at its last match
        self.last_scan: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None  # (odometry, ranges)
        self.grid: GridMaps | None = None                      # the best particle's map since the update
        self._maps: tuple[GridMaps, int] | None = None         # ... as the particles' maps and the best's index
        self._log()

    def start(self, pose: NDArray[np.float64], odom: NDArray[np.float64], ranges: NDArray[np.float64],
              maps: GridMaps, best: int) -> None:
        """An update: the best particle's pose at odometry pose odom; the particles' maps, best's the one."""
        self.pose = pose.copy()
        self.at_update = pose.copy()
        self.odom = self.match_odom = odom
        self.last_scan = (odom, ranges)
        self.grid, self._maps = None, (maps, best)   # its view taken when a scan is matched
        self._log()

    def rebase(self, odom: NDArray[np.float64]) -> None:
        """Takes odom as the new reference without moving the pose (after a jump)."""
        self.odom = self.match_odom = odom
        self.last_scan = None

    def moved(self, odom: NDArray[np.float64]) -> NDArray[np.float64]:
        """(3,) the pose moved by the odometry since its last scan, to odometry pose odom."""
        assert self.odom is not None
        return compose(self.pose, relative(self.odom, odom))

    def motion_since_update(self, odom: NDArray[np.float64]) -> NDArray[np.float64]:
        """(3,) the pose's motion from the last update to odometry pose odom: matched at the
        scans between (track_scans), the odometry's last step into this one."""
        return relative(self.at_update, self.moved(odom))

    def settle(self) -> None:
        """Nothing outstanding in this process (filter/pipeline.py waits here)."""

    def track(self, odom: NDArray[np.float64], scan: Scan) -> None:
        """A scan between updates.

        A stalled odometry (stalled) is matched round the last pose with STALL_STD; the
        motion found is then taken as odometry the stall missed (the pose's odometry moves
        with it), so the odometry's catch-up step is not counted twice.
        """
        self._track(odom, scan)
        self.last_scan = (odom, scan.ranges)
        self._log()

    def _log(self) -> None:
        if self.timeline is not None:
            self.timeline.append(self.pose.copy())

    def ticket(self) -> int:
        """The index in timeline of the pose now (timeline a list)."""
        assert self.timeline is not None
        return len(self.timeline) - 1

    def state(self) -> dict[str, Any]:
        """The pose and what moves it (not the map): load() takes it back."""
        return {"pose": self.pose, "at_update": self.at_update, "odom": self.odom, "match_odom": self.match_odom,
                "last_scan": self.last_scan, "stalls": self.stalls}

    def load(self, state: dict[str, Any]) -> None:
        for key, value in state.items():
            setattr(self, key, value)

    def _track(self, odom: NDArray[np.float64], scan: Scan) -> None:
        cfg = self.cfg
        assert self.match_odom is not None and self.odom is not None
        stalled = cfg.track_scans and self.stalled(odom, scan)
        if stalled:   # round the last pose, its odometry kept (it moves with the match below)
            predicted = self.pose.copy()
        else:
            predicted = self.moved(odom)
            self.pose, self.odom = predicted, odom
        if not cfg.track_scans:
            return
        moved = float(np.hypot(*(odom[:2] - self.match_odom[:2])))
        if not stalled and moved < TRACK_STILL[0] and \
                abs(float(wrap_angle(odom[2] - self.match_odom[2]))) < TRACK_STILL[1]:
            return  # (nearly) standing: the last match, moved by the odometry, holds
        if stalled:
            std = np.array(STALL_STD)
        else:
            std = (np.asarray(cfg.motion_sigmas, dtype=np.float64) if cfg.motion_model == "assignment"
                   else odometry_std(self.match_odom, odom, (cfg.srr, cfg.srt, cfg.str, cfg.stt)))
            self.match_odom = odom
        one = predicted[None, :]
        start, params, prior = match_request(cfg, self.params, one, one, std)
        if self.grid is None:
            assert self._maps is not None
            self.grid = self._maps[0].view(self._maps[1])
        beams = select_beams(scan, cfg)
        found = (refine_poses(self.grid, start, beams, params, prior) if cfg.track_search == "refine"
                 else match_poses(self.grid, start, beams, params, prior=prior))
        match = gate_match(cfg, found, one, std)
        if match.trusted[0]:
            self.pose = match.poses[0]
            if stalled:
                self.stalls += 1
                self.odom = self.match_odom = compose(self.odom, relative(predicted, self.pose))

    def stalled(self, odom: NDArray[np.float64], scan: Scan) -> bool:
        """Whether the odometry is unchanged since the last scan while the scan changed."""
        if self.last_scan is None:
            return False
        last_odom, last_ranges = self.last_scan
        if len(last_ranges) != len(scan.ranges) or np.any(np.abs(odom - last_odom) > STALL_ODOM):
            return False
        both = ((scan.ranges > scan.range_min) & (scan.ranges < scan.range_max)
                & (last_ranges > scan.range_min) & (last_ranges < scan.range_max))
        return bool(both.any() and np.median(np.abs(scan.ranges[both] - last_ranges[both])) > STALL_RANGE_CHANGE)
