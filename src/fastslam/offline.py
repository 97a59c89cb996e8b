"""Offline FastSLAM on a ROS 1 bag, without a master, far faster than real time.

    python -m fastslam.offline BAG --out DIR [--config FILE] [--set key=value]...
                               [--seed N] [--scan-topic T] [--odom-topic T]

Reads the bag with `rosbags`, takes the laser mounting from /tf_static or /tf, feeds
every scan and odometry message through the same Frontend and FastSlam.step as the
slam.py node, and writes DIR/map.pgm + map.yaml (map_server format), map.png,
trajectory.txt (t x y theta of the final best particle, one line per processed
scan, header stamps), stats.json and the effective config.yaml.
"""
from __future__ import annotations

import argparse
import json
import resource
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .config import ConfigError, SlamConfig, parse_override
from .frontend import Dropped, Frontend, drop_key
from .io.bag import BagData, BagError, OdomRecord, read_bag
from .io.mapfile import save_map
from .io.png import render_map, write_png
from .io.trajectory import write_trajectory
from .scan import Scan, laser_problem
from .slam import FastSlam

DEFAULT_CONFIG = Path(__file__).resolve().parents[2] / "config" / "slam.yaml"


@dataclass
class OfflineResult:
    slam: FastSlam
    scans: int = 0
    updates: int = 0
    wall_seconds: float = 0.0
    update_ms: list[float] = field(default_factory=list)
    dropped: dict[str, int] = field(default_factory=dict)
    events: list[str] = field(default_factory=list)

    def stats(self) -> dict[str, Any]:
        ms = np.array(self.update_ms) if self.update_ms else np.zeros(1)
        return {"scans": self.scans, "updates": self.updates, "wall_seconds": round(self.wall_seconds, 3),
                "ms_per_update_median": float(np.median(ms)), "ms_per_update_p95": float(np.percentile(ms, 95)),
                "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                "dropped": self.dropped, "events": self.events}


def run_bag(data: BagData, cfg: SlamConfig, *, progress: bool = False) -> OfflineResult:
    """Processes every message of the bag in time order."""
    slam = FastSlam(cfg)
    front = Frontend(slam)
    result = OfflineResult(slam=slam)
    mount = (data.mount.x, data.mount.y, data.mount.yaw)
    bag_span = (data.scans[-1].t - data.scans[0].t) if data.scans else 0.0
    start = last_print = time.perf_counter()
    for rec in data.records():
        try:
            if isinstance(rec, OdomRecord):
                front.add_odom(rec.t, np.array([rec.x, rec.y, rec.yaw]))
                continue
            result.scans += 1
            problem = laser_problem(len(rec.ranges), rec.angle_min, rec.angle_increment,
                                    rec.range_min, rec.range_max)
            if problem:
                raise Dropped(problem)
            scan = Scan.from_laser(rec.ranges, rec.angle_min, rec.angle_increment, rec.range_min,
                                   rec.range_max, mount=mount, upside_down=data.mount.upside_down, stamp=rec.t)
            info = front.add_scan(scan)
            if info.processed:
                result.updates += 1
                result.update_ms.append(1000.0 * info.seconds)
        except Dropped as err:
            key = drop_key(str(err))
            result.dropped[key] = result.dropped.get(key, 0) + 1
        result.events += [str(e) for e in front.events]
        front.events.clear()
        now = time.perf_counter()
        if progress and (now - last_print > 0.5 or result.scans == len(data.scans)):
            last_print = now
            _progress(result.scans, len(data.scans), now - start, bag_span)
    result.wall_seconds = time.perf_counter() - start
    if progress:
        print(file=sys.stderr)
    return result


def _progress(done: int, total: int, wall: float, bag_span: float) -> None:
    frac = done / max(total, 1)
    bar = "#" * int(30 * frac)
    rate = done / max(wall, 1e-9)
    speedup = frac * bag_span / max(wall, 1e-9)
    print(f"\r[{bar:<30}] {done}/{total} scans  {rate:6.1f} scans/s  {speedup:6.1f}x real time",
          end="", file=sys.stderr, flush=True)


def write_results(out: Path, result: OfflineResult, cfg: SlamConfig) -> None:
    import yaml

    out.mkdir(parents=True, exist_ok=True)
    slam = result.slam
    grid = slam.grid
    occ = slam.best_occupancy()
    origin = (float(grid.origin[0]), float(grid.origin[1]), 0.0)
    save_map(out / "map", occ, grid.resolution, origin)
    traj = slam.trajectory()
    write_trajectory(out / "trajectory.txt", traj[:, 0], traj[:, 1:],
                     comment="final best particle, one pose per processed scan: t x y theta")
    write_png(out / "map.png", render_map(occ, grid.resolution, origin,
                                          {"estimate": (traj[:, 1:3], (220, 0, 0))}, scale=2))
    (out / "stats.json").write_text(json.dumps(result.stats(), indent=2) + "\n")
    (out / "config.yaml").write_text(yaml.safe_dump(cfg.to_dict(), sort_keys=False))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m fastslam.offline", description=__doc__.split("\n\n")[0])
    parser.add_argument("bag", help="ROS 1 bag with LaserScan and Odometry (and tf)")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--config", default=str(DEFAULT_CONFIG), help="SlamConfig YAML (default config/slam.yaml)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a parameter")
    parser.add_argument("--seed", type=int, help="RNG seed (overrides the config)")
    parser.add_argument("--scan-topic", help="default: the only LaserScan topic")
    parser.add_argument("--odom-topic", help="default: the only Odometry topic")
    parser.add_argument("--quiet", action="store_true", help="no progress bar")
    args = parser.parse_args(argv)
    try:
        overrides = dict(parse_override(s) for s in args.set)
        if args.seed is not None:
            overrides["seed"] = args.seed
        cfg = SlamConfig.from_yaml(args.config, overrides)
        data = read_bag(args.bag, args.scan_topic, args.odom_topic)
    except (ConfigError, BagError, OSError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    if not data.mount.found:
        print(f"warning: no tf from '{data.mount.base_frame}' to '{data.mount.laser_frame}' in the bag; "
              "assuming the laser sits at the base origin", file=sys.stderr)
    result = run_bag(data, cfg, progress=not args.quiet)
    write_results(Path(args.out), result, cfg)
    for event in result.events:
        print(f"warning: {event}", file=sys.stderr)
    s = result.stats()
    print(f"{s['scans']} scans, {s['updates']} updates in {s['wall_seconds']:.1f} s "
          f"({s['ms_per_update_median']:.1f} ms median per update), peak {s['peak_memory_mb']:.0f} MB; "
          f"dropped {sum(result.dropped.values())}; results in {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
