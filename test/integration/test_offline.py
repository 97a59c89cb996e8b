"""Offline replay of a bag equals the direct run, and the CLI writes its files."""
import json

import numpy as np

from fastslam import offline, simrun
from fastslam.config import SlamConfig
from fastslam.io.bag_reader import read_bag
from fastslam.io.bag_writer import write_bag
from fastslam.io.map_files import load_map
from fastslam.io.trajectory_files import read_trajectory
from fastslam.transforms import StaticTransform


def test_bag_replay_equals_the_direct_run(tmp_path, repo_root):
    cfg = SlamConfig.from_yaml(repo_root / "config" / "slam.yaml", {"seed": 3, "particles": 8})
    direct = simrun.run("room", cfg, seed=1, record=True, max_time=40.0)
    bag = tmp_path / "room.bag"
    write_bag(bag, direct.scans, direct.odoms,
              static_transforms=[StaticTransform.planar("base_footprint", "base_scan", x=-0.032, z=0.172)])
    data = read_bag(bag)
    assert (data.mount.x, data.mount.y, data.mount.yaw) == (-0.032, 0.0, 0.0)
    replay = offline.run_bag(data, cfg)
    assert replay.updates == direct.updates == len(direct.scans) > 150
    # Headings pass through quaternions in the bag: equal to the last bit or two.
    np.testing.assert_allclose(replay.slam.trajectory(), direct.slam.trajectory(), rtol=0, atol=1e-9)
    assert np.array_equal(replay.slam.grid.logodds, direct.slam.grid.logodds)


def test_cli_writes_map_trajectory_and_stats(tmp_path, capsys, repo_root):
    cfg = SlamConfig.from_yaml(repo_root / "config" / "slam.yaml", {"seed": 0, "particles": 4})
    direct = simrun.run("room", cfg, seed=0, record=True, max_time=10.0)
    bag = tmp_path / "short.bag"
    write_bag(bag, direct.scans, direct.odoms,
              static_transforms=[StaticTransform.planar("base_footprint", "base_scan", x=-0.032)])
    out = tmp_path / "out"
    assert offline.main([str(bag), "--out", str(out), "--set", "particles=4", "--seed", "0", "--quiet"]) == 0
    stats = json.loads((out / "stats.json").read_text())
    assert stats["scans"] == stats["updates"] == len(direct.scans)
    assert stats["peak_memory_mb"] > 0 and stats["ms_per_update_median"] > 0
    t, poses = read_trajectory(out / "trajectory.txt")
    np.testing.assert_allclose(np.c_[t, poses], direct.slam.trajectory())
    occ, res, origin = load_map(out / "map.yaml")
    assert res == 0.05 and occ.shape == direct.slam.grid.shape
    assert (out / "map.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "particles: 4" in (out / "config.yaml").read_text()

