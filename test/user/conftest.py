"""A new user's machine for the tests of test/user, one per test session: a home folder
holding the tracked files of this repository (``git archive``) as ``~/assign5``, `make demo`
in it (which prepares it: make setup), then the README's "The assignment's way" up to its
first roslaunch: a plain catkin workspace in ~/catkin_ws holding a copy of the folder. The
README's commands then run in bash exactly as written there, each ROS graph on a master of
its own.

The user's environment is this one minus anything ROS or this repository put in it: no
ROS variables, no PYTHONPATH, no .venv on PATH, no display. With --import-mode=importlib
nothing here is importable by name: the tests get it through the fixtures at the end.
"""
from __future__ import annotations

import os
import re
import shlex
import signal
import socket
import subprocess
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from types import SimpleNamespace
from typing import Any, Iterator

import pytest

REPO = Path(__file__).resolve().parents[2]
README = REPO / "README.md"
PROBE = Path(__file__).with_name("probe.py")
# what must never appear in the output of a command a user types
BAD_OUTPUT = re.compile(r"Traceback|cannot marshal|\[FATAL\]|ERROR|has died")
DROPPED_VARS = ("ROS_", "PYTHONPATH", "CMAKE_PREFIX_PATH", "LD_LIBRARY_PATH", "PKG_CONFIG_PATH", "DISPLAY",
                "VIRTUAL_ENV", "ASSIGN5_WS", "XDG_CACHE_HOME", "TEST_OUT", "ROSTESTS")


def readme_commands() -> list[str]:
    """Every command line of the README's bash blocks; also the ROS commands written in a
    comment (e.g. "#   roslaunch ... then, in another shell:   rosbag play ...")."""
    text = README.read_text()
    lines = []
    for block in re.findall(r"```bash\n(.*?)```", text, re.S):
        for line in block.replace("\\\n", " ").splitlines():   # a line continued with a backslash is one
            line = line.strip()
            if not line:
                continue
            if line.startswith("#"):
                lines += re.findall(r"\b((?:roslaunch|rosrun|rosbag) .+?)(?=\s{3,}|$)", line)
                continue
            lines.append(line)
    return [c for c in lines if c]


def command(line: str) -> str:
    """A README line without its trailing comment (what bash runs)."""
    return re.sub(r"\s+#\s.*$", "", line).strip()


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def user_path() -> str:
    venv = str(REPO / ".venv")
    return ":".join(p for p in os.environ.get("PATH", "/usr/bin:/bin").split(":") if p and not p.startswith(venv))


@dataclass
class Running:
    """A command started in its own process group, as in its own terminal."""

    proc: subprocess.Popen
    log: Path
    what: str
    pty: int | None = None   # the terminal's master side, when it has one

    def type(self, keys: bytes) -> None:
        assert self.pty is not None, f"`{self.what}` has no terminal"
        os.write(self.pty, keys)

    def expect(self, text: str, timeout: float) -> None:
        """Waits until text appears in the output."""
        wait_until(lambda: text in self.output() or self.proc.poll() is not None, timeout, what=repr(text))
        assert text in self.output(), f"`{self.what}` ended without printing {text!r}:\n{self.output()[-3000:]}"

    def output(self) -> str:
        return self.log.read_text(errors="replace")

    def interrupt(self, timeout: float = 60.0) -> int:
        """Ctrl-C (SIGINT to the process group), then wait; kills and fails after timeout."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGINT)
        return self.wait(timeout)

    def wait(self, timeout: float) -> int:
        try:
            return self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
            raise AssertionError(f"`{self.what}` did not end within {timeout:.0f} s; its output:\n"
                                 + self.output()[-3000:]) from None

    def kill(self) -> None:
        """Ctrl-C first (roslaunch then stops the nodes it started, each in a session of its
        own), SIGKILL to the group if it has not ended after 20 s."""
        if self.proc.poll() is None:
            try:
                os.killpg(self.proc.pid, signal.SIGINT)
                self.proc.wait(20)
            except (ProcessLookupError, subprocess.TimeoutExpired):
                try:
                    os.killpg(self.proc.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                self.proc.wait()


@dataclass
class UserMachine:
    home: Path
    port: int = 0
    env_extra: dict[str, str] = field(default_factory=dict)
    started: list[Running] = field(default_factory=list)
    demo_output: str = ""
    demo_status: int = -1
    ws_steps: list[str] = field(default_factory=list)
    logs: int = 0   # commands started so far: each has its own log

    @property
    def clone(self) -> Path:
        return self.home / "assign5"

    @property
    def ws(self) -> Path:
        return self.home / "catkin_ws"

    def env(self, **extra: str) -> dict:
        env = {k: v for k, v in os.environ.items() if not k.startswith(DROPPED_VARS)}
        env.update(HOME=str(self.home), PATH=user_path(), TERM="dumb", LANG="C.UTF-8")
        # pip may find no registry here (isolated test runs): make setup kept the wheels
        env["PIP_FIND_LINKS"] = " ".join(filter(None, (os.environ.get("PIP_FIND_LINKS"), str(wheelhouse()))))
        env["PIP_RETRIES"] = "0"
        if self.port:  # a master of its own, whatever else runs on this machine
            env["ROS_MASTER_URI"] = f"http://localhost:{self.port}"
        env.update(self.env_extra, **extra)
        return env

    def new_master(self) -> int:
        """A fresh master port for the next graph (roslaunch starts the master on it)."""
        self.port = free_port()
        return self.port

    def _script(self, line: str, ros: bool) -> str:
        # a terminal of the catkin route has the workspace sourced (the README says so)
        return (f"source {self.ws}/devel/setup.bash\n" if ros else "") + line + "\n"

    def run(self, line: str, cwd: Path | None = None, timeout: float = 120.0, ros: bool = True,
            **env: str) -> subprocess.CompletedProcess:
        """Runs line in bash and waits for it (no terminal)."""
        return subprocess.run(["bash", "-c", self._script(line, ros)], cwd=cwd or self.home, env=self.env(**env),
                              stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              text=True, timeout=timeout)

    def start(self, line: str, cwd: Path | None = None, ros: bool = True, tty: bool = False, **env: str) -> Running:
        """Starts line in bash in its own process group; tty: on a pseudo-terminal (returned as .pty)."""
        self.logs += 1
        log = Path(self.home, "logs", f"{self.logs:03d}.log")
        log.parent.mkdir(exist_ok=True)
        out = open(log, "wb", buffering=0)
        if tty:
            import pty

            master, slave = pty.openpty()
            kwargs = dict(stdin=slave, stdout=slave, stderr=slave)
        else:
            kwargs = dict(stdin=subprocess.DEVNULL, stdout=out, stderr=subprocess.STDOUT)
        proc = subprocess.Popen(["bash", "-c", self._script(line, ros)], cwd=cwd or self.home, env=self.env(**env),
                                start_new_session=True, **kwargs)
        run = Running(proc, log, line)
        if tty:
            os.close(slave)
            run.pty = master
            threading.Thread(target=_drain, args=(master, out), daemon=True).start()
        self.started.append(run)
        return run

    def probe(self, *args: str, timeout: float = 60.0) -> dict[str, Any]:
        """test/user/probe.py in the user's ROS environment; its JSON answer."""
        import json

        res = self.run(" ".join(["/usr/bin/python3", str(PROBE), *map(shlex.quote, args)]), timeout=timeout + 30)
        last = res.stdout.strip().splitlines()[-1:] or ["{}"]
        try:
            return json.loads(last[0])
        except ValueError:
            raise AssertionError(f"probe {args} failed:\n{res.stdout[-2000:]}") from None

    def stop_all(self) -> None:
        for r in self.started:
            r.kill()
        # what a killed roslaunch left (masters and nodes run in sessions of their own):
        # every process of this user's home folder, found by the HOME it was given
        mine = f"HOME={self.home}".encode()
        for pid in filter(str.isdigit, os.listdir("/proc")):
            try:
                with open(f"/proc/{pid}/environ", "rb") as f:
                    if mine in f.read().split(b"\0") and int(pid) != os.getpid():
                        os.kill(int(pid), signal.SIGKILL)
            except (OSError, ValueError):
                continue


def clean(output: str, what: str) -> None:
    """Fails naming the lines a user would read as errors."""
    bad = [line for line in output.splitlines() if BAD_OUTPUT.search(line)]
    assert not bad, f"`{what}` printed errors:\n" + "\n".join(bad[:10])


def tracked_files(dest: Path) -> None:
    """The tracked files of this repository, with their changes in the working tree (what a
    commit of the tree would hold), into dest: git stash create makes that commit object
    without touching the tree or the stash list."""
    rev = subprocess.run(["git", "-C", str(REPO), "stash", "create"], capture_output=True, text=True)
    if rev.returncode != 0:
        raise RuntimeError(f"{REPO} is not a git checkout: the user tests export its tracked files")
    dest.mkdir(parents=True)
    archive = subprocess.Popen(["git", "-C", str(REPO), "archive", rev.stdout.strip() or "HEAD"],
                               stdout=subprocess.PIPE)
    subprocess.run(["tar", "-x", "-C", str(dest)], stdin=archive.stdout, check=True)
    if archive.wait() != 0:
        raise RuntimeError("git archive failed")


def shared_data() -> Path | None:
    """../shared beside the repository (CI), or one level higher (a worktree in wt/)."""
    for cand in (REPO.parent / "shared", REPO.parent.parent / "shared"):
        if (cand / "data").is_dir():
            return cand
    return None


def wait_until(predicate, timeout: float, interval: float = 0.2, what: str = "condition"):
    """predicate() until it returns something true; fails after timeout (wall)."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        value = predicate()
        if value:
            return value
        time.sleep(interval)
    raise AssertionError(f"{what} not met within {timeout:.0f} s")




def _drain(fd: int, out) -> None:
    """Copies a terminal's output into the log until the terminal closes."""
    while True:
        try:
            chunk = os.read(fd, 4096)
        except OSError:
            return
        if not chunk:
            return
        out.write(chunk)


def wheelhouse() -> Path:
    """Where make setup keeps the requirements' wheels (beside its workspace)."""
    ws = subprocess.run(["bash", str(REPO / "scripts" / "ws.sh")], capture_output=True, text=True, check=True)
    return Path(ws.stdout.strip()).parent / "wheels"


def assignment_block() -> list[str]:
    text = README.read_text()
    section = text[text.index("## The assignment's way"):]
    block = re.search(r"```bash\n(.*?)```", section, re.S)
    assert block is not None, "README: no bash block under 'The assignment's way'"
    return [line for line in block.group(1).splitlines() if line.strip()]


@pytest.fixture
def readme() -> SimpleNamespace:
    """The README's commands: commands() every line, command(line) without its comment,
    assignment_block() the lines of "The assignment's way"; clean(output, what)."""
    return SimpleNamespace(commands=readme_commands, command=command, assignment_block=assignment_block,
                           clean=clean, path=README)


@pytest.fixture(scope="session")
def machine(tmp_path_factory: pytest.TempPathFactory) -> Iterator[UserMachine]:
    home = tmp_path_factory.mktemp("home")
    m = UserMachine(home)
    tracked_files(m.clone)
    shared = shared_data()
    if shared is not None:  # the data lies beside the repository, as in CI
        os.symlink(shared, home / "shared")
    demo = m.run("make demo", cwd=m.clone, ros=False, timeout=1500)
    m.demo_output, m.demo_status = demo.stdout, demo.returncode
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
def user(machine: UserMachine, readme: SimpleNamespace) -> Iterator[UserMachine]:
    """The machine, with a master port of its own for this test's graph."""
    machine.new_master()
    machine.env_extra = {}
    yield machine
    machine.stop_all()
    machine.started.clear()
