"""One new user's machine per test session: ~/assign5 from the tracked files, `make demo`
in it (which prepares it: make setup), then the README's "The assignment's way" up to
the first roslaunch: a plain catkin workspace in ~/catkin_ws holding a copy of the folder."""
from __future__ import annotations

import os
import re

import pytest
from usertools import README, UserMachine, readme_commands, shared_data, tracked_files


def assignment_block() -> list[str]:
    text = README.read_text()
    section = text[text.index("## The assignment's way"):]
    block = re.search(r"```bash\n(.*?)```", section, re.S).group(1)
    return [line for line in block.splitlines() if line.strip()]


@pytest.fixture(scope="session")
def machine(tmp_path_factory):
    home = tmp_path_factory.mktemp("home")
    m = UserMachine(home)
    tracked_files(m.clone)
    shared = shared_data()
    if shared is not None:  # the data lies beside the repository, as in CI
        os.symlink(shared, home / "shared")
    demo = m.run("make demo", cwd=m.clone, ros=False, timeout=1500)
    m.demo_output = demo.stdout
    m.demo_status = demo.returncode
    # "The assignment's way", up to its first roslaunch: copy, catkin_make, source
    steps = []
    for line in assignment_block():
        if line.startswith("roslaunch"):
            break
        steps.append(line)
    m.ws_steps = steps
    build = m.run("set -e\n" + "\n".join(steps), ros=False, timeout=900)
    assert build.returncode == 0, f"{steps} failed:\n{build.stdout[-3000:]}"
    assert (m.ws / "devel" / "setup.bash").is_file()
    yield m
    m.stop_all()


@pytest.fixture
def user(machine):
    """The machine, with a master port of its own for this test's graph."""
    machine.new_master()
    machine.env_extra = {}
    yield machine
    machine.stop_all()
    machine.started.clear()


def pytest_report_header(config):
    return f"README commands: {len(readme_commands())}"
