"""Tracking, and matching, weighing and writing the maps of some particles, in a second process
(filter/pipeline.py) gives the results of doing it all in this one, to the bit."""
import os

import numpy as np
import pytest

from fastslam import offline, simrun
from fastslam.config import SlamConfig
from fastslam.filter import pipeline, track
from fastslam.filter.pipeline import PipelinedTracker
from fastslam.io.bag_reader import read_bag
from fastslam.io.bag_writer import write_bag
from fastslam.transforms import StaticTransform


@pytest.fixture(scope="module")
def sim_bag(tmp_path_factory):
    direct = simrun.run("room", SlamConfig.from_yaml("config/slam.yaml", {"seed": 0, "particles": 4}), seed=0,
                        record=True, max_time=20.0)
    return write_bag(tmp_path_factory.mktemp("pipeline") / "sim.bag", direct.scans, direct.odoms,
                     static_transforms=[StaticTransform.planar("base_footprint", "base_scan", x=-0.032)])


@pytest.fixture(scope="module")
def sim_data(sim_bag):
    return read_bag(sim_bag)


@pytest.fixture(scope="module")
def cfg():
    # 0.2 m / 0.3 rad gating: a few scans tracked between updates
    return SlamConfig.from_yaml("config/real.yaml", {"seed": 1, "particles": 5, "linear_update": 0.2,
                                                     "angular_update": 0.3, "map_width": 10, "map_height": 10})


@pytest.fixture(scope="module")
def serial(sim_data, cfg):
    return offline.run_bag(sim_data, cfg)


def _assert_same(run, serial):
    np.testing.assert_array_equal(run.live_poses(), serial.live_poses())
    np.testing.assert_array_equal(run.scan_trajectory(), serial.scan_trajectory())
    np.testing.assert_array_equal(run.slam.trajectory(), serial.slam.trajectory())
    np.testing.assert_array_equal(run.slam.best_occupancy(), serial.slam.best_occupancy())
    assert run.slam.stalls == serial.slam.stalls


def test_the_second_process_tracks_every_scan_between_updates_to_the_same_bits(sim_data, cfg, serial):
    run = offline.run_bag(sim_data, cfg, pipeline=True)
    tracked = run.scans - run.updates
    assert tracked > 50 and run.slam.tracker.served == tracked and not run.events
    # how many depends on the time each process takes (not the results)
    assert run.slam.tracker.matched > 0 and run.slam.tracker.wrote > 0
    _assert_same(run, serial)
    # the poses between updates came from the matcher (not the odometry alone)
    assert not np.array_equal(serial.live_poses(), offline.run_bag(sim_data, cfg.replace(track_scans=False))
                              .live_poses())


def test_any_share_of_the_particles_matched_in_the_second_process_gives_the_same_bits(sim_data, cfg, serial,
                                                                                       monkeypatch):
    monkeypatch.setattr(PipelinedTracker, "share", lambda self, n: n - 1 - len(self._queued) % 3)
    monkeypatch.setattr(pipeline, "MAX_QUEUED", 2)   # and a wait after every second scan between updates
    run = offline.run_bag(sim_data, cfg, pipeline=True)
    assert run.slam.tracker.matched >= 2 * (run.updates - 1) and not run.events
    _assert_same(run, serial)


def test_any_share_of_the_particles_written_in_the_second_process_gives_the_same_bits(sim_data, cfg, serial,
                                                                                       monkeypatch):
    shares = []

    def share(self, n):
        shares.append(1 + len(shares) % (n - 1))
        return shares[-1]
    monkeypatch.setattr(PipelinedTracker, "write_share", share)
    run = offline.run_bag(sim_data, cfg, pipeline=True)
    assert run.slam.tracker.wrote == sum(shares) and set(shares) == {1, 2, 3, 4} and not run.events
    assert run.slam.tracker.short == 0
    _assert_same(run, serial)


def test_a_second_process_short_of_tiles_gives_its_writes_back_and_is_lent_more(sim_data, cfg, serial,
                                                                                 monkeypatch):
    monkeypatch.setattr(pipeline, "FIRST_LOAN", 1)
    run = offline.run_bag(sim_data, cfg, pipeline=True)
    tracker = run.slam.tracker
    assert tracker.short > 0 and tracker._lend > 1 and tracker.wrote > 0 and not run.events
    _assert_same(run, serial)


def test_a_process_killed_while_it_writes_leaves_the_results_as_they_were(sim_data, cfg, serial, monkeypatch):
    submit, calls = PipelinedTracker.submit_writes, []

    def submit_then_kill(self, *args):
        submit(self, *args)
        calls.append(1)
        if len(calls) == 5:      # the worker has the tiles lent and is told to write
            self._worker.kill()
            self._worker.join()
    monkeypatch.setattr(PipelinedTracker, "submit_writes", submit_then_kill)
    run = offline.run_bag(sim_data, cfg, pipeline=True)
    assert 0 < run.slam.tracker.wrote and any("tracking process" in e for e in run.events), run.events
    _assert_same(run, serial)
    pool = run.slam.grid.pool   # the tiles lent came back: every count adds up
    held = np.bincount(run.slam.grid.table.reshape(-1), minlength=pool.top)[1:pool.top]
    np.testing.assert_array_equal(pool.refs[1:pool.top], held)


def test_the_map_the_worker_tracks_against_stays_as_at_the_update_while_the_filter_writes(cfg):
    from fastslam.filter.slam import FastSlam
    from fastslam.filter.tiles import TileMaps
    maps = TileMaps(3, (32, 32), 0.1, (-1.6, -1.6), shared=True)
    maps.put(1, [3, 20], [4, 20], [9, 9])
    tracker = PipelinedTracker(cfg, FastSlam.track_params(cfg))
    try:
        tracker.start(np.zeros(3), np.zeros(3), np.ones(4), maps, 1)
        held = maps.table[1].copy()
        assert (maps.pool.refs[held[held > 0]] == 2).all()     # the particle's, and the worker's
        maps.put(1, [3, 3], [4, 5], [-5, 7])                       # the filter writes: a copy
        assert maps.values(1, [3, 3], [4, 5]).tolist() == [-5, 7]
        assert tracker.grid.values(0, [3, 3, 20], [4, 5, 20]).tolist() == [9, 0, 9]   # as at the update
        tracker.start(np.zeros(3), np.zeros(3), np.ones(4), maps, 0)  # the next update: let go
        table = maps.table.reshape(-1)
        np.testing.assert_array_equal(maps.pool.refs[1:maps.pool.top],
                                      np.bincount(table, minlength=maps.pool.top)[1:])
    finally:
        tracker.close()


def test_the_shares_time_each_process_s_own_work_not_its_wait_for_the_other(cfg, monkeypatch):
    import types

    from fastslam.filter.slam import FastSlam
    clock = [0.0]
    monkeypatch.setattr(pipeline, "time", types.SimpleNamespace(perf_counter=lambda: clock[0]))
    tracker = PipelinedTracker(cfg, FastSlam.track_params(cfg))
    part = (np.zeros((10, 3)),) + (None,) * 5

    def receive(kind):
        clock[0] = 9.0                      # the filter waits until the worker's answer comes
        return ("matched", part, 1.0, 4.0)  # it matched its 10 particles from 1 s to 4 s
    try:
        monkeypatch.setattr(tracker, "_receive", receive)
        assert tracker.share(30) == 10      # a third before anything is timed
        tracker._handed = (10, 0.0)
        clock[0] = 2.0                      # the filter matched its 20 in 2 s
        assert tracker.result(None, (), 1) is part
        assert tracker._per_particle == pytest.approx((0.1, 0.3))
        assert tracker.share(30) == 8       # 30 x 0.1 s over 0.1 + 0.3 s a particle: 7.5
        tracker._free_at = 10.4             # 1.4 s of scans still to track: 30 x 0.1 - 1.4 over 0.4 s
        assert tracker.share(30) == 4
    finally:
        tracker.close()


def test_a_killed_tracking_process_leaves_the_results_as_they_were(sim_data, cfg, serial, monkeypatch):
    start, starts = PipelinedTracker.start, []

    def start_then_kill(self, *args):
        start(self, *args)
        starts.append(self)
        if len(starts) == 6:      # the worker holds the map of update 6 and is sent the scans after it
            self._worker.kill()
            self._worker.join()
    monkeypatch.setattr(PipelinedTracker, "start", start_then_kill)
    run = offline.run_bag(sim_data, cfg, pipeline=True)
    assert 0 < run.slam.tracker.served < run.scans - run.updates
    assert any("tracked in this process" in e and "tracking process" in e for e in run.events), run.events
    _assert_same(run, serial)


def test_an_error_in_the_tracking_process_is_reported_and_its_scans_tracked_here(sim_data, cfg, serial,
                                                                                 monkeypatch):
    home, track_scan, calls = os.getpid(), track.Tracker.track, []

    def fails_in_the_worker(self, odom, scan):
        calls.append(1)
        if os.getpid() != home and len(calls) == 30:
            raise RuntimeError("broken on purpose")
        track_scan(self, odom, scan)
    monkeypatch.setattr(track.Tracker, "track", fails_in_the_worker)
    run = offline.run_bag(sim_data, cfg, pipeline=True)
    assert any("RuntimeError: broken on purpose" in e for e in run.events), run.events
    assert 0 < run.slam.tracker.served < run.scans - run.updates
    _assert_same(run, serial)


def test_the_command_uses_the_second_process_and_serial_writes_the_same_files(sim_bag, tmp_path, monkeypatch):
    import json

    bag = sim_bag
    monkeypatch.setattr(offline, "available", lambda: True)   # (a one-core machine would run serial)
    common = [str(bag), "--config", "config/real.yaml", "--seed", "1", "--quiet", "--set", "particles=5",
              "--set", "linear_update=0.2", "--set", "map_width=10", "--set", "map_height=10"]
    assert offline.main(common + ["--out", str(tmp_path / "two")]) == 0
    assert offline.main(common + ["--out", str(tmp_path / "one"), "--serial"]) == 0
    two, one = (json.loads((tmp_path / d / "stats.json").read_text()) for d in ("two", "one"))
    assert one["second_process"] is None
    worker = two["second_process"]
    assert worker["scans_tracked"] == two["scans"] - two["updates"] > 20 and worker["particles_matched"] > 0
    assert worker["particles_written"] > 0
    assert worker["failure"] == ""
    for name in ("trajectory.txt", "trajectory_scans.txt", "live_poses.txt", "trajectory_smoothed.txt", "map.pgm"):
        assert (tmp_path / "two" / name).read_bytes() == (tmp_path / "one" / name).read_bytes(), name


def test_dense_maps_cannot_be_shared_so_the_tracking_stays_here(sim_data, cfg, serial, monkeypatch):
    from fastslam.filter.grid import GridMaps
    from fastslam.filter.slam import FastSlam
    monkeypatch.setattr(FastSlam, "maps_type", GridMaps)
    run = offline.run_bag(sim_data, cfg, pipeline=True)
    assert run.slam.tracker.served == 0 and any("cannot be shared" in e for e in run.events), run.events
    np.testing.assert_allclose(run.live_poses(), serial.live_poses(), rtol=0, atol=1e-9)   # dense maps: the same
