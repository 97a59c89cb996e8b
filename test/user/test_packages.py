"""The package list installs every command the project calls: each one resolves to a
Debian package inside the dependency closure of scripts/debian-packages.txt, so a fresh
Debian 12 given that list (make setup) has them all."""
from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]

ROS_COMMANDS = re.compile(r"\b(rosrun|roslaunch|rostest|rosbag|rosservice|rostopic|rosparam|rosnode|roscore|rosmaster"
                          r"|catkin_make|catkin_find|rospack)\b")
ALWAYS = {"git", "make"}   # the Makefile and .ci run make; test/user exports the tracked files with git


def package_list() -> list[str]:
    lines = (REPO / "scripts" / "debian-packages.txt").read_text().splitlines()
    return [line.split()[0] for line in lines if line.strip() and not line.lstrip().startswith("#")]


def commands_called() -> set[str]:
    files = subprocess.run(["git", "-C", str(REPO), "ls-files", "*.sh", "*.py", "*.launch", "*.test", "Makefile",
                            ".ci"], capture_output=True, text=True, check=True).stdout.split()
    found = set(ALWAYS)
    for name in files:
        found |= set(ROS_COMMANDS.findall((REPO / name).read_text(errors="replace")))
    return found


def closure(packages: list[str]) -> set[str]:
    out = subprocess.run(["apt-cache", "depends", "--recurse", "--no-recommends", "--no-suggests", "--no-conflicts",
                          "--no-breaks", "--no-replaces", "--no-enhances", *packages],
                         capture_output=True, text=True, check=True).stdout
    return {line.strip() for line in out.splitlines() if line and not line.startswith(" ")}


def owner(command: str) -> str | None:
    path = shutil.which(command, path="/usr/bin:/bin:/usr/sbin:/sbin")
    if path is None:
        return None
    for candidate in (str(Path(path).resolve()), path, path.replace("/usr/bin/", "/bin/")):
        res = subprocess.run(["dpkg", "-S", candidate], capture_output=True, text=True)
        if res.returncode == 0:
            return res.stdout.split(":")[0]
    return "?"


def test_every_command_the_project_calls_comes_from_the_package_list():
    used = commands_called()
    assert {"rosrun", "roslaunch", "rostest", "rosbag", "catkin_make"} <= used
    have = closure(package_list())
    missing = []
    for cmd in sorted(used):
        pkg = owner(cmd)
        if pkg is None:
            missing.append(f"{cmd} (not installed here)")
        elif pkg not in have:
            missing.append(f"{cmd} (from Debian package {pkg})")
    assert not missing, f"called by the project, not installed by scripts/debian-packages.txt: {missing}"


def test_the_list_names_packages_debian_has():
    res = subprocess.run(["apt-cache", "show", "--no-all-versions", *package_list()], capture_output=True, text=True)
    assert res.returncode == 0, res.stderr
