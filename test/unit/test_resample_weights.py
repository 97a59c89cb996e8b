import numpy as np
import pytest

from fastslam.resample import entropy, low_variance_indices, neff, slot_parents
from fastslam.weights import assignment_log_weights, normalise_log


def test_weight_by_hand():
    # d = [1, 2], z = [1, 1]: ||d - z|| = 1, w = 1 / 2
    log_w = assignment_log_weights(np.array([[1.0, 2.0]]), np.array([1.0, 1.0]), np.array([True, True]))
    assert np.exp(log_w[0]) == pytest.approx(0.5)


def test_invalid_beams_are_left_out_of_d_and_z():
    d = np.array([[1.0, 2.0, 9.0], [1.0, 1.0, 0.0]])
    z = np.array([1.0, 1.0, np.inf])
    w = np.exp(assignment_log_weights(d, z, np.array([True, True, False])))
    np.testing.assert_allclose(w, [0.5, 1.0])
    np.testing.assert_allclose(normalise_log(np.log(w)), [1 / 3, 2 / 3])


def test_normalise_is_uniform_when_nothing_is_finite():
    np.testing.assert_allclose(normalise_log(np.array([-np.inf, np.nan])), [0.5, 0.5])


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


def test_entropy_of_the_weights_by_hand():
    assert entropy(np.array([0.0, 1.0, 0.0])) == 0.0                 # one particle holds all
    assert entropy(np.full(4, 0.25)) == pytest.approx(np.log(4))    # uniform: ln N
    # 0.5 ln 2 + 2 * 0.25 ln 4 = 1.5 ln 2
    assert entropy(np.array([0.5, 0.25, 0.25])) == pytest.approx(1.5 * np.log(2))
