"""Particle weights: the assignment's 1/(||d - z|| + 1) and a likelihood beam model,
both as log-weights so that weights can carry over between updates without underflow."""
from __future__ import annotations

import numpy as np
from numpy.typing import NDArray


def assignment_log_weights(expected: NDArray[np.float64], measured: NDArray[np.float64],
                           valid: NDArray[np.bool_]) -> NDArray[np.float64]:
    """log of 1/(||d - z|| + 1) per particle over the valid beams only.

    Args:
        expected: (N, M) expected ranges d from each particle's map [m].
        measured: (M,) measured ranges z [m].
        valid: (M,) beams that count; the others are left out of both d and z.
    """
    diff = np.where(valid, expected - measured, 0.0)
    return -np.log1p(np.sqrt(np.sum(diff * diff, axis=1)))


def likelihood_log_weights(distances: NDArray[np.float64], valid: NDArray[np.bool_],
                           sigma: float, max_dist: float, gain: float) -> NDArray[np.float64]:
    """Endpoint model: sum over valid beams of -dist^2 / (2 sigma^2), dist capped.

    Args:
        distances: (N, M) distance from each beam's end point to the nearest occupied
            cell of the particle's map [m] (capped: an unexplained beam costs a constant).
        valid: (M,) beams with a real return.
        gain: exponent on the whole likelihood (< 1 flattens it, gmapping's smoothing).
    """
    d = np.minimum(distances, max_dist)
    return gain * np.sum(np.where(valid, -0.5 * (d / sigma) ** 2, 0.0), axis=1)


def normalise_log(log_w: NDArray[np.float64]) -> NDArray[np.float64]:
    """Normalised weights from log-weights, subtracting the max before exp.

    Non-finite log-weights get weight 0; if none is finite the weights are uniform.
    """
    finite = np.isfinite(log_w)
    if not finite.any():
        return np.full(len(log_w), 1.0 / len(log_w))
    w = np.zeros(len(log_w))
    w[finite] = np.exp(log_w[finite] - log_w[finite].max())
    return w / w.sum()
