import pytest

from fastslam.config import ConfigError, SlamConfig, parse_override


def test_yaml_defaults_are_the_assignment(tmp_path):
    cfg = SlamConfig.from_yaml("config/slam.yaml")
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


def test_a_count_rejects_true_and_false_but_the_noise_switch_takes_them():
    # `particles:=true` on a roslaunch line used to become 1 particle, silently
    with pytest.raises(ConfigError, match="particles=True must be an integer, not true/false"):
        SlamConfig.from_dict({"particles": True})
    with pytest.raises(ConfigError, match="beam_step=False"):
        SlamConfig.from_dict({"beam_step": False})
    assert SlamConfig.from_dict({"toggle_noise": False}).toggle_noise == 0
    assert SlamConfig.from_dict({"toggle_noise": True}).toggle_noise == 1
