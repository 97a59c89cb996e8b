"""ROS-free pieces the node relies on: parameter split, odometry buffer, metrics."""
import numpy as np
import pytest

from assign5.params import NodeConfig, split_params
from fastslam.config import ConfigError, SlamConfig
from fastslam.metrics import map_quality, trajectory_errors
from fastslam.odombuffer import OdomBuffer


def test_params_split_into_node_and_core():
    node, core = split_params({"particles": 7, "map_frame": "world", "map_update_interval": 1})
    assert core == SlamConfig(particles=7)
    assert node.map_frame == "world" and node.map_update_interval == 1.0


@pytest.mark.parametrize("params, message", [
    ({"particles": 0}, "particles=0 must be in [1, 10000]"),
    ({"map_resolution": -0.05}, "map_resolution=-0.05 must be in"),
    ({"transform_publish_period": -1.0}, "transform_publish_period=-1.0 must be in [0.0, 10.0]"),
    ({"odom_topic": ""}, "odom_topic='' must be a non-empty string"),
    ({"save_on_exit": "yes"}, "save_on_exit='yes' must be true or false"),
    ({"debug_maps": 1.5}, "debug_maps=1.5 must be an integer"),
    ({"scan_topik": "x"}, "unknown parameter 'scan_topik'"),
])
def test_bad_node_parameters_are_named(params, message):
    with pytest.raises(ConfigError) as err:
        split_params(params)
    assert message in str(err.value)


def test_node_defaults_are_valid_and_like_gmapping():
    cfg = NodeConfig()
    assert (cfg.map_frame, cfg.odom_frame, cfg.transform_publish_period) == ("map", "odom", 0.05)


def test_odom_buffer_interpolates_and_wraps_heading():
    buf = OdomBuffer(span=10.0)
    buf.add(1.0, np.array([0.0, 0.0, 3.1]))
    buf.add(2.0, np.array([1.0, 2.0, -3.1]))
    p = buf.at(1.5, 0.5)
    np.testing.assert_allclose(p[:2], [0.5, 1.0])
    assert abs(abs(p[2]) - np.pi) < 1e-9  # through +-pi, not through 0
    np.testing.assert_allclose(buf.at(2.3, 0.5), [1.0, 2.0, -3.1])
    assert buf.at(0.5, 0.5) is None and buf.at(2.6, 0.5) is None


def test_odom_buffer_forgets_old_samples_and_ignores_older_ones():
    buf = OdomBuffer(span=1.0)
    for t in np.arange(0.0, 3.01, 0.5):
        buf.add(t, np.array([t, 0.0, 0.0]))
    assert len(buf) == 3 and buf.at(1.0, 0.1) is None
    buf.add(0.1, np.array([9.0, 9.0, 0.0]))
    assert buf.latest[0] == 3.0


def test_trajectory_errors_against_interpolated_truth():
    truth = np.array([[0.0, 0, 0, 0], [1.0, 1, 0, 0], [2.0, 2, 0, 0]])
    est = np.array([[0.5, 0.5, 0.3, 0], [1.5, 1.5, -0.4, 0], [5.0, 0, 0, 0]])
    np.testing.assert_allclose(trajectory_errors(est, truth), [0.3, 0.4])


def test_map_quality_counts_recall_and_spurious_cells():
    occ = np.full((20, 20), 0, dtype=np.int8)
    occ[:, 15] = 100           # a wall at x in [1.5, 1.6), right where the truth is
    occ[2, 2] = 100            # one stray cell
    occ[:, :1] = -1            # never seen
    boundary = np.c_[np.full(200, 1.55), np.linspace(0.0, 1.999, 200)]
    q = map_quality(occ, 0.1, (0.0, 0.0), boundary)
    assert q["boundary_recall"] == 1.0 and q["observed_fraction"] == 1.0
    assert q["occupied_cells"] == 21 and q["spurious_fraction"] == pytest.approx(1 / 21)
    occ[:, 15] = 0             # the wall seen as free: observed, but missed
    assert map_quality(occ, 0.1, (0.0, 0.0), boundary)["boundary_recall"] == 0.0


def test_points_in_the_frame_of_a_pose():
    from fastslam.metrics import in_frame_of

    out = in_frame_of(np.array([1.0, 2.0, np.pi / 2]), np.array([[1.0, 3.0], [0.0, 2.0]]))
    np.testing.assert_allclose(out, [[1.0, 0.0], [0.0, 1.0]], atol=1e-12)


def test_slam_gmapping_names_reach_the_node_and_the_core():
    notices = []
    node, core = split_params({"delta": 0.1, "map_update_interval": 5.0, "throttle_scans": 1, "particles": 30},
                              notices)
    assert core.map_resolution == 0.1 and core.particles == 30 and node.map_update_interval == 5.0
    assert len(notices) == 2 and any(n.startswith("throttle_scans=1 (slam_gmapping's) has no counterpart") for n in notices)


def test_time_source_problems_are_named():
    from assign5.watchdog import clock_problem

    text = clock_problem(False, ["/simulator"], 0.0, 5.0)
    assert text.startswith("/clock is published (by /simulator) but this node runs on wall time")
    assert "use_sim_time:=true" in text
    assert clock_problem(True, [], 4.9, 5.0) is None       # a bag may start a moment later
    assert "nothing has published /clock for 5 s" in clock_problem(True, [], 5.0, 5.0)
    assert clock_problem(True, ["/play"], 60.0, 5.0) is None and clock_problem(False, [], 60.0, 5.0) is None


def test_a_silent_scan_topic_is_named_with_the_laser_topics_there_are():
    from assign5.watchdog import scan_problem

    text = scan_problem("/laser", 5.0, {"/scan": ["/simulator"], "/base_scan": []})
    assert text.startswith("no scan received on /laser for 5 s. LaserScan topics there are: "
                           "/base_scan (from nobody now); /scan (from /simulator).")
    assert "No topic carries sensor_msgs/LaserScan" in scan_problem("/scan", 5.0, {})


def test_map_file_default_lies_in_ros_home(monkeypatch, tmp_path):
    from assign5.slam_node import map_path

    monkeypatch.setenv("ROS_HOME", str(tmp_path / "rh"))
    assert map_path(NodeConfig().map_file) == str(tmp_path / "rh" / "assign5_map")
    assert (tmp_path / "rh").is_dir()
    assert map_path("/abs/map") == "/abs/map"
    monkeypatch.setenv("HOME", str(tmp_path))
    assert map_path("~/maps/x") == str(tmp_path / "maps" / "x")
