"""The final path at every scan with hindsight: between two processed scans the motion
since the first (the scan matcher's or the odometry's) is bent to end at the second.

A pose between updates composes the motion since the last processed scan onto the
final particle's pose there; its error grows until the next processed scan, where the
particle's own pose is known again. The gap between where that motion leads and the
particle's next pose is spread along the way, in proportion to the distance travelled
(and turned), as a smoother would: each scan moves by its share of the correction.
The last step into the processed scan is the odometry's (the matcher does not track
processed scans), which jitters between scans (CSAIL: 2 degrees median): it counts
ODOM_STEP_WEIGHT times its length, so a jittery last step takes most of the gap itself.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from fastslam.geometry import compose, inverse, pose_exp, pose_log, relative

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray

ODOM_STEP_WEIGHT = 8.0   # the odometry's last step against the matcher's steps (CSAIL, ACES: 4-8 alike)
TURN_LENGTH = 0.3        # [m/rad] a turn counts as this much travel


def spread_gaps(poses: NDArray[np.float64], processed: NDArray[np.bool_], odom: NDArray[np.float64], *,
                odom_weight: float = ODOM_STEP_WEIGHT, turn_length: float = TURN_LENGTH) -> NDArray[np.float64]:
    """(S, 3) poses with each gap's error spread along it.

    Args:
        poses: (S, 3) the path at every scan: the final particle's pose at processed
            scans, the motion since the last one composed onto it elsewhere.
        processed: (S,) which scans were processed.
        odom: (S, 3) the odometry at every scan.
    Scans before the first or after the last processed scan keep their poses.
    """
    out = np.array(poses, dtype=np.float64)
    s = len(out)
    done = np.flatnonzero(processed)
    if s < 3 or len(done) < 2:
        return out
    # each step's length, i-1 -> i; into a processed scan: the odometry's, weighed
    step = relative(out[:-1], out[1:])
    odo = relative(odom[:-1], odom[1:])
    into = np.asarray(processed[1:], dtype=bool)
    step[into] = odo[into]
    length = np.hypot(step[:, 0], step[:, 1]) + turn_length * np.abs(step[:, 2])
    length[into] *= odom_weight
    run = np.concatenate([[0.0], np.cumsum(length)])          # run[i]: length from scan 0 to i
    # every scan between two processed ones, and the processed scans before (a) and after (b) it
    inside = np.flatnonzero(~np.asarray(processed, dtype=bool))
    inside = inside[(inside > done[0]) & (inside < done[-1])]
    after = np.searchsorted(done, inside)
    a, b = done[after - 1], done[after]
    # where the motion since a leads at b, and the correction that lands it on b's pose
    reached = compose(out[b - 1], odo[b - 1])
    fix = pose_log(compose(out[b], inverse(reached)))
    total = run[b] - run[a]
    share = (run[inside] - run[a]) / np.where(total > 0, total, 1.0)
    out[inside] = compose(pose_exp(share[:, None] * fix), out[inside])
    return out
