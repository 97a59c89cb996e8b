"""Teleop key logic (pure) and the refusal without a terminal."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from assign5.teleop_node import TeleopState, press, ramp, status_line, tick


def keys(seq: str, state: TeleopState | None = None) -> TeleopState:
    state = state or TeleopState()
    for k in seq:
        state, _ = press(state, k)
    return state


def test_steps_and_limits() -> None:
    s = keys("www")
    assert s.target_linear == pytest.approx(0.03) and s.presses == 3
    assert keys("xx").target_linear == pytest.approx(-0.02)
    assert keys("a" * 5 + "d").target_angular == pytest.approx(0.4)
    assert keys("w" * 40).target_linear == 0.22          # burger limit
    assert keys("d" * 40).target_angular == -2.84


def test_stop_and_quit_zero_everything() -> None:
    s = tick(keys("wwwa"))
    s, kind = press(s, " ")
    assert kind == "stop" and (s.target_linear, s.target_angular, s.linear, s.angular) == (0, 0, 0, 0)
    s, kind = press(keys("ww"), "s")
    assert kind == "stop" and s.target_linear == 0.0
    s, kind = press(keys("ww"), "\x03")
    assert kind == "quit" and s.linear == 0.0
    assert press(TeleopState(), "q") == (TeleopState(), "none")
    assert press(TeleopState(), "") == (TeleopState(), "none")


def test_ramp_moves_half_a_step_per_loop() -> None:
    assert ramp(0.0, 0.03, 0.005) == 0.005
    assert ramp(0.03, 0.0, 0.005) == pytest.approx(0.025)
    assert ramp(0.029, 0.03, 0.005) == 0.03
    s = keys("www")
    for _ in range(5):
        s = tick(s)
    assert s.linear == pytest.approx(0.025)
    s = tick(s)
    assert s.linear == pytest.approx(0.03)
    assert "linear vel 0.03" in status_line(s)


@pytest.mark.ros  # the executable imports rospy
def test_refuses_without_a_terminal(repo_root: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(repo_root / "src"))
    out = subprocess.run([sys.executable, str(repo_root / "src" / "teleop_key.py")], stdin=subprocess.DEVNULL,
                         capture_output=True, text=True, timeout=30, env=env)
    assert out.returncode != 0
    assert "not a terminal" in out.stderr
