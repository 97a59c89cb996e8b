"""Each parameter has one home: its YAML file, which the typed config's defaults equal.

A key the typed config does not know, a default that disagrees with the YAML, a launch
file that overrides a YAML key with an argument left at its default, and a node reading
a parameter around its typed config all fail here.
"""
import dataclasses
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
import yaml

from assign5.params import NodeConfig, RelayConfig, ReportConfig
from assign5.replay import ReplayConfig
from assign5.teleop_node import TeleopConfig
from fastslam.config import SlamConfig
from fastslam.sim.robot import MAX_ANGULAR, MAX_LINEAR
from fastslam.sim.sim import SimConfig

# YAML file -> its typed config, and the fields a launch file sets instead (not user settings)
HOMES = {"config/slam.yaml": (SlamConfig, set()),
         "config/node.yaml": (NodeConfig, set()),
         "config/sim_burger.yaml": (SimConfig, {"worlds_dir"})}
PRESETS = ["config/burger.yaml", "config/real.yaml"]


def default(f: dataclasses.Field):
    return f.default_factory() if f.default is dataclasses.MISSING else f.default


@pytest.mark.parametrize("path", sorted(HOMES))
def test_the_yaml_holds_every_key_of_its_config_with_the_default_value(path):
    cls, set_by_launch = HOMES[path]
    data = yaml.safe_load(Path(path).read_text())
    fields = {f.name: f for f in dataclasses.fields(cls)}
    dead = sorted(set(data) - set(fields))
    assert not dead, f"{path}: keys no code reads: {dead}"
    missing = sorted(set(fields) - set(data) - set_by_launch)
    assert not missing, f"{path} lacks {missing}: the YAML is their one home"
    disagree = {k: (data[k], default(fields[k])) for k in data if data[k] != default(fields[k])}
    assert not disagree, f"{path} vs {cls.__name__} defaults (yaml, code): {disagree}"


@pytest.mark.parametrize("path", PRESETS)
def test_a_preset_names_only_core_keys(path):
    data = yaml.safe_load(Path(path).read_text())
    dead = sorted(set(data) - {f.name for f in dataclasses.fields(SlamConfig)})
    assert not dead, f"{path}: keys no code reads: {dead}"
    SlamConfig.from_yaml(path, notices=[])   # and valid


def test_the_burger_limits_have_one_home():
    sim = yaml.safe_load(Path("config/sim_burger.yaml").read_text())
    assert (sim["max_linear"], sim["max_angular"]) == (MAX_LINEAR, MAX_ANGULAR) == (0.22, 2.84)
    assert (TeleopConfig().max_linear, TeleopConfig().max_angular) == (MAX_LINEAR, MAX_ANGULAR)
    for path in list(Path("launch").glob("*.launch")) + list(Path("src").rglob("*.py")):
        if path == Path("src/fastslam/sim/robot.py"):
            continue  # their home in code
        text = path.read_text()
        assert "0.22" not in text and "2.84" not in text, f"{path} writes a burger limit again"


def launch_files():
    return sorted(Path("launch").glob("*.launch"))


def yaml_keys_loaded(node, args):
    keys = set()
    for r in node.iter("rosparam"):
        if r.get("command", "load") != "load":
            continue
        name = r.get("file")
        arg = re.fullmatch(r"\$\(arg (\w+)\)", name)
        if arg:  # a file chosen by an argument: its default, or every preset for config:=
            name = args.get(arg.group(1), "")
            names = ([f"config/{p}.yaml" for p in ("slam", "burger", "real")] if arg.group(1) == "config_file"
                     else [name])
        else:
            names = [name]
        for n in names:
            path = Path(re.sub(r"\$\(find assign5\)/", "", n))
            if path.is_file():
                keys |= set(yaml.safe_load(path.read_text()))
    return keys


@pytest.mark.parametrize("path", launch_files(), ids=lambda p: p.name)
def test_launch_arguments_override_a_yaml_key_only_when_given(path):
    root = ET.parse(path).getroot()
    args = {a.get("name"): a.get("default", a.get("value")) for a in root.iter("arg")}
    for node in root.iter("node"):
        keys = yaml_keys_loaded(node, args)
        for p in node.iter("param"):
            name = p.get("name")
            if name not in keys:
                continue
            used = re.fullmatch(r"\$\(arg (\w+)\)", p.get("value", ""))
            assert used, f"{path.name}: {name} is fixed over its YAML"
            arg = used.group(1)
            assert p.get("if") == f"$(eval arg('{arg}') != '')", f"{path.name}: {name} set even when {arg} is empty"
            assert args[arg] == "", (f"{path.name}: argument {arg} defaults to {args[arg]!r}, "
                                     f"overriding the YAML's {name}")


def test_launch_files_leave_use_sim_time_alone_unless_they_run_a_clock():
    # slam.launch (a node alone, for robots, bags and the simulator) sets it only when asked
    root = ET.parse("launch/slam.launch").getroot()
    (p,) = [p for p in root.iter("param") if p.get("name") == "/use_sim_time"]
    assert p.get("if") == "$(eval arg('use_sim_time') != '')"
    assert {a.get("name"): a.get("default") for a in root.iter("arg")}["use_sim_time"] == ""


def test_nodes_read_parameters_only_through_their_typed_config():
    offenders = []
    for path in sorted(Path("src").rglob("*.py")):
        if path.name == "params.py":
            continue
        for line in path.read_text().splitlines():
            if re.search(r"get_param\(\s*[\"']~[^\"']", line):   # one key, past the typed config
                offenders.append(f"{path}: {line.strip()}")
    assert not offenders, "\n".join(offenders)


@pytest.mark.parametrize("cls, bad, message", [
    (TeleopConfig, {"max_linear": -1.0}, "max_linear=-1.0 must be in [0.0, 10.0]"),
    (RelayConfig, {"odom_frme": "odom"}, "unknown parameter 'odom_frme'"),
    (ReportConfig, {}, "world_file='' must name the world's YAML file"),
    (ReplayConfig, {"bag": "x.bag", "rate": 0}, "rate=0.0 must be in [0.01, 1000.0]"),
    (ReplayConfig, {}, "bag='' must name a bag"),
])
def test_the_small_nodes_name_a_bad_parameter(cls, bad, message):
    from fastslam.fields import ConfigError, coerce

    with pytest.raises(ConfigError) as err:
        cls(**coerce(cls, bad))
    assert message in str(err.value)
