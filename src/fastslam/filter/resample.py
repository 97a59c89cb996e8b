"""Low-variance resampling (Probabilistic Robotics, table 4.4) and its bookkeeping."""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


def low_variance_indices(weights: NDArray[np.float64], rng: np.random.Generator) -> NDArray[np.intp]:
    """Parent index of each of the N new particles: one u0 in [0, 1/N), u_j = u0 + j/N,
    a single walk of the cumulative weights."""
    n = len(weights)
    u = rng.uniform(0.0, 1.0 / n) + np.arange(n) / n
    c = np.cumsum(weights)
    c[-1] = 1.0  # rounding must not leave u_j past the end
    return np.searchsorted(c, u, side="right").astype(np.intp)


def neff(weights: NDArray[np.float64]) -> float:
    """Effective sample size 1 / sum(w^2) of normalised weights."""
    return float(1.0 / np.sum(np.square(weights)))


def entropy(weights: NDArray[np.float64]) -> float:
    """Entropy -sum(w ln w) of normalised weights [nat], slam_gmapping's ~entropy:
    0 when one particle holds all the weight, ln N when all weigh the same."""
    w = weights[weights > 0.0]
    return float(-np.sum(w * np.log(w)))


def slot_parents(indices: NDArray[np.intp]) -> NDArray[np.intp]:
    """Assigns the children of a resampling to slots so that maps move least.

    A parent with at least one child keeps its own slot for one of them; only the
    extra children are copied, into the slots of parents that left none. Returns
    parent (N,): the particle each slot now holds (identity where nothing moved).
    """
    n = len(indices)
    counts = np.bincount(indices, minlength=n)
    extra = np.repeat(np.arange(n), np.maximum(counts - 1, 0))
    parent = np.arange(n)
    parent[counts == 0] = extra
    return parent
