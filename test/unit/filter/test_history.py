"""History: the particles' paths as an ancestry tree in arrays, pruned to living lineages."""
from __future__ import annotations

import numpy as np
import pytest

import fastslam.filter.history as history_module
from fastslam.config import SlamConfig
from fastslam.filter.history import History


def poses_of_step(k: int, n: int) -> np.ndarray:
    """(n, 3): slot j at x = 10 k + j, y = -k, theta = 0.01 j; every row tells its step and slot."""
    j = np.arange(n)
    return np.stack([10.0 * k + j, np.full(n, -float(k)), 0.01 * j], axis=1)


def naive_path(steps: list[np.ndarray], parents: list[np.ndarray], particle: int) -> np.ndarray:
    """(T, 4) the path by following parents back through every stored step, no pruning."""
    rows, j = [], particle
    for k in range(len(steps) - 1, -1, -1):
        rows.append((float(k), *steps[k][j]))
        j = int(parents[k][j])
    return np.array(rows[::-1])


def test_paths_follow_parents_through_resampling():
    h = History()
    h.append(0.0, poses_of_step(0, 3), np.arange(3))
    h.append(1.0, poses_of_step(1, 3), np.array([2, 2, 0]))   # slots 0, 1 from slot 2; slot 2 from slot 0
    h.append(2.0, poses_of_step(2, 3), np.array([1, 0, 0]))
    # slot 0: step 2 row 0 <- step 1 row 1 <- step 0 row 2
    np.testing.assert_array_equal(h.path(0), [[0.0, 2.0, 0.0, 0.02], [1.0, 11.0, -1.0, 0.01],
                                              [2.0, 20.0, -2.0, 0.0]])
    # slots 1 and 2: step 2 rows 1, 2 <- step 1 row 0 <- step 0 row 2
    np.testing.assert_array_equal(h.path(1)[:, 1], [2.0, 10.0, 21.0])
    np.testing.assert_array_equal(h.path(2)[:, 1], [2.0, 10.0, 22.0])
    assert len(h) == 3 and h.kept_rows == 9


def test_appended_poses_are_copied():
    h = History()
    poses = poses_of_step(0, 2)
    h.append(0.5, poses, np.arange(2))
    poses[:] = 99.0                                           # the filter moves its particles on
    np.testing.assert_array_equal(h.path(1), [[0.5, 1.0, 0.0, 0.01]])


def test_pruning_moves_the_shared_steps_into_the_trunk(monkeypatch):
    monkeypatch.setattr(history_module, "PRUNE_EVERY", 4)
    h = History()
    h.append(0.0, poses_of_step(0, 4), np.arange(4))
    for k in range(1, 3):
        h.append(float(k), poses_of_step(k, 4), np.zeros(4, dtype=np.intp))  # all descend from slot 0
    assert h.kept_rows == 12                                  # 3 steps x 4 slots: not pruned yet
    h.append(3.0, poses_of_step(3, 4), np.zeros(4, dtype=np.intp))
    # pruned at the 4th step: steps 0..2 keep only row 0 (the one lineage), in the trunk;
    # the newest step keeps its 4 slots
    assert h.kept_rows == 3 + 4 and len(h) == 4
    for j in range(4):
        np.testing.assert_array_equal(h.path(j), [[0.0, 0.0, 0.0, 0.0], [1.0, 10.0, -1.0, 0.0],
                                                  [2.0, 20.0, -2.0, 0.0], [3.0, 30.0 + j, -3.0, 0.01 * j]])


def test_pruning_keeps_every_living_lineage_of_random_resamplings(monkeypatch, rng):
    monkeypatch.setattr(history_module, "PRUNE_EVERY", 3)
    n, steps, parents = 6, [], []
    h = History()
    for k in range(50):
        parent = np.arange(n) if k == 0 else np.sort(rng.integers(0, n, n))  # some lineages die each step
        steps.append(poses_of_step(k, n))
        parents.append(parent)
        h.append(float(k), steps[-1], parent)
        for j in range(n):
            np.testing.assert_array_equal(h.path(j), naive_path(steps, parents, j))
    assert len(h) == 50
    assert h.kept_rows < 50 * n / 2                           # merged lineages are stored once


def test_pruned_history_keeps_every_living_particles_path(monkeypatch, loop, drifting, run_room):
    truth = loop(120)
    odom = drifting(truth)
    monkeypatch.setattr(history_module, "PRUNE_EVERY", 10**9)
    full = run_room(SlamConfig(particles=20, seed=1), truth, odom)
    paths = [full.trajectory(i) for i in range(20)]
    monkeypatch.setattr(history_module, "PRUNE_EVERY", 7)
    pruned = run_room(SlamConfig(particles=20, seed=1), truth, odom)
    for i in range(20):
        assert np.array_equal(pruned.trajectory(i), paths[i])
    rows = pruned.history.kept_rows
    assert rows < 0.3 * 120 * 20  # lineages merge: far fewer than N poses per update are kept


@pytest.mark.parametrize("n_steps", [0, 1])
def test_short_histories(n_steps):
    h = History()
    for k in range(n_steps):
        h.append(7.0, poses_of_step(k, 2), np.arange(2))
    assert len(h) == n_steps and h.path(1).shape == (n_steps, 4)


def test_a_path_from_a_row_on_and_the_settled_rows_never_change(monkeypatch):
    # the node keeps what it made of the settled rows and asks only for the rest
    monkeypatch.setattr(history_module, "PRUNE_EVERY", 4)
    rng = np.random.default_rng(3)
    h, steps, parents, kept = History(), [], [], []
    for k in range(40):
        parent = np.zeros(5, dtype=np.intp) if k % 7 == 0 else rng.integers(0, 5, 5).astype(np.intp)
        steps.append(poses_of_step(k, 5))
        parents.append(parent)
        h.append(float(k), steps[-1], parent)
        for j in range(5):
            full = naive_path(steps, parents, j)
            for start in (0, h.settled, h.settled + 1, len(full), len(full) + 3):
                np.testing.assert_array_equal(h.path(j, start), full[start:])
        kept.append((h.settled, h.path(0)[:h.settled].copy()))
    assert kept[-1][0] > 20                                       # pruning settled most of the path
    for settled, rows in kept:
        np.testing.assert_array_equal(h.path(4)[:settled], rows)  # settled rows are every lineage's, for good


def test_latest_is_every_slots_newest_pose_through_pruning(monkeypatch):
    monkeypatch.setattr(history_module, "PRUNE_EVERY", 4)
    h = History()
    assert h.latest is None
    for k in range(6):     # pruned at the 4th step: the newest keeps its slots
        h.append(float(k), poses_of_step(k, 4), np.zeros(4, dtype=np.intp))
        np.testing.assert_array_equal(h.latest, poses_of_step(k, 4))
        np.testing.assert_array_equal(h.latest, np.stack([h.path(j)[-1, 1:] for j in range(4)]))


def test_a_collapsed_history_is_one_path_whose_trunk_rows_can_be_rewritten():
    h = History()
    steps, parents = [], []
    for k, parent in enumerate([np.arange(3), np.array([2, 2, 0]), np.array([1, 0, 0])]):
        steps.append(poses_of_step(k, 3))
        parents.append(parent)
        h.append(float(k), steps[-1], parent)
    want = naive_path(steps, parents, 1)
    h.collapse(1)
    assert h.settled == 2 and h.kept_rows == 2 + 3          # the trunk, and the newest step's slots
    for slot in range(3):
        np.testing.assert_array_equal(h.path(slot), want)
    h.rewrite(1, np.array([[7.0, 8.0, 0.5]]))
    np.testing.assert_array_equal(h.path(2)[1], [1.0, 7.0, 8.0, 0.5])
    np.testing.assert_array_equal(h.path(2)[[0, 2]], want[[0, 2]])
    with pytest.raises(ValueError, match="not all in the trunk"):
        h.rewrite(1, np.zeros((2, 3)))                       # row 2 is the newest step's, not the trunk's
