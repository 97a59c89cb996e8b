"""The wheel odometry's scale in travel, learnt from the scan matches (odom_scale).

Real wheel odometry misreads travel by a steady factor (a wheel radius a little off):
our matched paths travel 2 % further than the CSAIL robot's odometry says, and 0.7-1 %
less than the ACES robot's. Along a corridor the scan cannot tell where the robot is,
so the matcher keeps it where odometry puts it, and 1 % becomes half a metre over a
40 m corridor: coming back, the old walls lie that far along from the new.

Each update, a match whose scan pins the motion down along its direction (the scan
holds MIN_SHARE of the information there; the odometry prior barely pulled it) says
how far the robot moved. The scale is the ratio of those matched travels to the
odometry's over the same updates,

    scale = (prior + sum matched travel) / (prior + sum odometry travel),

starting from `prior` metres at scale 1. A ratio of sums, not a least-squares fit:
odometry that lags the scans (CSAIL's heading) moves travel from one update to the
next, which a fit reads as a scale and a sum does not; and noise in the odometry's
steps does not shrink it. Rooms and corners count, corridors do not; matches that
found a place again beyond the gate (a loop, a recovery) are not motion and are
left out. Turns are not scaled: the scans see the heading everywhere, and CSAIL's
lagging heading made any fit of its turns meaningless (1.10 one way, 0.98 another).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fastslam.geometry import compose, relative

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


MAX_SCALE_ERROR = 0.2   # the estimate stays within 1 -+ this: beyond it the odometry is broken, not off
MIN_TRAVEL = 0.05       # [m] shorter steps say little of the scale
MIN_SHARE = 0.9         # a match counts where its scan holds this share of the information along its travel


class OdometryScale:
    """Running estimate of the factor the odometry's travel is off by."""

    def __init__(self, prior: float) -> None:
        """prior [m]: odometry travel at scale 1 the estimate starts from."""
        self._matched = self._odometry = float(prior)
        self.steps = 0   # updates that added to the estimate

    @property
    def travel(self) -> float:
        """The factor odometry travel is multiplied by."""
        if self._odometry == 0:   # nothing counted, no prior
            return 1.0
        return float(min(max(self._matched / self._odometry, 1.0 - MAX_SCALE_ERROR), 1.0 + MAX_SCALE_ERROR))

    def summary(self) -> dict[str, float | int]:
        """The estimate for stats.json: the factor and how many updates made it."""
        return {"travel": round(self.travel, 4), "updates": self.steps}

    def corrected(self, prev_odom: NDArray[np.float64], odom: NDArray[np.float64]) -> NDArray[np.float64]:
        """(3,) the odometry pose odom as if the step from prev_odom had been scaled."""
        step = relative(prev_odom, odom)
        step[:2] *= self.travel
        return compose(prev_odom, step)

    def observe(self, travel: float, before: NDArray[np.float64], matched: NDArray[np.float64],
                scan_information: NDArray[np.float64], prior_information: NDArray[np.float64]) -> None:
        """One update's matches of K particles.

        travel [m] (negative: reversing): the raw odometry step; before and matched (K, 3):
        each particle's pose at the last update and its match now; scan_information and
        prior_information (K, 3, 3): the match's information from the scan alone and from
        the motion prior.
        """
        if abs(travel) < MIN_TRAVEL:
            return
        way = matched[:, :2] - before[:, :2]
        length = np.hypot(way[:, 0], way[:, 1])
        ok = length > 0
        u = way[ok] / length[ok, None]                                         # (K', 2) direction of travel
        i_s = np.clip(np.einsum("ki,kij,kj->k", u, scan_information[ok, :2, :2], u), 0.0, None)
        i_p = np.einsum("ki,kij,kj->k", u, prior_information[ok, :2, :2], u)
        pinned = i_s >= MIN_SHARE * (i_s + i_p)
        if not pinned.any():
            return
        self._matched += float(np.mean(length[ok][pinned])) * np.sign(travel)
        self._odometry += travel
        self.steps += 1
