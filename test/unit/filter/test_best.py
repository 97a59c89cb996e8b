"""Which particle is published: pairwise path distances and the weighted medoid, by hand."""
from __future__ import annotations

import numpy as np

from fastslam.filter.best import pairwise_distances, weighted_medoid


def test_pairwise_distances_by_hand():
    xy = np.array([[0.0, 0.0], [3.0, 4.0], [0.0, 1.0]])
    np.testing.assert_allclose(pairwise_distances(xy), [[0, 5, 1], [5, 0, np.hypot(3, 3)], [1, np.hypot(3, 3), 0]])


def test_the_medoid_is_the_consensus_not_the_heaviest():
    # three paths at x = 0, 1, 3: sums of weighted distances 0.35 * 1 + 0.45 * 3 = 1.70,
    # 0.2 * 1 + 0.45 * 2 = 1.10 and 0.2 * 3 + 0.35 * 2 = 1.30: the middle one, not the heaviest
    apart = pairwise_distances(np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0]]))
    w = np.array([0.2, 0.35, 0.45])
    assert weighted_medoid(apart, w) == 1
    assert int(np.argmax(w)) == 2


def test_a_particle_holding_the_weight_is_its_own_medoid():
    apart = pairwise_distances(np.array([[0.0, 0.0], [1.0, 0.0], [3.0, 0.0]]))
    assert weighted_medoid(apart, np.array([0.0, 0.0, 1.0])) == 2
    assert weighted_medoid(apart, np.array([0.98, 0.01, 0.01])) == 0
