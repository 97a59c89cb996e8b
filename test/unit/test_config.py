"""SlamConfig: the assignment's defaults, errors that name the parameter, derived values."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam.config import ConfigError, SlamConfig, parse_override


def test_yaml_defaults_are_the_assignment(repo_root):
    cfg = SlamConfig.from_yaml(repo_root / "config" / "slam.yaml")
    assert cfg.particles == 20
    assert cfg.map_resolution == 0.05
    assert (cfg.map_width, cfg.map_height) == (10.0, 10.0)
    assert cfg.grid_shape == (200, 200)
    assert cfg.weight_model == "assignment" and cfg.resample_threshold == 1.0
    assert cfg == SlamConfig()


@pytest.mark.parametrize("values, message", [
    ({"particles": 0}, "particles=0 must be in [1, 10000]"),
    ({"map_resolution": 0}, "map_resolution=0.0 must be in [0.005, 1.0]"),
    ({"sigma_x": -0.1}, "sigma_x=-0.1 must be in [0.0, 10.0]"),
    ({"map_width": 0.1}, "map_width=0.1 must be in [0.5, 2000.0]"),
    ({"map_width": 0.6, "map_resolution": 0.5}, "map_width=0.6 must be at least 4 cells"),
    ({"map_resolutoin": 0.1}, "unknown parameter 'map_resolutoin'"),
    ({"particles": 2.5}, "particles=2.5 must be an integer"),
    ({"weight_model": "gauss"}, "weight_model='gauss' must be one of assignment, likelihood"),
    ({"fov_min": 30, "fov_max": -30}, "fov_min=30.0 must be less than fov_max=-30.0"),
    ({"max_range": float("nan")}, "max_range=nan must be in"),
    ({"max_range": 20, "mark_range": 15, "weight_model": "likelihood"},
     "mark_range=15.0 must be 0 (off) or beyond max_range=20.0"),
    ({"max_range": 20, "mark_range": 30}, "mark_range=30.0 needs weight_model=likelihood"),
])
def test_bad_values_name_the_parameter(values, message):
    with pytest.raises(ConfigError) as err:
        SlamConfig.from_dict(values)
    assert message in str(err.value)


def test_yaml_that_is_not_a_mapping_is_an_error(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("- 1\n- 2\n")
    with pytest.raises(ConfigError, match="expected a mapping"):
        SlamConfig.from_yaml(path)


def test_overrides_and_replace():
    assert parse_override("particles=5") == ("particles", 5)
    assert parse_override("seed=null") == ("seed", None)
    cfg = SlamConfig().replace(particles=5, toggle_noise=False)
    assert cfg.particles == 5 and cfg.toggle_noise == 0
    assert list(cfg.motion_sigmas) == [0.0, 0.0, 0.0]
    with pytest.raises(ConfigError):
        parse_override("particles")


def test_slam_gmapping_names_are_read_as_ours_with_a_notice():
    notices = []
    cfg = SlamConfig.from_dict({"delta": 0.1, "maxUrange": 3.0, "linearUpdate": 1.0, "angularUpdate": 0.2,
                                "temporalUpdate": 0.5, "resampleThreshold": 0.5, "lsigma": 0.075, "lskip": 1,
                                "xmin": -10.0, "xmax": 10.0, "ymin": -5.0, "particles": 100, "srr": 0.01},
                               notices=notices)
    assert (cfg.map_resolution, cfg.max_range, cfg.linear_update, cfg.angular_update, cfg.temporal_update,
            cfg.resample_threshold, cfg.likelihood_sigma) == (0.1, 3.0, 1.0, 0.2, 0.5, 0.5, 0.075)
    assert cfg.beam_step == 2                 # lskip beams skipped after each used one
    assert cfg.map_width == 20.0              # xmax - xmin
    assert cfg.map_height == 105.0            # ymax left at gmapping's default 100
    assert cfg.particles == 100 and cfg.srr == 0.01   # the same names need nothing
    assert len(notices) == 10 and all("\n" not in n for n in notices)
    assert "delta=0.1 (slam_gmapping's) read as map_resolution=0.1" in notices
    assert "lskip=1 (slam_gmapping's) read as beam_step=2 (every (lskip + 1)-th beam)" in notices


def test_slam_gmapping_names_without_counterpart_are_ignored_with_a_hint():
    notices = []
    cfg = SlamConfig.from_dict({"ogain": 3.0, "minimumScore": 50, "kernelSize": 1}, notices=notices)
    assert cfg == SlamConfig()
    assert len(notices) == 3
    assert any(n.startswith("minimumScore=50 (slam_gmapping's) has no counterpart here and is ignored: "
                            "see match_min_score") for n in notices)


@pytest.mark.parametrize("values, message", [
    ({"delta": 0.1, "map_resolution": 0.05}, "delta=0.1 (slam_gmapping's) disagrees with map_resolution=0.05"),
    ({"xmin": 5.0, "xmax": -5.0}, "xmin=5.0, xmax=-5.0: need numbers with xmin < xmax"),
    ({"lskip": -1}, "lskip=-1 must be an integer >= 0"),
    ({"delta": 0.0}, "map_resolution=0.0 must be in [0.005, 1.0]"),
])
def test_bad_slam_gmapping_values_name_the_parameter(values, message):
    with pytest.raises(ConfigError) as err:
        SlamConfig.from_dict(values, notices=[])
    assert message in str(err.value)


def test_without_a_notice_list_the_notices_are_logged(caplog):
    with caplog.at_level("WARNING", logger="fastslam.config"):
        assert SlamConfig.from_dict({"delta": 0.1}).map_resolution == 0.1
    assert [r.getMessage() for r in caplog.records] == ["delta=0.1 (slam_gmapping's) read as map_resolution=0.1"]


def test_match_spread_needs_icp():
    with pytest.raises(ConfigError, match="match_spread"):
        SlamConfig(match_spread="match", match_refine="hill")


@pytest.mark.parametrize("name", ["match_gate", "match_window", "match_recover"])
def test_keys_in_motion_std_devs_need_the_motion_prior(name):
    with pytest.raises(ConfigError, match=f"{name} needs match_prior=motion"):
        SlamConfig(**{name: 3.0}, match_prior="window")
    assert getattr(SlamConfig(**{name: 3.0}, match_prior="motion"), name) == 3.0


def test_log_odds_steps_and_clamps_keep_their_signs():
    with pytest.raises(ConfigError, match=r"l_min=1.0 must be in \[-100.0, -1e-06\]"):
        SlamConfig(l_min=1.0)
    with pytest.raises(ConfigError, match=r"l_max=-1.0 must be in \[1e-06, 100.0\]"):
        SlamConfig(l_max=-1.0)
    with pytest.raises(ConfigError, match="l_free=0.4 must be in"):
        SlamConfig.from_dict({"l_free": 0.4})


def test_derived_values():
    cfg = SlamConfig(map_width=3.0, map_height=1.0, map_resolution=0.2, sigma_x=0.1, sigma_y=0.2, sigma_theta=0.3)
    assert cfg.grid_shape == (5, 15)                     # (H, W): 1.0 / 0.2 rows, 3.0 / 0.2 columns
    np.testing.assert_allclose(cfg.motion_sigmas, [0.1, 0.2, 0.3])
    np.testing.assert_array_equal(cfg.replace(toggle_noise=0).motion_sigmas, [0.0, 0.0, 0.0])
    assert SlamConfig(seed=-1).rng_seed is None and SlamConfig(seed=0).rng_seed == 0


def test_from_yaml_applies_overrides_and_to_dict_round_trips(tmp_path):
    path = tmp_path / "c.yaml"
    path.write_text("particles: 7\nmap_resolution: 0.1\n")
    cfg = SlamConfig.from_yaml(path, {"particles": 9, "seed": 3})
    assert (cfg.particles, cfg.map_resolution, cfg.seed) == (9, 0.1, 3)
    assert SlamConfig.from_dict(cfg.to_dict()) == cfg
    (tmp_path / "empty.yaml").write_text("")
    assert SlamConfig.from_yaml(tmp_path / "empty.yaml") == SlamConfig()


def test_override_values_are_read_as_yaml():
    assert parse_override("match_refine=icp") == ("match_refine", "icp")
    assert parse_override(" map_grow = false") == ("map_grow", False)
    assert parse_override("l_free=-0.5") == ("l_free", -0.5)
    with pytest.raises(ConfigError, match="key=value"):
        parse_override("=3")


def test_a_count_rejects_true_and_false_but_the_noise_switch_takes_them():
    # `particles:=true` on a roslaunch line used to become 1 particle, silently
    with pytest.raises(ConfigError, match="particles=True must be an integer, not true/false"):
        SlamConfig.from_dict({"particles": True})
    with pytest.raises(ConfigError, match="beam_step=False"):
        SlamConfig.from_dict({"beam_step": False})
    assert SlamConfig.from_dict({"toggle_noise": False}).toggle_noise == 0
    assert SlamConfig.from_dict({"toggle_noise": True}).toggle_noise == 1
