"""The soak (`make bench soak`): the live node under every fault class of issue 13 at once.

A master, slam.py through slam.launch (sim time, the burger preset, node.yaml's rates
and limits) and this driver: the ROS-free simulator (fastslam.sim) drives the office
loop again and again for 30 simulated minutes; the driver publishes /clock, odometry,
tf and scans as the simulator node does, and injects at random (seeded) stale and
reordered scans, odometry gaps (the robot driving on) and jumps (at once, or after up
to a minute of silence standing still), frozen odometry stamps, scans from unknown
frames, bursts of up to a million beams, bad geometry, NaN odometry, future stamps, and
dynamic_map (up to 20 at once) and save_map calls; once, in the last third, the
simulator restarts (/clock goes back): the one real restart. It reports, every 5
simulated minutes, the known cells of the published map (never dropping but at the
restart), the node's resident memory (flat within 5 MB after warm-up) and how late
map->odom came (gaps between its stamps beyond transform_publish_period).

    PYTHONPATH=src:. python -m bench.soak [--minutes 30] [--speed 1] [--seed 0] [--config burger]
"""
from __future__ import annotations

import argparse
import json
import os
import signal
import socket
import subprocess
import sys
import tempfile
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bench.common import ROOT
from fastslam.sim.lidar import driver_ranges
from fastslam.sim.route import load_route
from fastslam.sim.sim import SimConfig, Simulation
from fastslam.sim.world_loader import load_world

WARM_UP = 300.0        # [s] of sim time before memory must be flat (the first lap maps the office)
REPORT_EVERY = 300.0   # [s] of sim time between report rows
SAMPLE_EVERY = 10.0    # [s] of sim time between samples of the map and the memory
TF_PERIOD = 0.05       # node.yaml's transform_publish_period [s]
START = 100.0          # [s] the clock starts here (0 is "no time yet" to rospy)
# per class, expected firings per simulated minute
RATES = {"stale scan": 2.0, "reordered scans": 1.0, "odometry gap": 0.5, "odometry jump": 0.3,
         "frozen odometry stamps": 0.5, "unknown frame": 2.0, "beam burst": 0.5, "bad geometry": 1.0,
         "bad odometry": 1.0, "future stamp": 0.5, "dynamic_map calls": 1.0, "save_map call": 0.5}


@dataclass
class Watch:
    """What the driver sees of the node: map->odom stamps, ~stats."""

    lock: threading.Lock = field(default_factory=threading.Lock)
    tf_stamps: list[float] = field(default_factory=list)
    stats: dict[str, Any] = field(default_factory=dict)
    service_errors: int = 0
    calls: int = 0

    def on_tf(self, msg: Any) -> None:
        for t in msg.transforms:
            if t.child_frame_id == "odom":
                with self.lock:
                    self.tf_stamps.append(t.header.stamp.to_sec())

    def on_stats(self, msg: Any) -> None:
        with self.lock:
            self.stats = json.loads(msg.data)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def node_rss_mb(pid: int) -> float:
    with open(f"/proc/{pid}/status") as f:
        return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024


class Driver:
    """The simulator on the wire, with faults."""

    def __init__(self, rng: np.random.Generator, seed: int) -> None:
        import rospy
        import tf2_ros
        from nav_msgs.msg import Odometry
        from rosgraph_msgs.msg import Clock
        from rospy.numpy_msg import numpy_msg
        from sensor_msgs.msg import LaserScan

        from assign5 import convert

        self.rospy, self.rng, self.convert = rospy, rng, convert
        self.Clock, self.LaserScan, self.Odometry = Clock, numpy_msg(LaserScan), Odometry
        self.world = load_world(ROOT / "worlds" / "office.yaml")
        self.route = np.concatenate([load_route(ROOT / "worlds" / "office.route.yaml")] * 40)
        self.cfg = SimConfig(seed=seed)
        self.pub_clock = rospy.Publisher("/clock", Clock, queue_size=10)
        # numpy_msg: a scan of a million beams is written at once, so the driver's clock never stalls
        self.pub_scan = rospy.Publisher("scan", numpy_msg(LaserScan), queue_size=20)
        self.pub_odom = rospy.Publisher("odom", Odometry, queue_size=50)
        self.tf = tf2_ros.TransformBroadcaster()
        self.static = tf2_ros.StaticTransformBroadcaster()
        self.injected: dict[str, int] = dict.fromkeys(RATES, 0)
        self.log: list[tuple[float, str]] = []   # (sim time, fault) of every injection
        self.restart()

    def restart(self) -> None:
        """The simulator starts again: robot at the spawn, odometry at zero, clock at START."""
        self.sim = Simulation(self.world, self.cfg, np.random.default_rng(int(self.rng.integers(2**31))),
                              route=self.route)
        self.odom_offset = np.zeros(2)
        self.odom_gap_until = -1.0
        self.stand_until = -1.0
        self.held_scan: Any = None
        self.last_scan: Any = None
        self.static.sendTransform([self.convert.transform_msg(self.stamp(0.0), "base_footprint", "base_scan",
                                                              self.cfg.laser_x, self.cfg.laser_y, 0.0,
                                                              z=self.cfg.laser_z)])

    def stamp(self, t: float) -> Any:
        return self.rospy.Time.from_sec(START + t)

    @property
    def now(self) -> float:
        return START + self.sim.time

    # -- messages --------------------------------------------------------------------
    def odom_msg(self, stamp: Any, pose: np.ndarray) -> Any:
        msg = self.Odometry()
        msg.header.stamp, msg.header.frame_id, msg.child_frame_id = stamp, "odom", "base_footprint"
        msg.pose.pose = self.convert.pose_msg(*pose)
        return msg

    def scan_msg(self, stamp: Any, ranges: np.ndarray, frame: str = "base_scan", repeat: int = 1) -> Any:
        lidar = self.sim.lidar
        msg = self.LaserScan()
        msg.header.stamp, msg.header.frame_id = stamp, frame
        msg.angle_min = lidar.angle_min
        msg.angle_increment = lidar.angle_increment / repeat
        msg.angle_max = lidar.angle_min + (len(ranges) * repeat - 1) * msg.angle_increment
        msg.range_min, msg.range_max = lidar.range_min, lidar.range_max
        msg.ranges = np.repeat(ranges, repeat).astype(np.float32)
        msg.intensities = np.zeros(0, np.float32)
        return msg

    def tick(self) -> None:
        standing = self.now < self.stand_until
        route, self.sim.route = self.sim.route, None if standing else self.sim.route
        tick = self.sim.step()       # without its route, the robot stands (no cmd_vel)
        self.sim.route = route
        stamp = self.stamp(tick.t)
        self.pub_clock.publish(self.Clock(stamp))
        if tick.odom_due and self.now >= self.odom_gap_until:
            pose = self.sim.odom.pose.copy()
            pose[:2] += self.odom_offset
            self.pub_odom.publish(self.odom_msg(stamp, pose))
            self.tf.sendTransform(self.convert.transform_msg(stamp, "odom", "base_footprint", *pose))
        if tick.scan is not None:
            msg = self.scan_msg(stamp, driver_ranges(tick.scan, self.cfg.range_min, self.cfg.no_return))
            if self.held_scan is not None:      # reordered: the newer one first
                self.pub_scan.publish(msg)
                self.pub_scan.publish(self.held_scan)
                self.held_scan = None
            else:
                self.pub_scan.publish(msg)
            self.last_scan = msg

    # -- faults ----------------------------------------------------------------------
    def inject(self, kind: str) -> None:
        self.injected[kind] += 1
        self.log.append((self.now, kind))
        rospy, last = self.rospy, self.last_scan
        now = self.stamp(self.sim.time)
        if kind == "stale scan" and last is not None:
            stale = self.scan_msg(last.header.stamp - rospy.Duration(float(self.rng.uniform(0.001, 0.05))),
                                  np.asarray(last.ranges))
            self.pub_scan.publish(stale)
        elif kind == "reordered scans" and last is not None:
            self.held_scan = last               # sent again after the next one
        elif kind == "odometry gap":
            self.odom_gap_until = self.now + float(self.rng.uniform(1.0, 5.0))
        elif kind == "odometry jump":
            # a kidnap of the odometry frame (a driver reset), at once or after a silence of
            # up to a minute while the robot stands still (no motion is lost: the map stays whole)
            self.odom_offset += self.rng.uniform(-1.0, 1.0, 2) * float(self.rng.choice([20.0, 1000.0]))
            if self.rng.uniform() < 0.5:
                self.odom_gap_until = self.stand_until = self.now + float(self.rng.uniform(5.0, 60.0))
        elif kind == "frozen odometry stamps":
            pose = self.sim.odom.pose.copy()
            pose[:2] += self.odom_offset
            for _ in range(200):
                self.pub_odom.publish(self.odom_msg(now, pose))
        elif kind == "unknown frame" and last is not None:
            frame = str(self.rng.choice(["nowhere", "", "base_scan_typo", f"laser_{int(self.rng.integers(1000))}"]))
            self.pub_scan.publish(self.scan_msg(now, np.asarray(last.ranges), frame=frame))
        elif kind == "beam burst" and last is not None:
            repeat = int(self.rng.choice([100, 1000, 2800]))     # up to a million beams
            self.pub_scan.publish(self.scan_msg(now, np.asarray(last.ranges), repeat=repeat))
        elif kind == "bad geometry" and last is not None:
            bad = self.scan_msg(now, np.asarray(last.ranges))
            field_name, value = [("angle_increment", float("nan")), ("range_max", 0.0), ("angle_increment", 0.0),
                                 ("ranges", np.zeros(0, np.float32))][int(self.rng.integers(4))]
            setattr(bad, field_name, value)
            self.pub_scan.publish(bad)
        elif kind == "bad odometry":
            msg = self.odom_msg(now, self.sim.odom.pose)
            if self.rng.uniform() < 0.5:
                msg.pose.pose.position.x = float("nan")
            else:
                q = msg.pose.pose.orientation
                q.x = q.y = q.z = q.w = 0.0
            self.pub_odom.publish(msg)
        elif kind == "future stamp" and last is not None:
            self.pub_scan.publish(self.scan_msg(now + rospy.Duration(3600.0), np.asarray(last.ranges)))


def call_services(watch: Watch, kind: str, count: int) -> None:
    """count concurrent dynamic_map calls (read by numpy), or one save_map call, in threads."""
    import rospy
    from nav_msgs.srv import GetMap, GetMapRequest, GetMapResponse
    from rospy.numpy_msg import numpy_msg
    from std_srvs.srv import Trigger

    class NumpyGetMap:
        _type, _md5sum = GetMap._type, GetMap._md5sum
        _request_class, _response_class = GetMapRequest, numpy_msg(GetMapResponse)

    def one() -> None:
        try:
            if kind == "dynamic_map calls":
                rospy.ServiceProxy("dynamic_map", NumpyGetMap)()
            else:
                rospy.ServiceProxy("slam/save_map", Trigger)()
            with watch.lock:
                watch.calls += 1
        except (rospy.ServiceException, rospy.ROSException):
            with watch.lock:
                watch.service_errors += 1

    for _ in range(count):
        threading.Thread(target=one, daemon=True).start()


def late_moments(stamps: list[float], log: list[tuple[float, str]], count: int = 5) -> list[dict[str, Any]]:
    """The count largest gaps between map->odom stamps, each with the faults injected in
    the 2 s before it (to tell a fault's cost from the machine's scheduling)."""
    st = np.asarray(stamps)
    gaps = np.diff(st)
    out = []
    for i in np.argsort(gaps)[::-1][:count]:
        if gaps[i] <= 0:
            continue
        t = float(st[i])
        near = sorted({kind for when, kind in log if t - 2.0 <= when <= t + gaps[i]})
        out.append({"at_s": round(t - START, 2), "gap_s": round(float(gaps[i]), 3), "faults": near})
    return out


def tf_lateness(stamps: list[float]) -> float:
    """Largest gap between successive map->odom stamps beyond one period [s]; gaps
    across the clock going back are left out."""
    gaps = np.diff(np.asarray(stamps))
    gaps = gaps[gaps > 0]
    return float(gaps.max() - TF_PERIOD) if len(gaps) else float("nan")


def run(minutes: float, speed: float, seed: int, config: str) -> dict[str, Any]:
    rng = np.random.default_rng(seed)
    home = Path(tempfile.mkdtemp(prefix="assign5_soak_"))
    env = {**os.environ, "ROS_MASTER_URI": f"http://127.0.0.1:{free_port()}", "ROS_HOME": str(home)}
    ws = subprocess.run(["bash", str(ROOT / "scripts" / "ws.sh")], capture_output=True, text=True).stdout.strip()
    source = f"source {ws}/devel/setup.bash && exec "
    port = env["ROS_MASTER_URI"].rsplit(":", 1)[1]
    logs = open(home / "processes.log", "w")
    core = subprocess.Popen(["bash", "-c", source + f"roscore -p {port}"], env=env, stdout=logs,
                            stderr=subprocess.STDOUT, start_new_session=True)
    os.environ.update(ROS_MASTER_URI=env["ROS_MASTER_URI"], ROS_HOME=str(home))
    import rosgraph
    import rospy
    from std_msgs.msg import String
    from tf2_msgs.msg import TFMessage

    deadline = time.monotonic() + 60
    while not rosgraph.is_master_online() and time.monotonic() < deadline:
        time.sleep(0.2)
    launch = subprocess.Popen(["bash", "-c", source + f"roslaunch assign5 slam.launch use_sim_time:=true "
                               f"config:={config} map_file:={home}/soak_map output:=log"], env=env, stdout=logs,
                              stderr=subprocess.STDOUT, start_new_session=True)
    rows: list[dict[str, Any]] = []
    samples: list[dict[str, Any]] = []
    try:
        rospy.init_node("soak_driver", disable_signals=True)
        watch = Watch()
        rospy.Subscriber("/tf", TFMessage, watch.on_tf, queue_size=200)
        rospy.Subscriber("slam/stats", String, watch.on_stats, queue_size=5)
        master = rosgraph.Master("/soak_driver")
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            try:
                import xmlrpc.client

                pid = int(xmlrpc.client.ServerProxy(master.lookupNode("/slam")).getPid("/soak_driver")[2])
                break
            except (rosgraph.MasterError, OSError):
                time.sleep(0.2)
        else:
            raise RuntimeError(f"slam.py did not start (see {home}/processes.log)")
        driver = Driver(rng, seed)
        while driver.pub_scan.get_num_connections() == 0 and time.monotonic() < deadline:
            time.sleep(0.1)
        rows, samples = drive(driver, watch, pid, minutes, speed, rng)
    finally:
        launch.send_signal(signal.SIGINT)     # the node saves its map on the way out
        try:
            launch.wait(timeout=60)
        except subprocess.TimeoutExpired:
            launch.kill()
        core.send_signal(signal.SIGINT)
        core.wait(timeout=30)
        logs.close()
    saved = sorted(p.name for p in home.glob("soak_map*.yaml"))
    return summarise(rows, samples, watch, driver.injected, driver.log, saved, home)


def drive(driver: Driver, watch: Watch, pid: int, minutes: float, speed: float,
          rng: np.random.Generator) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """Ticks the simulator at `speed` x real time for `minutes`, injecting faults; returns
    the report rows and the samples (every SAMPLE_EVERY, and the moment of the restart)."""
    total = minutes * 60.0
    restart_at = float(rng.uniform(0.65, 0.8)) * total
    restarted = False
    elapsed = 0.0                   # sim time over both runs
    period = driver.sim.dt / speed
    per_tick = {k: r / 60.0 * driver.sim.dt for k, r in RATES.items()}
    rows: list[dict[str, Any]] = []
    samples: list[dict[str, Any]] = []
    next_sample, next_row = SAMPLE_EVERY, REPORT_EVERY
    due = time.monotonic()
    print(f"{'sim min':>7} {'updates':>7} {'known cells':>11} {'resets':>6} {'RSS MB':>7} {'tf late s':>9} "
          f"{'dropped':>7} {'calls':>5}", flush=True)
    while elapsed < total:
        driver.tick()
        elapsed += driver.sim.dt
        for kind, p in per_tick.items():
            if rng.uniform() < p:
                if kind in ("dynamic_map calls", "save_map call"):
                    driver.injected[kind] += 1
                    driver.log.append((driver.now, kind))
                    call_services(watch, kind, int(rng.integers(1, 21)) if kind == "dynamic_map calls" else 1)
                else:
                    driver.inject(kind)
        if not restarted and elapsed >= restart_at:
            restarted = True
            driver.restart()
            samples.append({"restart": elapsed})
        if elapsed >= next_sample:
            next_sample += SAMPLE_EVERY
            with watch.lock:
                s = dict(watch.stats)
            samples.append({"t": elapsed, "known": s.get("known_cells", 0), "resets": s.get("resets", 0),
                            "rss": node_rss_mb(pid), "maps_mb": s.get("maps_mb", 0.0), "updates": s.get("updates", 0),
                            "dropped": sum(s.get("dropped", {}).values())})
        if elapsed >= next_row:
            next_row += REPORT_EVERY
            rows.append(report_row(samples, watch, elapsed))
        # the next tick one period after this one was due, or after now if late: the clock
        # never catches up in a burst (a burst would show as map->odom gaps in sim time)
        due = max(due + period, time.monotonic())
        delay = due - time.monotonic()
        if delay > 0:
            time.sleep(delay)
    return rows, samples


def report_row(samples: list[dict[str, Any]], watch: Watch, elapsed: float) -> dict[str, Any]:
    last = next(s for s in reversed(samples) if "t" in s)
    with watch.lock:
        late = tf_lateness(watch.tf_stamps)
        calls = watch.calls
    row = {"sim_min": round(elapsed / 60), "updates": last["updates"], "known_cells": last["known"],
           "resets": last["resets"], "rss_mb": round(last["rss"], 1), "tf_late_s": round(late, 3),
           "dropped": last["dropped"], "calls": calls}
    print(f"{row['sim_min']:>7} {row['updates']:>7} {row['known_cells']:>11} {row['resets']:>6} "
          f"{row['rss_mb']:>7.1f} {row['tf_late_s']:>9.3f} {row['dropped']:>7} {row['calls']:>5}", flush=True)
    return row


def summarise(rows: list[dict[str, Any]], samples: list[dict[str, Any]], watch: Watch, injected: dict[str, int],
              log: list[tuple[float, str]], saved: list[str], home: Path) -> dict[str, Any]:
    restart = next((s["restart"] for s in samples if "restart" in s), None)
    points = [s for s in samples if "t" in s]
    # known cells may drop only where the node reset (its ~stats count the resets); the
    # published map is the best particle's, and another particle may know a few cells less
    drops = [(round(b["t"] / 60, 2), a["known"] - b["known"]) for a, b in zip(points, points[1:])
             if b["known"] < a["known"] and b["resets"] == a["resets"]]
    worst = max(drops, key=lambda d: d[1], default=(0.0, 0))
    worst_share = worst[1] / max(max((s["known"] for s in points), default=1), 1)

    def baseline(lo: float, hi: float, window: float = 60.0) -> tuple[float, float]:
        """Memory after warm-up, [lo, hi): the range of the minima of each whole window
        (what stays, transients left out) and the largest transient above its window's minimum."""
        windows: dict[int, list[float]] = {}
        for s in points:
            i = int((s["t"] - lo) // window)
            if lo <= s["t"] and lo + (i + 1) * window <= hi:   # whole windows only: a part has few samples
                windows.setdefault(i, []).append(s["rss"])
        if not windows:
            return float("nan"), float("nan")
        lows = [min(v) for v in windows.values()]
        return float(max(lows) - min(lows)), float(max(max(v) - min(v) for v in windows.values()))

    end = points[-1]["t"] if points else 0.0
    before = (WARM_UP, restart if restart is not None else end + 1)
    after = (restart + WARM_UP, end + 1) if restart is not None else None
    first, first_peak = baseline(*before)
    second, second_peak = baseline(*after) if after else (float("nan"),) * 2
    # six samples a minute can all land on an update's or a fault's transient: the floor of
    # each report period says whether what stays grows
    floor = [baseline(*span, window=REPORT_EVERY)[0] if span else float("nan") for span in (before, after)]
    with watch.lock:
        late, calls, errors, stats = tf_lateness(watch.tf_stamps), watch.calls, watch.service_errors, watch.stats
        moments = late_moments(watch.tf_stamps, log)
    out = {"injected": injected, "known_cell_drops": drops, "tf_largest_gaps": moments,
           "rss_flat_after_warm_up_mb": [round(first, 1), round(second, 1)],
           "rss_transient_mb": [round(first_peak, 1), round(second_peak, 1)],
           "rss_floor_per_report_mb": [round(f, 1) for f in floor],
           "tf_late_max_s": round(late, 3), "service_calls": calls, "service_errors": errors,
           "node_stats": stats, "saved_maps": saved, "rows": rows, "samples": samples,
           "restart_at_min": None if restart is None else round(restart / 60, 1)}
    (home / "soak.json").write_text(json.dumps(out, indent=1) + "\n")
    print(f"injected: {json.dumps(injected)}")
    print(f"node: {stats.get('updates')} updates, {stats.get('resets')} resets, "
          f"dropped {json.dumps(stats.get('dropped'))}, rules {json.dumps(stats.get('rules'))}, "
          f"growth refused {stats.get('map_growth_refused')}")
    print(f"known cells: outside the restart (at {out['restart_at_min']} sim min) "
          + ("never dropped" if not drops else f"dipped {len(drops)} times, at most {worst[1]} cells "
                                                 f"({100 * worst_share:.3f} % of the map) at {worst[0]} min"))
    print(f"memory after warm-up ({WARM_UP / 60:.0f} min): the per-minute low stayed within {first:.1f} MB before the "
          f"restart and {second:.1f} MB after (transients of a fault up to {first_peak:.1f} / {second_peak:.1f} MB); "
          f"the low of each {REPORT_EVERY / 60:.0f} minutes within {floor[0]:.1f} / {floor[1]:.1f} MB")
    print("largest map->odom gaps (sim s after the start of its run, the faults of the 2 s before): " +
          "; ".join(f"{m['gap_s']} s at {m['at_s']} ({', '.join(m['faults']) or 'none'})" for m in moments))
    print(f"map->odom at most {late:.3f} s late ({late / TF_PERIOD:.1f} periods); {calls} service calls answered, "
          f"{errors} failed; maps saved: {', '.join(saved)}; everything in {home}/soak.json")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--minutes", type=float, default=30.0, help="simulated minutes")
    parser.add_argument("--speed", type=float, default=1.0, help="sim time per wall time (tf lateness is "
                        "measured in sim time: a faster run scales the node's wall-time jitter up)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--config", default="burger", help="slam.launch's config (a preset)")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    run(args.minutes, args.speed, args.seed, args.config)
    print(f"{args.minutes:.0f} simulated minutes in {time.perf_counter() - start:.0f} s wall")
    return 0


if __name__ == "__main__":
    sys.exit(main())
