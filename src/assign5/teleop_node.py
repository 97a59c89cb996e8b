"""Keyboard teleop like turtlebot3_teleop_key: w/x, a/d step the target speeds, s/space stop.

The key -> command logic (``press``, ``ramp``) is pure and tested; ``TeleopNode`` only
owns the terminal and the publisher. A zero Twist is sent and the terminal restored on
every way out (CTRL-C, shutdown, error).
"""
from __future__ import annotations

import os
import select
import sys
import termios
from dataclasses import dataclass, replace

from fastslam.fields import check_fields
from fastslam.fields import num as _num
from fastslam.sim.robot import MAX_ANGULAR, MAX_LINEAR

LIN_STEP = 0.01   # [m/s] per w/x press
ANG_STEP = 0.1    # [rad/s] per a/d press
BANNER_EVERY = 20  # velocity keypresses between banner reprints

BANNER = """
Drive the TurtleBot3 burger (assign5)
---------------------------
Moving around:
        w
   a    s    d
        x

w/x : increase/decrease linear velocity  (burger: +-{lin:.2f} m/s)
a/d : increase/decrease angular velocity (burger: +-{ang:.2f} rad/s)
space key, s : force stop

CTRL-C to quit
"""


@dataclass(frozen=True)
class TeleopConfig:
    """teleop_key.py's private parameters: the robot's limits (the burger's by default)."""

    max_linear: float = _num(MAX_LINEAR, 0.0, 10.0, "largest target speed [m/s]")
    max_angular: float = _num(MAX_ANGULAR, 0.0, 100.0, "largest target turn rate [rad/s]")

    def __post_init__(self) -> None:
        check_fields(self)


@dataclass(frozen=True)
class TeleopState:
    """Targets chosen by the keys and the ramped command actually sent ([m/s], [rad/s])."""

    target_linear: float = 0.0
    target_angular: float = 0.0
    linear: float = 0.0
    angular: float = 0.0
    presses: int = 0   # velocity-changing keypresses so far


def _clamp(v: float, limit: float) -> float:
    return max(-limit, min(limit, v))


def press(state: TeleopState, key: str, max_linear: float = MAX_LINEAR,
          max_angular: float = MAX_ANGULAR) -> tuple[TeleopState, str]:
    """Applies one key -> (new state, kind); kind is 'speed', 'stop', 'quit' or 'none'.

    Targets are rounded to the step so repeated presses do not accumulate float error.
    """
    s = state
    if key in ("w", "x"):
        lin = round(s.target_linear + (LIN_STEP if key == "w" else -LIN_STEP), 4)
        return replace(s, target_linear=_clamp(lin, max_linear), presses=s.presses + 1), "speed"
    if key in ("a", "d"):
        ang = round(s.target_angular + (ANG_STEP if key == "a" else -ANG_STEP), 4)
        return replace(s, target_angular=_clamp(ang, max_angular), presses=s.presses + 1), "speed"
    if key in (" ", "s"):
        return replace(s, target_linear=0.0, target_angular=0.0, linear=0.0, angular=0.0), "stop"
    if key == "\x03":
        return replace(s, target_linear=0.0, target_angular=0.0, linear=0.0, angular=0.0), "quit"
    return s, "none"


def ramp(current: float, target: float, slop: float) -> float:
    """One loop of the speed profile: current moves toward target by at most slop."""
    if target > current:
        return min(target, current + slop)
    if target < current:
        return max(target, current - slop)
    return target


def tick(state: TeleopState) -> TeleopState:
    """Ramps the sent command toward the targets by half a key step (called every loop, ~10 Hz)."""
    return replace(state, linear=ramp(state.linear, state.target_linear, LIN_STEP / 2.0),
                   angular=ramp(state.angular, state.target_angular, ANG_STEP / 2.0))


def status_line(state: TeleopState) -> str:
    return f"currently:\tlinear vel {state.target_linear:.2f}\t angular vel {state.target_angular:.2f}"


class TeleopNode:
    """Reads keys from the terminal (0.1 s timeout) and publishes cmd_vel every loop."""

    def __init__(self, cfg: TeleopConfig) -> None:
        import rospy
        from geometry_msgs.msg import Twist

        self.rospy, self.Twist = rospy, Twist
        self.max_linear, self.max_angular = cfg.max_linear, cfg.max_angular
        self.pub = rospy.Publisher("cmd_vel", Twist, queue_size=10)
        self.fd = sys.stdin.fileno()

    def _key(self) -> str:
        # os.read, not sys.stdin.read: the latter buffers several keys out of select's sight
        ready, _, _ = select.select([self.fd], [], [], 0.1)
        return os.read(self.fd, 1).decode(errors="replace") if ready else ""

    def _keys_mode(self, saved: list) -> None:
        """Unbuffered keys without echo, CTRL-C read as a key (no SIGINT); output unchanged."""
        mode = list(saved)
        mode[3] &= ~(termios.ICANON | termios.ECHO | termios.ISIG)
        mode[6] = list(mode[6])
        mode[6][termios.VMIN], mode[6][termios.VTIME] = 1, 0
        termios.tcsetattr(self.fd, termios.TCSADRAIN, mode)

    def _send(self, linear: float, angular: float) -> None:
        msg = self.Twist()
        msg.linear.x, msg.angular.z = linear, angular
        self.pub.publish(msg)

    def run(self) -> None:
        saved = termios.tcgetattr(self.fd)
        banner = BANNER.format(lin=self.max_linear, ang=self.max_angular)
        state = TeleopState()
        print(banner, flush=True)
        try:
            self._keys_mode(saved)
            while not self.rospy.is_shutdown():
                key = self._key()
                state, kind = press(state, key, self.max_linear, self.max_angular)
                if kind == "quit":
                    break
                if kind == "speed":
                    if state.presses % BANNER_EVERY == 0:
                        print(banner, flush=True)
                    print(status_line(state), flush=True)
                elif kind == "stop":
                    print(status_line(state), flush=True)
                state = tick(state)
                self._send(state.linear, state.angular)
        except KeyboardInterrupt:
            pass
        finally:
            self._send(0.0, 0.0)
            termios.tcsetattr(self.fd, termios.TCSADRAIN, saved)
