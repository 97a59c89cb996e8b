"""Low-variance resampling, the effective sample size, and slots that move least."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.filter.resample import entropy, low_variance_indices, neff, slot_parents


def test_style_guide_example_weights_0_1_0_resample_to_1_1_1():
    idx = low_variance_indices(np.array([0.0, 1.0, 0.0]), np.random.default_rng(0))
    assert list(idx) == [1, 1, 1]


class FixedU0:
    """A generator whose uniform draw is a given u0 (the one random number of the walk)."""

    def __init__(self, u0: float) -> None:
        self.u0 = u0

    def uniform(self, low: float, high: float) -> float:
        assert low == 0.0 and self.u0 < high
        return self.u0


def test_low_variance_walk_by_hand():
    # N = 4, w = (0.1, 0.4, 0.2, 0.3): cumulative 0.1, 0.5, 0.7, 1.0; u0 = 0.15:
    # u = 0.15, 0.4, 0.65, 0.9 fall in the intervals of particles 1, 1, 2, 3
    idx = low_variance_indices(np.array([0.1, 0.4, 0.2, 0.3]), FixedU0(0.15))
    assert list(idx) == [1, 1, 2, 3]
    idx = low_variance_indices(np.array([0.1, 0.4, 0.2, 0.3]), FixedU0(0.05))
    assert list(idx) == [0, 1, 2, 3]                       # u = 0.05, 0.3, 0.55, 0.8


def test_one_heavy_particle_takes_all():
    idx = low_variance_indices(np.array([0.0, 0.0, 1.0, 0.0]), np.random.default_rng(0))
    assert list(idx) == [2, 2, 2, 2]


def test_uniform_weights_keep_each_particle_once():
    for seed in range(5):
        idx = low_variance_indices(np.full(7, 1 / 7), np.random.default_rng(seed))
        assert sorted(idx) == list(range(7))


def test_counts_stay_within_one_of_n_times_w():
    rng = np.random.default_rng(3)
    for _ in range(50):
        w = rng.random(20)
        w /= w.sum()
        counts = np.bincount(low_variance_indices(w, rng), minlength=20)
        assert np.all(np.abs(counts - 20 * w) < 1.0 + 1e-9)


def test_slot_parents_move_only_extra_children():
    parent = slot_parents(np.array([0, 0, 0, 3]))
    # 0 and 3 keep their slots; slots 1 and 2 (no children) take the extra copies of 0
    assert list(parent) == [0, 0, 0, 3]
    parent = slot_parents(np.array([1, 1, 2, 3]))
    assert list(parent) == [1, 1, 2, 3]
    parent = slot_parents(np.array([2, 2, 3, 3]))
    assert sorted(parent) == [2, 2, 3, 3] and parent[2] == 2 and parent[3] == 3


def test_neff():
    assert neff(np.full(4, 0.25)) == pytest.approx(4.0)
    assert neff(np.array([1.0, 0, 0, 0])) == pytest.approx(1.0)
    assert neff(np.array([0.5, 0.25, 0.25])) == pytest.approx(1 / 0.375)   # 1 / (0.25 + 2 * 0.0625)


def test_entropy_of_the_weights_by_hand():
    assert entropy(np.array([0.0, 1.0, 0.0])) == 0.0                 # one particle holds all
    assert entropy(np.full(4, 0.25)) == pytest.approx(np.log(4))    # uniform: ln N
    # 0.5 ln 2 + 2 * 0.25 ln 4 = 1.5 ln 2
    assert entropy(np.array([0.5, 0.25, 0.25])) == pytest.approx(1.5 * np.log(2))
