"""Offline replay of a bag equals the direct run, and the CLI writes its files."""
import json

import numpy as np
import pytest

from fastslam import offline, simrun
from fastslam.config import SlamConfig
from fastslam.eval.trajectory import ate, interpolate_poses
from fastslam.filter.grid import GridMaps
from fastslam.filter.slam import FastSlam
from fastslam.filter.tiles import TileMaps
from fastslam.geometry import relative
from fastslam.io.bag_reader import read_bag
from fastslam.io.bag_writer import write_bag
from fastslam.io.map_files import load_map
from fastslam.io.trajectory_files import read_trajectory
from fastslam.transforms import StaticTransform


# 30 Hz: every scan (5 Hz) has odometry of its own stamp; 29 Hz: most fall between two messages
@pytest.mark.parametrize("odom_rate", [30.0, 29.0])
def test_bag_replay_equals_the_direct_run(tmp_path, repo_root, odom_rate):
    cfg = SlamConfig.from_yaml(repo_root / "config" / "slam.yaml", {"seed": 3, "particles": 8})
    direct = simrun.run("room", cfg, seed=1, record=True, max_time=40.0, sim={"odom_rate": odom_rate})
    bag = tmp_path / "room.bag"
    write_bag(bag, direct.scans, direct.odoms,
              static_transforms=[StaticTransform.planar("base_footprint", "base_scan", x=-0.032, z=0.172)])
    data = read_bag(bag)
    assert (data.mount.x, data.mount.y, data.mount.yaw) == (-0.032, 0.0, 0.0)
    replay = offline.run_bag(data, cfg)
    assert replay.updates == direct.updates == len(direct.scans) > 150
    # Headings pass through quaternions in the bag: equal to the last bit or two.
    np.testing.assert_allclose(replay.slam.trajectory(), direct.slam.trajectory(), rtol=0, atol=1e-9)
    assert all(np.array_equal(replay.slam.grid.particle_map(i), direct.slam.grid.particle_map(i))
               for i in range(direct.slam.grid.particles))


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


def test_an_internal_error_is_one_line_exit_1_and_nothing_written(tmp_path, capsys, monkeypatch, repo_root):
    cfg = SlamConfig.from_yaml(repo_root / "config" / "slam.yaml", {"seed": 0, "particles": 2})
    direct = simrun.run("room", cfg, seed=0, record=True, max_time=3.0)
    bag = tmp_path / "short.bag"
    write_bag(bag, direct.scans, direct.odoms,
              static_transforms=[StaticTransform.planar("base_footprint", "base_scan", x=-0.032)])

    def broken(*_args, **_kw):
        raise AssertionError

    monkeypatch.setattr(offline, "run_bag", broken)
    out = tmp_path / "out"
    assert offline.main([str(bag), "--out", str(out), "--quiet"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "Traceback" not in err, err
    assert err.startswith("error: the run stopped on an internal error, nothing written: AssertionError (")
    assert not out.exists() and list(tmp_path.iterdir()) == [bag]


def test_saved_maps_are_the_same_with_dense_and_tiled_storage(tmp_path, monkeypatch, repo_root):
    # The tool's map files (map_server PGM + YAML, map.png) from the filter on shared
    # tiles equal, byte for byte, those of the dense grids the filter used to keep.
    cfg = SlamConfig.from_yaml(repo_root / "config" / "burger.yaml", {"seed": 0, "particles": 6})
    direct = simrun.run("room", cfg, seed=0, record=True, max_time=30.0)
    bag = tmp_path / "room.bag"
    write_bag(bag, direct.scans, direct.odoms,
              static_transforms=[StaticTransform.planar("base_footprint", "base_scan", x=-0.032)])
    files = {}
    for storage in (GridMaps, TileMaps):
        monkeypatch.setattr(FastSlam, "maps_type", storage)
        out = tmp_path / storage.__name__
        assert offline.main([str(bag), "--out", str(out), "--config", str(repo_root / "config" / "burger.yaml"),
                             "--set", "particles=6", "--seed", "0", "--quiet"]) == 0
        files[storage] = {name: (out / name).read_bytes() for name in ("map.pgm", "map.yaml", "map.png")}
    assert files[GridMaps] == files[TileMaps]
    occ, res, origin = load_map(tmp_path / "TileMaps" / "map.yaml")
    assert (occ != -1).sum() > 1000 and res == 0.05                      # a map, not an empty one


def _sim_bag(tmp_path, seconds: float):
    cfg = SlamConfig.from_yaml("config/slam.yaml", {"seed": 0, "particles": 4})
    direct = simrun.run("room", cfg, seed=0, record=True, max_time=seconds)
    bag = tmp_path / "sim.bag"
    write_bag(bag, direct.scans, direct.odoms,
              static_transforms=[StaticTransform.planar("base_footprint", "base_scan", x=-0.032)])
    return bag


def _odom_at(data, t):
    """The bag's odometry interpolated at times t, as the frontend does."""
    od = data.odom_poses()
    return interpolate_poses(od[:, 0], od[:, 1:], t)


def test_a_pose_for_every_scan_follows_odometry_between_updates(tmp_path):
    # One particle moved exactly by odometry (noise off, exact motion model), scans
    # processed only every 0.3 m or 0.3 rad: every pose written, at processed scans
    # or between them, must be the odometry at that scan (map frame = odom frame).
    bag = _sim_bag(tmp_path, 20.0)
    out = tmp_path / "out"
    sets = ["particles=1", "toggle_noise=0", "motion_model=odometry", "linear_update=0.3", "angular_update=0.3"]
    assert offline.main([str(bag), "--out", str(out), "--seed", "0", "--quiet",
                         *[a for s in sets for a in ("--set", s)]]) == 0
    data = read_bag(bag)
    stats = json.loads((out / "stats.json").read_text())
    assert stats["updates"] < stats["scans"] / 3          # gating left most scans unprocessed
    for name in ("trajectory_scans.txt", "live_poses.txt"):
        t, poses = read_trajectory(out / name)
        assert len(t) == stats["scans"] == len(data.scans)
        np.testing.assert_allclose(poses, _odom_at(data, t), rtol=0, atol=1e-9)
    t_proc, _ = read_trajectory(out / "trajectory.txt")
    assert len(t_proc) == stats["updates"]


def test_every_scan_pose_is_the_processed_pose_plus_odometry(tmp_path):
    bag = _sim_bag(tmp_path, 20.0)
    data = read_bag(bag)
    cfg = SlamConfig.from_yaml("config/real.yaml", {"seed": 1, "particles": 5, "linear_update": 0.2,
                                                    "angular_update": 0.3, "map_width": 10, "map_height": 10,
                                                    "track_scans": False})
    result = offline.run_bag(data, cfg)
    every, traj = result.scan_trajectory(), result.slam.trajectory()
    assert len(every) == len(data.scans) and 0 < len(traj) < len(every) / 2
    at = np.searchsorted(every[:, 0], traj[:, 0])
    np.testing.assert_array_equal(every[at], traj)          # processed scans: the trajectory itself
    # between processed scans the path moves exactly as odometry does
    odom = _odom_at(data, every[:, 0])
    gap = np.setdiff1d(np.arange(1, len(every)), at)
    np.testing.assert_allclose(relative(every[gap - 1, 1:], every[gap, 1:]),
                               relative(odom[gap - 1], odom[gap]), rtol=0, atol=1e-9)
    # live: at a processed scan the best particle of that moment, so the first agrees
    live = result.live_poses()
    np.testing.assert_array_equal(live[0], every[0])
    assert not np.allclose(live[:, 1:], every[:, 1:], atol=1e-6)  # not the same estimate (hindsight vs live)


def test_with_tracking_every_scan_pose_moves_as_the_tracked_live_pose(tmp_path):
    bag = _sim_bag(tmp_path, 20.0)
    data = read_bag(bag)
    cfg = SlamConfig.from_yaml("config/real.yaml", {"seed": 1, "particles": 5, "linear_update": 0.2,
                                                    "angular_update": 0.3, "map_width": 10, "map_height": 10})
    assert cfg.track_scans
    result = offline.run_bag(data, cfg)
    every, traj, live = result.scan_trajectory(), result.slam.trajectory(), result.live_poses()
    at = np.searchsorted(every[:, 0], traj[:, 0])
    np.testing.assert_array_equal(every[at], traj)          # processed scans: the trajectory itself
    gap = np.setdiff1d(np.arange(1, len(every)), at)
    # between processed scans: the live pose's motion (the matcher's), not the odometry's
    np.testing.assert_allclose(relative(every[gap - 1, 1:], every[gap, 1:]),
                               relative(live[gap - 1, 1:], live[gap, 1:]), rtol=0, atol=1e-9)
    odom = _odom_at(data, every[:, 0])
    step = relative(live[gap - 1, 1:], live[gap, 1:]) - relative(odom[gap - 1], odom[gap])
    assert np.abs(step[:, :2]).max() > 1e-3                 # the matches moved some of them


def test_the_smoothed_path_ends_each_gap_on_the_next_processed_pose_and_is_nearer_the_truth(tmp_path):
    # odometry only between updates (no tracking), 0.5 m gating: the motion since a processed
    # scan drifts until the next; the smoothed path bends it onto the particle's next pose
    sim = simrun.run("room", SlamConfig.from_yaml("config/slam.yaml", {"seed": 0, "particles": 4}), seed=0,
                     record=True, max_time=20.0)
    bag = write_bag(tmp_path / "sim.bag", sim.scans, sim.odoms,
                    static_transforms=[StaticTransform.planar("base_footprint", "base_scan", x=-0.032)])
    data = read_bag(bag)
    errors = []
    for seed in (0, 1, 2):
        cfg = SlamConfig.from_yaml("config/real.yaml", {"seed": seed, "particles": 5, "map_width": 10,
                                                        "map_height": 10, "track_scans": False})
        result = offline.run_bag(data, cfg)
        every, smooth, traj = result.scan_trajectory(), result.smoothed_trajectory(), result.slam.trajectory()
        assert 5 < len(traj) < len(every) / 4
        at = np.searchsorted(smooth[:, 0], traj[:, 0])
        np.testing.assert_array_equal(smooth[at], traj)          # processed scans: the trajectory itself
        np.testing.assert_array_equal(smooth[:, 0], every[:, 0])
        assert np.abs(smooth[:, 1:3] - every[:, 1:3]).max() > 1e-4  # the gaps moved
        truth = interpolate_poses(sim.truth[:, 0], sim.truth[:, 1:], every[:, 0])
        errors.append((ate(truth, every[:, 1:]), ate(truth, smooth[:, 1:])))
    before, after = np.array(errors).T          # seeds 0-2 measured: 4.3, 5.5, 4.3 mm -> 3.7, 5.0, 3.6 mm
    assert (after < before).all() and after.sum() < 0.9 * before.sum(), errors


def test_tum_format(tmp_path):
    bag = _sim_bag(tmp_path, 6.0)
    plain, tum = tmp_path / "plain", tmp_path / "tum"
    for out, extra in ((plain, []), (tum, ["--format", "tum"])):
        assert offline.main([str(bag), "--out", str(out), "--set", "particles=2", "--seed", "0", "--quiet",
                             *extra]) == 0
    for name in ("trajectory.txt", "trajectory_scans.txt", "trajectory_smoothed.txt", "live_poses.txt"):
        line = next(ln for ln in (tum / name).read_text().splitlines() if not ln.startswith("#"))
        assert len(line.split()) == 8
        t0, p0 = read_trajectory(plain / name)
        t1, p1 = read_trajectory(tum / name)
        np.testing.assert_array_equal(t0, t1)
        np.testing.assert_array_equal(p0[:, :2], p1[:, :2])
        np.testing.assert_allclose(np.cos(p0[:, 2] - p1[:, 2]), 1.0, rtol=0, atol=1e-12)


def test_reference_gives_ate_rpe_in_stats_error_png_and_the_evaluators_numbers(tmp_path, capsys):
    import math

    from PIL import Image

    from fastslam import evaluate
    from fastslam.io.bag_writer import BagWriter
    from fastslam.io.records import OdomRecord
    from fastslam.io.trajectory_files import write_trajectory

    cfg = SlamConfig.from_yaml("config/slam.yaml", {"seed": 0, "particles": 4})
    direct = simrun.run("room", cfg, seed=0, record=True, max_time=8.0)
    # the truth in a world frame of its own (turned and shifted), as the simulator's /ground_truth
    c, s = math.cos(0.8), math.sin(0.8)
    world = [OdomRecord(t, 3.0 + c * x - s * y, -1.0 + s * x + c * y, th + 0.8, frame_id="world")
             for t, x, y, th in direct.truth.tolist()]
    bag = tmp_path / "gt.bag"
    with BagWriter(bag) as w:
        w.static([StaticTransform.planar("base_footprint", "base_scan", x=-0.032)], t=direct.truth[0, 0])
        merged = sorted([*direct.odoms, *direct.scans], key=lambda r: r.t)
        for rec in merged:
            if isinstance(rec, OdomRecord):
                w.odom(rec)
            else:
                w.scan(rec)
        for g in world:
            w.odom(g, topic="/ground_truth")
    out = tmp_path / "out"
    assert offline.main([str(bag), "--out", str(out), "--seed", "0", "--set", "particles=4", "--quiet"]) == 0
    printed = capsys.readouterr().out
    acc = json.loads((out / "stats.json").read_text())["accuracy"]
    assert acc["reference"] == "gt.bag:/ground_truth" and acc["matched"] > 30
    assert f"ATE {acc['ate_rmse']:.3f} m" in printed
    assert 0 < acc["ate_rmse"] < 0.2            # the truth's own frame is aligned away
    # the same numbers as the evaluator on the same reference written to a file (the bag's
    # headings went through quaternions: equal to the last bits)
    gt = tmp_path / "gt.txt"
    write_trajectory(gt, [g.t for g in world], [[g.x, g.y, g.yaw] for g in world])
    assert evaluate.main([str(gt), str(out / "trajectory.txt"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == pytest.approx({k: v for k, v in acc.items() if k != "reference"},
                                                                rel=1e-9)
    with Image.open(out / "error.png") as img:
        assert img.format == "PNG" and img.size == (1100, 480)
    with Image.open(out / "map.png") as img:    # the reference drawn and in the legend
        assert np.all(np.asarray(img.convert("RGB")) == (0, 160, 0), axis=2).sum() > 60
    # --reference FILE instead of the topic: the same figures
    out2 = tmp_path / "out2"
    assert offline.main([str(bag), "--out", str(out2), "--seed", "0", "--set", "particles=4", "--quiet",
                         "--reference", str(gt)]) == 0
    acc2 = json.loads((out2 / "stats.json").read_text())["accuracy"]
    assert acc2.pop("reference") == str(gt) and acc2 == pytest.approx(
        {k: v for k, v in acc.items() if k != "reference"}, rel=1e-9)


def test_no_reference_no_accuracy_and_a_bad_reference_is_one_line(tmp_path, capsys):
    bag = _sim_bag(tmp_path, 3.0)
    out = tmp_path / "out"
    assert offline.main([str(bag), "--out", str(out), "--set", "particles=2", "--seed", "0", "--quiet"]) == 0
    assert "accuracy" not in json.loads((out / "stats.json").read_text()) and not (out / "error.png").exists()
    capsys.readouterr()
    assert offline.main([str(bag), "--out", str(tmp_path / "o2"), "--quiet", "--reference",
                         str(tmp_path / "none.txt")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: cannot read trajectory") and err.count("\n") == 1
    assert not (tmp_path / "o2").exists()
