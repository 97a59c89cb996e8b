"""The SLAM node's ROS-free helpers."""
from __future__ import annotations

from pathlib import Path

import pytest

from assign5.params import NodeConfig
from assign5.slam_node import map_path


def test_map_file_default_lies_in_ros_home(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("ROS_HOME", str(tmp_path / "rh"))
    assert map_path(NodeConfig().map_file) == str(tmp_path / "rh" / "assign5_map")
    assert (tmp_path / "rh").is_dir()
    assert map_path("/abs/map") == "/abs/map"
    monkeypatch.setenv("HOME", str(tmp_path))
    assert map_path("~/maps/x") == str(tmp_path / "maps" / "x")
