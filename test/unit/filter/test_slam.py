"""FastSlam: the assignment's algorithm end to end in the pillar room, the improved
mode's gating, adaptive resampling and map growth, and random input."""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from fastslam.config import SlamConfig
from fastslam.filter.resample import neff
from fastslam.filter.scan import Scan
from fastslam.filter.slam import FastSlam
from fastslam.geometry import compose, relative

ANGLES = np.radians(np.arange(360.0))
ANGLES_4 = np.radians(np.arange(0.0, 360.0, 4.0))  # the improved mode's tests: 90 beams


def in_start_frame(truth):
    return np.array([relative(truth[0], p) for p in truth])


def test_one_particle_noise_off_perfect_odometry_maps_the_room_exactly(loop, run_room):
    truth = loop(60)
    slam = run_room(SlamConfig(particles=1, toggle_noise=0, seed=0), truth, in_start_frame(truth), noise=0.0)
    occ = slam.best_occupancy()
    cells = np.argwhere(occ > 65)  # (iy, ix)
    world = slam.grid.cell_to_world(cells[:, ::-1])
    # back to the room's frame, where the walls are at +-2.5 m and the pillar at (1, 1)
    xy = compose(truth[0], np.c_[world, np.zeros(len(world))])[:, :2]
    wall = np.abs(np.maximum(np.abs(xy[:, 0]), np.abs(xy[:, 1])) - 2.5)
    pillar = np.abs(np.hypot(xy[:, 0] - 1, xy[:, 1] - 1) - 0.3)
    assert len(cells) > 300
    assert np.max(np.minimum(wall, pillar)) <= 0.05 * np.sqrt(2)


def test_filter_tracks_the_true_pose_despite_drifting_odometry(loop, drifting, run_room):
    truth = loop(120)
    odom = drifting(truth)
    ref = in_start_frame(truth)
    dead_reckoning = np.hypot(*(odom[-1, :2] - ref[-1, :2]))
    slam = run_room(SlamConfig(particles=20, seed=1, sigma_x=0.01, sigma_y=0.01, sigma_theta=0.01), truth, odom)
    est = slam.trajectory()
    err = np.hypot(est[:, 1] - ref[:, 0], est[:, 2] - ref[:, 1])
    # the assignment's flat weight halves the drift; it does not remove it
    assert dead_reckoning > 0.4
    assert err[-1] < 0.5 * dead_reckoning and np.sqrt(np.mean(err ** 2)) < 0.15


def test_same_seed_same_result_and_trajectory_survives_resampling(loop, drifting, run_room):
    truth = loop(30)
    odom = drifting(truth)
    a = run_room(SlamConfig(particles=10, seed=7), truth, odom)
    b = run_room(SlamConfig(particles=10, seed=7), truth, odom)
    assert np.array_equal(a.trajectory(), b.trajectory())
    assert all(np.array_equal(a.grid.particle_map(i), b.grid.particle_map(i)) for i in range(a.grid.particles))
    traj = a.trajectory()
    assert traj.shape == (30, 4)
    np.testing.assert_allclose(traj[-1, 1:], a.poses[a.best])
    assert np.all(np.diff(traj[:, 0]) > 0)


class _Recording(FastSlam):
    """FastSlam that keeps what each resampling saw: the paths' log-weights and the parents."""

    def _resample(self, w, n_eff):
        self.path_before = self.path_log_w.copy()
        resampled, parent = super()._resample(w, n_eff)
        self.parent = parent
        return resampled, parent


class _SeesMatches(FastSlam):
    """FastSlam that keeps every gated match its trusted particles were sampled round."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.matches = []

    def _sample_around(self, match):
        self.matches.append(match)
        super()._sample_around(match)


def test_the_medoid_particle_is_that_of_the_paths_through_resampling(loop, drifting, room_ranges):
    """best_particle medoid: the published particle minimises the sum of its path's
    distances to the others' (positions at every update, summed), each weighed by that
    path's weight since the start (log-weights carried through resampling, never reset)."""
    truth = loop(40)
    odom = drifting(truth)
    cfg = SlamConfig(particles=8, seed=3, motion_model="odometry", weight_model="likelihood",
                     likelihood_max_dist=0.15, resample_threshold=0.9, best_particle="medoid")
    slam, rng, resampled = _Recording(cfg), np.random.default_rng(0), 0
    for t, (pose, o) in enumerate(zip(truth, odom)):
        ranges = room_ranges(pose, ANGLES) + rng.normal(0, 0.01, 360)
        info = slam.step(o, Scan(ranges=ranges, angles=ANGLES, range_min=0.12, range_max=3.5, stamp=0.2 * t))
        resampled += info.resampled
        # the paths' weights: the parents' at a resampling (the current weights start again)
        np.testing.assert_array_equal(slam.path_log_w, slam.path_before[slam.parent])
        if info.resampled:
            np.testing.assert_array_equal(slam.log_w, np.zeros(8))
        paths = np.stack([slam.trajectory(i)[:, 1:3] for i in range(8)])          # (N, T, 2)
        apart = np.linalg.norm(paths[:, None] - paths[None, :], axis=3).sum(axis=2)
        path_w = np.exp(slam.path_log_w - slam.path_log_w.max())
        assert slam.best == int(np.argmin((path_w / path_w.sum()) @ apart))
    assert 0 < resampled < 40


def test_the_paths_weights_are_the_weights_until_a_resampling(loop, drifting, run_room):
    slam = run_room(SlamConfig(particles=6, seed=2, motion_model="odometry", weight_model="likelihood",
                               likelihood_max_dist=0.15, resample_threshold=0.0), loop(20), drifting(loop(20)))
    assert np.ptp(slam.log_w) > 1.0                  # weights that differ, never resampled
    np.testing.assert_allclose(slam.path_log_w, slam.log_w, atol=1e-9)


def test_mean_and_covariance_of_the_particles():
    slam = FastSlam(SlamConfig(particles=4, seed=0))
    slam.poses = np.array([[0, 0, np.pi - 0.1], [2, 0, -np.pi + 0.1], [0, 2, np.pi], [2, 2, np.pi]], float)
    mean = slam.mean_pose()
    np.testing.assert_allclose(mean[:2], [1, 1])
    assert abs(abs(mean[2]) - np.pi) < 1e-9
    cov = slam.covariance()
    assert cov[0, 0] == pytest.approx(1.0) and cov[2, 2] == pytest.approx(0.005)


def test_map_grows_when_the_robot_leaves_it_and_clips_when_growth_is_off():
    scan = Scan(ranges=np.full(360, 1.0), angles=ANGLES, range_min=0.12, range_max=3.5)
    slam = FastSlam(SlamConfig(particles=2, seed=0, toggle_noise=0))
    slam.step(np.zeros(3), scan)
    info = slam.step(np.array([4.0, 0.0, 0.0]), scan)
    assert info.grew and slam.grid.extent[2] > 4.0 + 3.5
    fixed = FastSlam(SlamConfig(particles=2, seed=0, toggle_noise=0, map_grow=False))
    fixed.step(np.zeros(3), scan)
    info = fixed.step(np.array([4.0, 0.0, 0.0]), scan)
    assert info.clipped and not info.grew and fixed.grid.shape == (200, 200)
    assert fixed.grid.values(np.arange(fixed.grid.particles), 100, 199).max() < 0  # the part inside was still mapped


def test_no_return_beams_clear_space_but_do_not_weigh():
    scan = Scan(ranges=np.full(360, np.inf), angles=ANGLES, range_min=0.12, range_max=3.5)
    slam = FastSlam(SlamConfig(particles=3, seed=0, no_return_range=1.0))
    slam.step(np.zeros(3), scan)
    row = slam.grid.particle_map(0)[100]
    assert np.all(row[103:120] < 0) and np.all(row[121:] == 0) and row[100:102].max() == 0
    assert np.all(slam.log_w == 0)


# -- the improved mode: log-weights carried over, Neff gating, update gating, growth ---------

def _filter(**kw) -> FastSlam:
    base = dict(particles=10, seed=0, motion_model="odometry", weight_model="likelihood")
    return FastSlam(SlamConfig(**{**base, **kw}))


@pytest.mark.parametrize("threshold, spread, expect", [(0.5, 0.1, False), (0.5, 3.0, True), (1.0, 0.0, True)])
def test_neff_gating_resamples_only_below_threshold(threshold, spread, expect):
    slam = _filter(resample_threshold=threshold)
    slam.log_w = -spread * np.arange(10.0)
    w = slam.weights
    before = slam.log_w.copy()
    assert (neff(w) < threshold * 10) == expect or threshold == 1.0
    assert slam._resample(w, neff(w))[0] == expect
    if expect:
        np.testing.assert_array_equal(slam.log_w, np.zeros(10))
    else:
        np.testing.assert_array_equal(slam.log_w, before)   # weights carry over


def test_weights_carry_over_between_updates_without_resampling(room_scan):
    slam = _filter(resample_threshold=0.01, particles=5, toggle_noise=0)
    slam.step(np.zeros(3), room_scan(np.zeros(3), ANGLES_4, 0.0))
    slam.log_w = np.log(np.array([0.1, 0.2, 0.3, 0.15, 0.25]))
    blind = Scan(ranges=np.full(len(ANGLES_4), np.inf), angles=ANGLES_4, range_min=0.12, range_max=3.5, stamp=0.1)
    info = slam.step(np.array([0.05, 0.0, 0.0]), blind)    # nothing to weigh with
    assert info.processed and not info.resampled
    np.testing.assert_allclose(slam.weights, [0.1, 0.2, 0.3, 0.15, 0.25])


def test_update_gating_processes_only_after_enough_motion(room_scan):
    slam = _filter(linear_update=0.5, angular_update=0.5, temporal_update=-1.0, toggle_noise=0)
    processed = []
    for i in range(8):
        pose = np.array([0.15 * i, 0.0, 0.0])
        processed.append(slam.step(pose, room_scan(pose, ANGLES_4, float(i))).processed)
    # first scan always; then every time odometry accumulated 0.5 m (0.6 m, 1.2 m)
    assert processed == [True, False, False, False, True, False, False, False]
    assert slam.poses[0] == pytest.approx([0.6, 0.0, 0.0])  # the skipped motion was not lost
    turn = slam.step(np.array([1.05, 0.0, 0.6]), room_scan(np.array([1.05, 0.0, 0.6]), ANGLES_4, 8.0))
    assert turn.processed                                   # 0.6 rad >= angular_update


def test_temporal_update_processes_a_still_robot(room_scan):
    slam = _filter(linear_update=0.5, angular_update=0.5, temporal_update=2.0)
    flags = [slam.step(np.zeros(3), room_scan(np.zeros(3), ANGLES_4, float(t))).processed for t in range(5)]
    assert flags == [True, False, True, False, True]


def test_filter_grows_the_map_instead_of_clipping(room_scan):
    slam = _filter(map_width=4.0, map_height=4.0, max_range=3.5, toggle_noise=0)
    grew = []
    for i in range(6):
        pose = np.array([0.5 * i, 0.0, 0.0])
        info = slam.step(pose, room_scan(pose, ANGLES_4, float(i)))
        grew.append(info.grew)
        assert not info.clipped
    assert any(grew)
    assert slam.grid.covers(2.5 - 3.5, -3.5, 2.5 + 3.5, 3.5)


# -- random scans and odometry never break the core: no exception, finite poses and weights --

reading = st.one_of(st.floats(allow_nan=True, allow_infinity=True, width=32),
                    st.floats(min_value=0.0, max_value=5.0))
coordinate = st.floats(min_value=-20.0, max_value=20.0)


@st.composite
def scans(draw):
    n = draw(st.integers(min_value=1, max_value=40))
    ranges = np.array(draw(st.lists(reading, min_size=n, max_size=n)), dtype=float)
    angle_min = draw(st.floats(min_value=-7.0, max_value=7.0))
    inc = draw(st.floats(min_value=-0.5, max_value=0.5).filter(lambda v: abs(v) > 1e-4))
    range_min = draw(st.floats(min_value=0.0, max_value=1.0))
    range_max = range_min + draw(st.floats(min_value=0.01, max_value=10.0))
    upside_down = draw(st.booleans())
    return Scan.from_laser(ranges, angle_min, inc, range_min, range_max,
                           mount=(0.1, -0.05, draw(st.floats(min_value=-4, max_value=4))),
                           upside_down=upside_down)


@settings(max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.lists(st.tuples(scans(), coordinate, coordinate, st.floats(min_value=-10, max_value=10)),
                min_size=1, max_size=6),
       st.sampled_from(["assignment", "odometry"]))
def test_core_survives_random_input(steps, motion_model):
    cfg = SlamConfig(particles=4, seed=0, map_width=4.0, map_height=4.0, max_range=3.0,
                     motion_model=motion_model)
    slam = FastSlam(cfg)
    for t, (scan, x, y, th) in enumerate(steps):
        scan = Scan(ranges=scan.ranges, angles=scan.angles, range_min=scan.range_min,
                    range_max=scan.range_max, mount=scan.mount, stamp=float(t))
        info = slam.step(np.array([x, y, th]), scan)
        assert info.processed
        assert np.all(np.isfinite(slam.poses))
        w = slam.weights
        assert np.all(np.isfinite(w)) and abs(w.sum() - 1.0) < 1e-9
        assert np.all(np.abs(slam.poses[:, 2]) <= np.pi)
    assert slam.trajectory().shape == (len(steps), 4)


def test_the_live_pose_between_updates_is_the_best_pose_moved_by_odometry(room_scan):
    slam = _filter(linear_update=0.5, angular_update=0.5, toggle_noise=0)
    slam.step(np.zeros(3), room_scan(np.zeros(3), ANGLES_4, 0.0))
    np.testing.assert_allclose(slam.live_pose, slam.poses[slam.best])
    slam.live_pose = np.array([1.0, 2.0, np.pi / 2])        # as if the map frame were turned
    info = slam.step(np.array([0.15, 0.0, 0.0]), room_scan(np.array([0.15, 0.0, 0.0]), ANGLES_4, 0.2))
    assert not info.processed
    np.testing.assert_allclose(slam.live_pose, [1.0, 2.15, np.pi / 2], atol=1e-12)  # 0.15 m ahead = +y


def _tracking(cls: type = FastSlam, **kw) -> FastSlam:
    """The improved mode in the pillar room, exact odometry up to the last scan, gating
    0.5 m: scans at -0.5 and 0 m are updates, the map is theirs."""
    base = dict(particles=3, seed=0, toggle_noise=0, motion_model="odometry", weight_model="likelihood",
                proposal="scan_match", match_prior="motion", match_window=3.0, match_gate=3.5,
                match_good_score=1.0, match_refine="icp", match_min_known=20, match_beams=90,
                linear_update=0.5, angular_update=0.5, track_scans=True, track_search="search")
    slam = cls(SlamConfig(**{**base, **kw}))
    return slam


def _map_two_scans(slam: FastSlam, room_scan) -> None:
    for i, x in enumerate((-0.5, 0.0)):
        pose = np.array([x, 0.0, 0.0])
        assert slam.step(pose, room_scan(pose, ANGLES, 0.2 * i)).processed


def test_paths_and_the_live_pose_take_the_matches_not_the_samples_round_them(room_scan):
    """The samples drawn round each trusted match spread the particles (and their maps);
    the paths and map->odom keep the match itself: the sample's noise would add to them."""
    slam = _tracking(_SeesMatches, particles=4, match_sigma_xy=0.03, match_sigma_theta=0.02, resample_threshold=0.0)
    _map_two_scans(slam, room_scan)
    pose = np.array([0.5, 0.0, 0.0])
    assert slam.step(pose, room_scan(pose, ANGLES, 0.4)).processed
    match = slam.matches[-1]
    assert match.trusted.all()
    for i in range(4):
        np.testing.assert_array_equal(slam.trajectory(i)[-1, 1:], match.poses[i])
    np.testing.assert_array_equal(slam.live_pose, match.poses[slam.best])
    assert np.abs(slam.poses[:, :2] - match.poses[:, :2]).max() > 0.01    # the particles: the samples


@pytest.mark.parametrize("scale", [1e-9, 1.0, 1000.0])
def test_path_match_scale_fuses_each_path_with_its_match(room_scan, scale):
    """path_match_scale: a path's next pose is its last one moved by the odometry, moved
    towards the particle's match by the ICP's information times the scale (tiny: the
    odometry; huge: the match); map->odom still takes the match."""
    slam = _tracking(_SeesMatches, particles=4, match_sigma_xy=0.03, match_sigma_theta=0.02, resample_threshold=0.0,
                     path_match_scale=scale)
    _map_two_scans(slam, room_scan)
    before = np.stack([slam.trajectory(i)[-1, 1:] for i in range(4)])
    pose = np.array([0.5, 0.0, 0.0])
    assert slam.step(pose, room_scan(pose, ANGLES, 0.4)).processed
    match = slam.matches[-1]
    assert match.trusted.all()
    after = np.stack([slam.trajectory(i)[-1, 1:] for i in range(4)])
    moved = compose(before, [0.5, 0.0, 0.0])                 # the odometry: 0.5 m straight on
    assert np.abs(moved - match.poses)[:, :2].max() > 0.01     # the two differ
    if scale == 1e-9:
        np.testing.assert_allclose(after, moved, atol=1e-6)
    elif scale == 1000.0:
        np.testing.assert_allclose(after, match.poses, atol=1e-5)
    else:
        assert (np.abs(after - moved).max(axis=1) > 1e-4).all()
        assert (np.abs(after - match.poses).max(axis=1) > 1e-4).all()
    np.testing.assert_array_equal(slam.live_pose, match.poses[slam.best])


@pytest.mark.parametrize("track", [True, False])
def test_path_match_scale_moves_the_paths_by_the_tracked_motion(room_scan, track):
    """With track_scans a path's next pose starts from its last one moved by the live
    pose's motion since the last update (matched at the scans between, the odometry's
    last step into this one), not by the odometry's: real odometry jitters by degrees."""
    slam = _tracking(particles=4, resample_threshold=0.0, path_match_scale=1e-9, track_scans=track,
                     track_search="refine")
    _map_two_scans(slam, room_scan)
    before = np.stack([slam.trajectory(i)[-1, 1:] for i in range(4)])
    # the odometry reads 4 cm too far at the scan between (tracked: 10 cm), then 40 cm more
    assert not slam.step(np.array([0.14, 0.0, 0.0]), room_scan(np.array([0.1, 0.0, 0.0]), ANGLES, 0.4)).processed
    assert slam.step(np.array([0.54, 0.0, 0.0]), room_scan(np.array([0.5, 0.0, 0.0]), ANGLES, 0.6)).processed
    after = np.stack([slam.trajectory(i)[-1, 1:] for i in range(4)])
    moved = relative(before, after)                           # each path's step (the same for all)
    if track:
        np.testing.assert_allclose(moved, np.tile([0.5, 0.0, 0.0], (4, 1)), atol=0.01)
    else:
        np.testing.assert_allclose(moved, np.tile([0.54, 0.0, 0.0], (4, 1)), atol=1e-6)


def test_path_match_scale_paths_follow_their_motion_when_no_match_is_trusted(room_scan):
    """An update where no particle's match is trusted: each path takes its own last pose
    moved by the odometry, not its particle's pose, which drew the motion model's noise."""
    slam = _tracking(particles=4, resample_threshold=0.0, path_match_scale=0.03, toggle_noise=1,
                     srr=0.2, srt=0.2, str=0.2, stt=0.2, match_recover=0)
    _map_two_scans(slam, room_scan)
    before = np.stack([slam.trajectory(i)[-1, 1:] for i in range(4)])
    pose = np.array([0.5, 0.0, 0.0])
    scan = room_scan(pose, ANGLES, 0.4)
    blind = dataclasses.replace(scan, ranges=np.full_like(scan.ranges, np.inf))   # no return: nothing to match
    info = slam.step(pose, blind)
    assert info.processed and info.matched == 0
    after = np.stack([slam.trajectory(i)[-1, 1:] for i in range(4)])
    np.testing.assert_allclose(relative(before, after), np.tile([0.5, 0.0, 0.0], (4, 1)), atol=1e-9)
    assert np.abs(relative(before, slam.poses) - [0.5, 0.0, 0.0]).max() > 0.01   # the particles: noisy


@pytest.mark.parametrize("search", ["search", "refine"])
def test_tracking_matches_the_scans_between_updates(room_scan, search):
    slam = _tracking(track_search=search)
    _map_two_scans(slam, room_scan)
    start = slam.poses[slam.best].copy()   # the pose its last scan was drawn into the map from
    truth = np.array([0.1, 0.0, 0.0])
    # odometry reads 4 cm too far (with 0.05 m floors: 0.8 std-devs of the motion model)
    info = slam.step(np.array([0.14, 0.0, 0.0]), room_scan(truth, ANGLES, 0.4))
    assert not info.processed
    moved = relative(start, slam.live_pose)
    assert abs(moved[0] - 0.1) < 0.01 and abs(moved[1]) < 0.01 and abs(moved[2]) < 0.005
    # untracked, the same scan gives the odometry
    plain = _tracking(track_scans=False)
    _map_two_scans(plain, room_scan)
    plain.step(np.array([0.14, 0.0, 0.0]), room_scan(truth, ANGLES, 0.4))
    assert relative(plain.trajectory()[-1, 1:], plain.live_pose)[0] == pytest.approx(0.14)


def test_tracking_skips_scans_after_less_motion_than_track_still(room_scan):
    from fastslam.filter.track import TRACK_STILL

    slam = _tracking(track_search="refine")
    _map_two_scans(slam, room_scan)
    start = slam.live_pose.copy()
    # the odometry creeps half a millimetre (under TRACK_STILL's 1 mm) while the robot stands:
    # not matched, the live pose follows the odometry
    assert TRACK_STILL[0] > 0.0005
    slam.step(np.array([0.0005, 0.0, 0.0]), room_scan(np.zeros(3), ANGLES, 0.4))
    np.testing.assert_allclose(relative(start, slam.live_pose), [0.0005, 0.0, 0.0], atol=1e-12)
    # 3 cm read, 1 cm driven (a slow move, not matched under round 9's 5 cm): matched, the scan
    # puts the pose within 8 mm of the truth (the odometry's is 2 cm off)
    slam.step(np.array([0.03, 0.0, 0.0]), room_scan(np.array([0.01, 0.0, 0.0]), ANGLES, 0.5))
    assert abs(relative(start, slam.live_pose)[0] - 0.01) < 0.008
    # 14 cm read, 10 cm driven: matched
    slam.step(np.array([0.14, 0.0, 0.0]), room_scan(np.array([0.1, 0.0, 0.0]), ANGLES, 0.6))
    assert abs(relative(start, slam.live_pose)[0] - 0.1) < 0.01


def test_tracking_follows_the_scans_while_the_odometry_stalls(room_scan):
    """CSAIL's odometry repeats its pose for scans while the robot turns: the tracker
    matches those scans round the last pose, and the odometry's catch-up step afterwards
    is not counted a second time."""
    from fastslam.filter.track import STALL_RANGE_CHANGE

    slam = _tracking(track_search="refine")
    _map_two_scans(slam, room_scan)
    start = slam.live_pose.copy()
    # standing: odometry and scan unchanged, no stall, nothing moves
    slam.step(np.zeros(3), room_scan(np.zeros(3), ANGLES, 0.3))
    assert slam.stalls == 0
    np.testing.assert_allclose(slam.live_pose, start, atol=1e-12)
    # turning 0.2 rad a scan while the odometry stays at 0
    for i, heading in enumerate((0.2, 0.4)):
        scan = room_scan(np.array([0.0, 0.0, heading]), ANGLES, 0.4 + 0.1 * i)
        last = room_scan(np.array([0.0, 0.0, heading - 0.2]), ANGLES)
        assert np.median(np.abs(scan.ranges - last.ranges)) > STALL_RANGE_CHANGE
        assert not slam.step(np.zeros(3), scan).processed
        assert abs(relative(start, slam.live_pose)[2] - heading) < 0.01
    assert slam.stalls == 2
    # the odometry catches up (0.45 rad, under angular_update) at a scan with no return: the live
    # pose is the prediction, the odometry's turn since the stall's start (counted twice: 0.85)
    blind = Scan(ranges=np.full(360, np.inf), angles=ANGLES, range_min=0.12, range_max=3.5, stamp=0.7)
    assert not slam.step(np.array([0.0, 0.0, 0.45]), blind).processed
    np.testing.assert_allclose(slam.live_pose, compose(start, [0.0, 0.0, 0.45]), atol=1e-9)


@pytest.mark.parametrize("search", ["search", "refine"])
def test_tracking_with_the_window_prior_matches_too(room_scan, search):
    # match_prior: window (the defaults' and burger's): a prior of half the search window round
    # the prediction; tracking once stopped here with an AssertionError (no motion prior)
    slam = _tracking(track_search=search, match_prior="window", match_window=0.0, match_gate=0.0,
                     match_xy_range=0.1, match_theta_range=0.05)
    _map_two_scans(slam, room_scan)
    start = slam.poses[slam.best].copy()   # the pose its last scan was drawn into the map from
    info = slam.step(np.array([0.14, 0.0, 0.0]), room_scan(np.array([0.1, 0.0, 0.0]), ANGLES, 0.4))
    assert not info.processed
    moved = relative(start, slam.live_pose)
    assert abs(moved[0] - 0.1) < 0.01 and abs(moved[1]) < 0.01 and abs(moved[2]) < 0.005


def test_tracking_keeps_the_motion_prediction_when_the_match_is_gated_or_blind(room_scan):
    # gate 0.5 std-devs: the match 4 cm (0.8 std-devs) from the prediction is not trusted
    slam = _tracking(match_gate=0.5)
    _map_two_scans(slam, room_scan)
    predicted = compose(slam.live_pose, [0.14, 0.0, 0.0])
    slam.step(np.array([0.14, 0.0, 0.0]), room_scan(np.array([0.1, 0.0, 0.0]), ANGLES, 0.4))
    np.testing.assert_allclose(slam.live_pose, predicted, atol=1e-12)
    # no returns: nothing to match, the prediction again
    blind = Scan(ranges=np.full(360, np.inf), angles=ANGLES, range_min=0.12, range_max=3.5, stamp=0.6)
    slam.step(np.array([0.2, 0.0, 0.0]), blind)
    np.testing.assert_allclose(slam.live_pose, compose(predicted, [0.06, 0.0, 0.0]), atol=1e-12)


def test_tracking_leaves_particles_maps_and_weights_alone(room_scan):
    slam = _tracking()
    _map_two_scans(slam, room_scan)
    def maps_of(s: FastSlam) -> np.ndarray:
        return np.stack([s.grid.particle_map(i) for i in range(s.grid.particles)])

    poses, maps, log_w = slam.poses.copy(), maps_of(slam), slam.log_w.copy()
    slam.step(np.array([0.14, 0.0, 0.0]), room_scan(np.array([0.1, 0.0, 0.0]), ANGLES, 0.4))
    np.testing.assert_array_equal(slam.poses, poses)
    np.testing.assert_array_equal(maps_of(slam), maps)
    np.testing.assert_array_equal(slam.log_w, log_w)
    # the next update starts from the particles' own poses: the odometry since the last update
    assert slam.step(np.array([0.5, 0.0, 0.0]), room_scan(np.array([0.5, 0.0, 0.0]), ANGLES, 0.6)).processed
    np.testing.assert_allclose(slam.live_pose, slam.trajectory()[-1, 1:])
