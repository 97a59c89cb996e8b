"""The SLAM node's parameters: ROS-only settings in NodeConfig, the algorithm's in SlamConfig."""
from __future__ import annotations

from pathlib import Path

import pytest

from assign5.params import CORE_KEYS, NODE_KEYS, NodeConfig, map_path, split_params
from fastslam.config import ConfigError, SlamConfig


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


def test_numbers_and_flags_are_coerced_and_empty_params_give_the_defaults():
    node, core = split_params({"map_update_interval": 5, "save_on_exit": 1, "debug_maps": 2.0, "particles": 3.0})
    assert node.map_update_interval == 5.0 and node.save_on_exit is True and node.debug_maps == 2
    assert core.particles == 3 and type(core.particles) is int
    assert split_params({}) == (NodeConfig(), SlamConfig())


def test_every_key_has_one_home():
    assert not NODE_KEYS & CORE_KEYS
    assert {"scan_topic", "map_frame", "odom_timeout"} <= NODE_KEYS and "particles" in CORE_KEYS


def test_slam_gmapping_names_reach_the_node_and_the_core():
    notices: list[str] = []
    node, core = split_params({"delta": 0.1, "map_update_interval": 5.0, "throttle_scans": 1, "particles": 30},
                              notices)
    assert core.map_resolution == 0.1 and core.particles == 30 and node.map_update_interval == 5.0
    assert len(notices) == 2
    assert any(n.startswith("throttle_scans=1 (slam_gmapping's) has no counterpart") for n in notices)


def test_map_file_default_lies_in_ros_home(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("ROS_HOME", str(tmp_path / "rh"))
    assert map_path(NodeConfig().map_file) == str(tmp_path / "rh" / "assign5_map")
    assert (tmp_path / "rh").is_dir()
    assert map_path("/abs/map") == "/abs/map"
    monkeypatch.setenv("HOME", str(tmp_path))
    assert map_path("~/maps/x") == str(tmp_path / "maps" / "x")
    monkeypatch.delenv("ROS_HOME")
    assert map_path("m") == str(tmp_path / ".ros" / "m")     # rospkg's default


def test_a_configuration_too_large_for_the_memory_limit_is_a_parameter_error():
    big = {"particles": 200, "map_width": 400.0, "map_height": 400.0}
    with pytest.raises(ConfigError) as err:
        split_params({**big, "memory_limit_mb": 4096})
    assert str(err.value).startswith("memory_limit_mb: particles=200 maps of 400 x 400 m at map_resolution=0.05 m "
                                     "(8000 x 8000 cells) need 12208 MB, more than the limit leaves for maps")
    node, core = split_params({**big, "memory_limit_mb": 20000})
    assert node.memory_limit_mb == 20000.0 and core.particles == 200
    with pytest.raises(ConfigError, match=r"max_map_extent=300 must be at least map_width/map_height \(400 m\)"):
        split_params({**big, "memory_limit_mb": 20000, "max_map_extent": 300})


def test_the_core_rules_default_to_the_node_defaults():
    # the offline tool runs the frontend and the filter with their own defaults: the node's
    from fastslam.filter.budget import MAX_BEAMS, MAX_MAP_EXTENT
    from fastslam.filter.frontend import Frontend
    from fastslam.filter.slam import FastSlam

    node = NodeConfig()
    front = Frontend(FastSlam(SlamConfig(particles=1)))
    for key in ("odom_timeout", "odom_buffer", "max_odom_speed", "max_odom_jump", "reset_backwards", "max_beams"):
        assert getattr(front, key) == getattr(node, key), key
    assert (node.max_beams, node.max_map_extent, node.memory_limit_mb) == (MAX_BEAMS, MAX_MAP_EXTENT, 0.0)
