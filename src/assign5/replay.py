"""Plays a bag into slam.py and ends the launch when the bag is done (launch/replay.launch).

Waits until the bag's LaserScan topic has a subscriber, runs ``rosbag play --clock``
(the bag's /tf remapped to tf_in, see tf_relay), waits for the node to process what it
was sent (its last update, or a quiet spell), then ends the roslaunch that started it
as Ctrl-C would: every node shuts down cleanly and slam.py saves its map on exit. A
required ``rosbag play`` node would instead end the launch with a red "died" banner.
"""
from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field

from fastslam.fields import ConfigError, check_fields
from fastslam.fields import num as _num


@dataclass(frozen=True)
class ReplayConfig:
    """replay.py's private parameters."""

    bag: str = field(default="", metadata={"doc": "the bag; a relative path is taken from $PWD"})
    rate: float = _num(1.0, 0.01, 1000.0, "rosbag play rate")
    delay: float = _num(1.0, 0.0, 60.0, "rosbag play -d: seconds between advertising and playing [s]")
    settle: float = _num(3.0, 0.1, 600.0, "after the bag: end once the node made no update for this long [s]")
    wait_subscriber: float = _num(60.0, 0.0, 3600.0, "wait this long for a node to subscribe to the scans [s]")

    def __post_init__(self) -> None:
        check_fields(self)
        if not self.bag:
            raise ConfigError("bag='' must name a bag: roslaunch assign5 replay.launch bag:=FILE.bag")


def resolve(path: str, cwd: str | None = None) -> str:
    """path with ~ expanded, relative to cwd (default $PWD: where the user typed roslaunch)."""
    path = os.path.expanduser(path)
    return path if os.path.isabs(path) else os.path.join(cwd or os.environ.get("PWD") or os.getcwd(), path)


def end_launch(rospy, why: str) -> None:
    """Ends the roslaunch that started this node as Ctrl-C does; alone, just this node."""
    rospy.loginfo(f"replay: {why}")
    try:
        with open(f"/proc/{os.getppid()}/cmdline", "rb") as f:
            parent = f.read().split(b"\0")
    except OSError:
        parent = []
    if any(os.path.basename(a.decode(errors="replace")) == "roslaunch" for a in parent[:2]):
        os.kill(os.getppid(), signal.SIGINT)
    else:
        rospy.signal_shutdown(why)


def main() -> None:
    import rosbag
    import rosgraph
    import rospy
    from geometry_msgs.msg import PoseArray

    from . import params

    rospy.init_node("replay")
    cfg = params.read(ReplayConfig)
    bag = resolve(cfg.bag)
    if not os.path.isfile(bag):
        rospy.logerr(f"replay: no bag at {bag} (a relative bag:= is taken from the folder roslaunch ran in)")
        end_launch(rospy, "nothing to play")
        return
    try:
        with rosbag.Bag(bag) as b:
            end_stamp = b.get_end_time()
            topics = b.get_type_and_topic_info().topics
    except Exception as err:  # rosbag raises several kinds for a bad file
        rospy.logerr(f"replay: cannot read {bag}: {err}")
        end_launch(rospy, "nothing to play")
        return
    scans = sorted(t for t, info in topics.items() if info.msg_type == "sensor_msgs/LaserScan")

    updated = threading.Condition()
    last = {"stamp": 0.0, "wall": time.monotonic(), "updates": 0}

    def on_update(msg: PoseArray) -> None:
        with updated:
            last.update(stamp=msg.header.stamp.to_sec(), wall=time.monotonic(), updates=last["updates"] + 1)
            updated.notify_all()

    rospy.Subscriber("particles", PoseArray, on_update, queue_size=10)
    master = rosgraph.Master(rospy.get_name())
    deadline = time.monotonic() + cfg.wait_subscriber
    while scans and not rospy.is_shutdown() and time.monotonic() < deadline:
        subscribed = {t for t, nodes in master.getSystemState()[1] if nodes}
        if subscribed & set(scans):
            break
        time.sleep(0.1)
    else:
        if scans and not rospy.is_shutdown():
            rospy.logwarn(f"replay: nobody subscribed to {', '.join(scans)} within {cfg.wait_subscriber:.0f} s; "
                          "playing anyway")
    rospy.loginfo(f"replay: playing {bag} at rate {cfg.rate}")
    # its progress line, redrawn 100 times a second, only makes sense on a terminal
    quiet = [] if sys.stdout.isatty() else ["--quiet"]
    play = subprocess.Popen(["rosbag", "play", "--clock", *quiet, "-d", str(cfg.delay), "-r", str(cfg.rate), bag,
                             "/tf:=/tf_in"])
    play.wait()  # a Ctrl-C reaches it too (roslaunch signals the node's process group)
    if rospy.is_shutdown():
        return
    if play.returncode != 0:
        rospy.logerr(f"replay: rosbag play {bag} failed (exit code {play.returncode})")
        end_launch(rospy, "rosbag play failed")
        return
    with updated:  # the node's last update, or no update for settle seconds
        last["wall"] = max(last["wall"], time.monotonic())
        while not rospy.is_shutdown() and last["stamp"] < end_stamp - 1e-3:
            quiet_left = cfg.settle - (time.monotonic() - last["wall"])
            if quiet_left <= 0:
                break
            updated.wait(quiet_left)
        updates = last["updates"]
    end_launch(rospy, f"end of {os.path.basename(bag)} ({updates} updates seen); stopping, slam.py saves its map")
    rospy.spin()
