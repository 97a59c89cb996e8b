"""Which particle the filter publishes: its map, its path, map->odom.

With a scan-matching proposal every particle explains its scans about equally well,
and flattened likelihoods (likelihood_gain) change the weights little per update: the
particle of the highest weight is then close to a random pick among them, and on logs
without loops it was often one of the most drifted (docs/benchmarks.md, issue 16 round 9).
The weighted medoid of the particles' paths, the one whose path lies nearest the
others' in the weights' measure, is the particle set's robust centre: it equals the
heaviest particle when one holds nearly all the weight, and the consensus when none does.
The filter weighs each path by its weight since the start (FastSlam.path_log_w: the
log-weights carried through resampling, not reset there, as gmapping's weightSum), the
evidence for the whole trajectory: on the Orebro log a few particles kept the right
corridor after a 2.9 m step with a 5-sigma odometry error and only the path weights
knew them (ATE 0.35 m against the consensus' 8.1 m).
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


def pairwise_distances(xy: NDArray[np.float64]) -> NDArray[np.float64]:
    """(N, N) distances between the positions xy (N, 2)."""
    return np.hypot(xy[:, None, 0] - xy[None, :, 0], xy[:, None, 1] - xy[None, :, 1])


def weighted_medoid(apart: NDArray[np.float64], weights: NDArray[np.float64]) -> int:
    """The particle j minimising sum_i weights[i] * apart[i, j] (the first of equals).

    apart: (N, N) symmetric distances between the particles' paths (summed over their
    updates); weights: (N,) normalised weights.
    """
    return int(np.argmin(weights @ apart))
