"""Offline FastSLAM on a ROS 1 bag, without a master, far faster than real time.

    python -m fastslam.offline BAG --out DIR [--config FILE] [--set key=value]...
                               [--seed N] [--scan-topic T] [--odom-topic T] [--format tum]
                               [--reference FILE] [--quiet] [--serial]

Reads the bag with `rosbags` or ROS's `rosbag`, takes the laser mounting from /tf_static or /tf, feeds
every scan and odometry message through the same Frontend and FastSlam.step as the
slam.py node, and writes DIR/map.pgm + map.yaml (map_server format), map.png,
stats.json, the effective config.yaml and four trajectories (header stamps;
`t x y theta`, or TUM's `t x y z qx qy qz qw` with --format tum):
trajectory.txt, the final best particle, one pose per processed scan;
trajectory_scans.txt, the same path at every scan the filter saw, the motion since
the last processed scan composed onto it in between (the odometry's, or with
track_scans the scan matcher's against the best map); trajectory_smoothed.txt, the same
with hindsight: between two processed scans, that motion bent to end on the particle's
pose at the second, the gap spread by distance (hindsight a live run cannot have);
live_poses.txt, one pose per
scan as map->odom gave it during the run: the best particle at the last processed
scan, moved since by that same motion (FastSlam.live_pose, as the node publishes it).
The node's stream rules and bounds apply (fastslam.filter.frontend, filter.budget); a
reset (time going back by more than reset_backwards) leaves the map before it in
map_before_reset_<k>.pgm/.yaml, and each kind of dropped message is one warning line
with its count.

With a reference, the bag's /ground_truth (nav_msgs/Odometry, as the simulator records
it) or ``--reference FILE`` (``t x y theta`` or TUM lines), stats.json gets the ATE and
RPE of trajectory.txt as ``python -m fastslam.evaluate REF DIR/trajectory.txt`` prints
them, map.png draws the reference too, and error.png plots both paths after alignment
and the error over time. A progress bar (tqdm) runs on a terminal, unless --quiet.

With track_scans, on a machine of two cores or more, a second process tracks the scans
between updates while the particles work on the next update, matches some of the
particles, and weighs some and writes the scan into their maps (filter/pipeline.py): the
same results to the bit, in less wall time; --serial keeps all the work in this one.
"""
from __future__ import annotations

import argparse
import json
import resource
import sys
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Callable

import numpy as np
from tqdm import tqdm

from fastslam.cli import closed_output_ends_quietly
from fastslam.config import ConfigError, SlamConfig, parse_override
from fastslam.eval.render import ESTIMATE_RGB, TRUTH_RGB, map_picture, write_png
from fastslam.eval.trajectory import align_2d, apply_alignment, match_by_time, score
from fastslam.filter.budget import AUTO_SHARE, Limits, startup_problem
from fastslam.filter.frontend import Dropped, Frontend, Reset, drop_key
from fastslam.filter.pipeline import PipelinedTracker, available
from fastslam.filter.scan import Scan, laser_problem
from fastslam.filter.scan_wait import ODOM_WAIT
from fastslam.filter.slam import FastSlam, UpdateTrace
from fastslam.filter.smooth import spread_gaps
from fastslam.geometry import compose, relative
from fastslam.io.bag_reader import REFERENCE_TOPIC, BagData, read_bag
from fastslam.io.map_files import save_map
from fastslam.io.records import BagError, OdomRecord, ScanRecord
from fastslam.io.staging import staged_folder
from fastslam.io.trajectory_files import FORMATS, TrajectoryError, read_trajectory, write_trajectory

if TYPE_CHECKING:  # numpy.typing needs numpy >= 1.21 (Noetic has 1.17)
    from numpy.typing import NDArray


DEFAULT_CONFIG = Path(__file__).resolve().parents[2] / "config" / "slam.yaml"


@dataclass(frozen=True)
class Reference:
    """A reference trajectory: where it came from, (T,) times and (T, 3) poses."""

    source: str
    times: NDArray[np.float64]
    poses: NDArray[np.float64]


@dataclass
class OfflineResult:
    slam: FastSlam
    scans: int = 0
    updates: int = 0
    wall_seconds: float = 0.0
    update_ms: list[float] = field(default_factory=list)
    dropped: dict[str, int] = field(default_factory=dict)
    events: list[str] = field(default_factory=list)
    drop_reasons: dict[str, str] = field(default_factory=dict)  # kind -> the first full reason
    reset_maps: list[tuple[NDArray[np.int8], float, tuple[float, float, float]]] = field(default_factory=list)
    rules: dict[str, int] = field(default_factory=dict)  # how often each odometry rule fired
    # one row per scan the filter saw: t, odometry x y theta, live pose x y theta,
    # index of the last processed update, filter life (resets before it), processed (0/1)
    scan_rows: list[list[float]] = field(default_factory=list)
    reference: Reference | None = None
    accuracy: dict[str, Any] | None = None   # against the reference, set by write_results
    second_process: dict[str, Any] | None = None   # what the pipeline's worker did (None: no worker)

    def live_poses(self) -> NDArray[np.float64]:
        """(S, 4) rows t, x, y, theta: map->odom composed with the odometry at every scan."""
        rows = np.array(self.scan_rows, dtype=np.float64).reshape(-1, 10)
        return rows[:, [0, 4, 5, 6]]

    def _last_life(self) -> NDArray[np.float64]:
        """The scan rows of the filter's last life (after its last reset)."""
        rows = np.array(self.scan_rows, dtype=np.float64).reshape(-1, 10)
        return rows[rows[:, 8] == rows[-1, 8]] if len(rows) else rows

    def scan_trajectory(self) -> NDArray[np.float64]:
        """(S, 4) rows t, x, y, theta: the final best particle's path at every scan of the
        filter's last life; between processed scans, the live pose's motion since the
        last one (odometry, or tracked with track_scans) composed onto its pose."""
        rows = self._last_life()
        if not len(rows):
            return np.zeros((0, 4))
        t, live = rows[:, 0], rows[:, 4:7]
        k = rows[:, 7].astype(np.intp)
        done = rows[:, 9] > 0
        traj = self.slam.trajectory()
        at_update = np.empty((len(traj), 3))
        at_update[k[done]] = live[done]          # the live pose at each processed scan
        poses = compose(traj[k, 1:], relative(at_update[k], live))
        poses[done] = traj[k[done], 1:]          # exactly, not through a zero motion
        return np.concatenate([t[:, None], poses], axis=1)

    def smoothed_trajectory(self, every: NDArray[np.float64] | None = None) -> NDArray[np.float64]:
        """(S, 4) scan_trajectory (every, if the caller has it) with hindsight: between two processed
        scans, the motion since the first bent to end on the particle's pose at the second (filter.smooth)."""
        rows = self._last_life()
        every = self.scan_trajectory() if every is None else every
        if not len(rows):
            return every
        poses = spread_gaps(every[:, 1:], rows[:, 9] > 0, rows[:, 1:4])
        return np.concatenate([every[:, :1], poses], axis=1)

    def stats(self) -> dict[str, Any]:
        ms = np.array(self.update_ms) if self.update_ms else np.zeros(1)
        return {"scans": self.scans, "updates": self.updates, "wall_seconds": round(self.wall_seconds, 3),
                "ms_per_update_median": float(np.median(ms)), "ms_per_update_p95": float(np.percentile(ms, 95)),
                "peak_memory_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                "dropped": self.dropped, "odometry_rules": self.rules, "events": self.events,
                "map_growth_refused": self.slam.refusals, "match_recoveries": self.slam.recoveries,
                "match_loops": self.slam.loops,
                "match_loops_spread": self.slam.loops_spread,
                "odometry_scale": None if self.slam.odom_scale is None else self.slam.odom_scale.summary(),
                "odometry_stalls_tracked": self.slam.stalls, "matches_beyond_gate": self.slam.beyond_gate,
                "resets": len(self.reset_maps), "second_process": self.second_process,
                **({"accuracy": self.accuracy} if self.accuracy is not None else {})}


def run_bag(data: BagData, cfg: SlamConfig, *, progress: bool = False, limits: Limits | None = None,
            trace: Callable[[UpdateTrace], None] | None = None, pipeline: bool = False) -> OfflineResult:
    """Processes every message of the bag in time order, with the node's rules and bounds
    (default: the node's defaults); the maps of the lives before each reset are kept.
    trace: called after each update (FastSlam.trace; bench/lineage.py).
    pipeline: track the scans between updates in a second process (filter/pipeline.py; the same results)."""
    tracker = PipelinedTracker(cfg, FastSlam.track_params(cfg)) if pipeline else None
    try:
        return _run(data, cfg, progress, limits, trace, tracker)
    finally:
        if tracker is not None:
            tracker.close()


def _run(data: BagData, cfg: SlamConfig, progress: bool, limits: Limits | None,
         trace: Callable[[UpdateTrace], None] | None, tracker: PipelinedTracker | None) -> OfflineResult:
    slam = FastSlam(cfg, limits=limits if limits is not None else default_limits(cfg), tracker=tracker)
    slam.trace = trace
    slam.tracker.timeline = [slam.live_pose.copy()]
    tickets: list[int] = []   # each scan row's live pose in slam.tracker.timeline (filled in at the end)
    result = OfflineResult(slam=slam)

    def keep_map(_event: Reset) -> None:
        grid = slam.grid
        result.reset_maps.append((slam.best_occupancy(), grid.resolution,
                                  (float(grid.origin[0]), float(grid.origin[1]), 0.0)))

    front = Frontend(slam, before_reset=keep_map)
    mount = (data.mount.x, data.mount.y, data.mount.yaw)
    start = time.perf_counter()
    bar = tqdm(total=len(data.scans), unit="scan", disable=not progress, file=sys.stderr, dynamic_ncols=True,
               mininterval=0.5)
    for rec in data.records(ODOM_WAIT):   # as the node, played at the bag's speed, handles them
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
            if info.refused:
                result.events.append(info.refused)
            odom = front.scan_odom
            assert odom is not None  # every add_scan that returns sets it
            if info.processed:
                result.updates += 1
                result.update_ms.append(1000.0 * info.seconds)
            tickets.append(slam.tracker.ticket())
            result.scan_rows.append([rec.t, *odom.tolist(), np.nan, np.nan, np.nan, slam.updates - 1, front.resets,
                                     float(info.processed)])
        except Dropped as err:
            key = drop_key(str(err))
            result.dropped[key] = result.dropped.get(key, 0) + 1
            result.drop_reasons.setdefault(key, str(err))
        result.events += [str(e) for e in front.events]
        front.events.clear()
        if isinstance(rec, ScanRecord):
            bar.update(1)
            if progress and result.scans % 50 == 0:   # bag seconds per wall second
                bar.set_postfix_str(f"{(rec.t - data.scans[0].t) / max(time.perf_counter() - start, 1e-9):.1f}x "
                                    "real time", refresh=False)
    bar.close()
    slam.tracker.settle()
    timeline = slam.tracker.timeline
    for row, k in zip(result.scan_rows, tickets):
        row[4:7] = timeline[k].tolist()
    if tracker is not None:
        if tracker.failure:
            result.events.append(f"scans between updates tracked in this process: {tracker.failure}")
        result.second_process = {"scans_tracked": tracker.served, "particles_matched": tracker.matched,
                                 "particles_written": tracker.wrote,
                                 "failure": tracker.failure}
    result.wall_seconds = time.perf_counter() - start
    result.rules = dict(front.counts)
    return result


def write_results(out: Path, result: OfflineResult, cfg: SlamConfig, fmt: str = "xytheta") -> None:
    """Writes every output into the folder out (which exists)."""
    import yaml

    slam = result.slam
    grid = slam.grid
    occ = slam.best_occupancy()
    origin = (float(grid.origin[0]), float(grid.origin[1]), 0.0)
    save_map(out / "map", occ, grid.resolution, origin)
    for k, (before, resolution, at) in enumerate(result.reset_maps, 1):   # the map is never lost to a reset
        save_map(out / f"map_before_reset_{k}", before, resolution, at)
    traj = slam.trajectory()
    write_trajectory(out / "trajectory.txt", traj[:, 0], traj[:, 1:], fmt=fmt,
                     comment="final best particle, one pose per processed scan")
    every = result.scan_trajectory()
    since = "the scans' matches against the best map" if cfg.track_scans else "the odometry"
    write_trajectory(out / "trajectory_scans.txt", every[:, 0], every[:, 1:], fmt=fmt,
                     comment="final best particle at every scan: its pose at the last processed scan "
                             f"composed with the motion since ({since})")
    smooth = result.smoothed_trajectory(every)
    write_trajectory(out / "trajectory_smoothed.txt", smooth[:, 0], smooth[:, 1:], fmt=fmt,
                     comment="trajectory_scans with hindsight: between two processed scans, the motion since "
                             "the first bent to end on the pose at the second")
    live = result.live_poses()
    write_trajectory(out / "live_poses.txt", live[:, 0], live[:, 1:], fmt=fmt,
                     comment="live map->odom composed with the odometry, one pose per scan: the best "
                             f"particle at the last processed scan moved since by {since}")
    paths = {"estimate": (traj[:, 1:3], ESTIMATE_RGB)}
    if result.reference is not None:
        result.accuracy = _accuracy(out, result.reference, traj)
        in_map = _reference_in_map_frame(result.reference, traj)
        if in_map is not None:
            paths = {"reference": (in_map[:, :2], TRUTH_RGB), **paths}
    write_png(out / "map.png", map_picture(occ, grid.resolution, origin, paths))
    (out / "stats.json").write_text(json.dumps(result.stats(), indent=2) + "\n")
    (out / "config.yaml").write_text(yaml.safe_dump(cfg.to_dict(), sort_keys=False))


OFFLINE_LIMIT = f"the memory limit ({AUTO_SHARE:.0%} of this machine's)"


def default_limits(cfg: SlamConfig) -> Limits:
    """The node's default bounds: max_map_extent, AUTO_SHARE of this machine's memory."""
    return Limits.for_memory(0.0, cfg.particles)


class NothingUsable(ValueError):
    """The bag holds nothing the filter can use; str() says why."""


def _check_usable(data: BagData) -> None:
    if not data.scans:
        raise NothingUsable(f"the bag has no scans on {data.scan_topic}")
    if not data.odoms:
        raise NothingUsable(f"the bag has no odometry on {data.odom_topic}: the filter needs both")


def _accuracy(out: Path, ref: Reference, traj: NDArray[np.float64]) -> dict[str, Any]:
    """ATE and RPE of trajectory.txt against the reference, matched as `fastslam.evaluate`
    matches by default; error.png beside them."""
    s = score(ref.times, ref.poses, traj[:, 0], traj[:, 1:])
    if s.matched == 0:
        return {"reference": ref.source, "matched": 0,
                "error": "no pose of trajectory.txt within 0.05 s of a reference pose"}
    from fastslam.eval.plots import plot_errors

    plot_errors(out / "error.png", ref.times, ref.poses, traj[:, 0], traj[:, 1:],
                title=f"{out.name}/trajectory.txt against {ref.source}")
    return {"reference": ref.source, **s.as_dict()}


def _reference_in_map_frame(ref: Reference, traj: NDArray[np.float64]) -> NDArray[np.float64] | None:
    """The reference moved onto the estimate by the ATE's rigid alignment (the map frame
    is the odometry's, the reference's may be the world's); None when nothing matches."""
    _, r, e = match_by_time(ref.times, ref.poses, traj[:, 0], traj[:, 1:])
    if len(r) == 0:
        return None
    rot, shift = align_2d(r, e)
    return apply_alignment(rot, shift, ref.poses)


def load_reference(data: BagData, bag: str, path: str | None) -> Reference | None:
    """--reference FILE, else the bag's /ground_truth, else None.

    Raises:
        TrajectoryError: the file cannot be read or holds no pose.
    """
    if path is not None:
        times, poses = read_trajectory(path)
        if len(times) == 0:
            raise TrajectoryError(f"{path}: no poses")
        return Reference(str(path), times, poses)
    if data.reference:
        rows = np.array([[r.t, r.x, r.y, r.yaw] for r in data.reference], dtype=np.float64)
        return Reference(f"{Path(bag).name}:{REFERENCE_TOPIC}", rows[:, 0], rows[:, 1:])
    return None


@closed_output_ends_quietly
def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m fastslam.offline", description=__doc__.split("\n\n")[0])
    parser.add_argument("bag", help="ROS 1 bag with LaserScan and Odometry (and tf)")
    parser.add_argument("--out", required=True, help="output folder")
    parser.add_argument("--config", default=str(DEFAULT_CONFIG), help="SlamConfig YAML (default config/slam.yaml)")
    parser.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="override a parameter")
    parser.add_argument("--seed", type=int, help="RNG seed (overrides the config)")
    parser.add_argument("--scan-topic", help="default: the only LaserScan topic")
    parser.add_argument("--odom-topic", help="default: the only Odometry topic")
    parser.add_argument("--format", choices=FORMATS, default="xytheta",
                        help="trajectory files: t x y theta (default) or TUM's t x y z qx qy qz qw")
    parser.add_argument("--reference", metavar="FILE",
                        help="reference trajectory (t x y theta or TUM) for stats.json's ATE/RPE and error.png; "
                             "default: the bag's /ground_truth, if any")
    parser.add_argument("--quiet", action="store_true", help="no progress bar (there is none off a terminal)")
    parser.add_argument("--serial", action="store_true",
                        help="all the work in this process (default with track_scans, on a machine of two cores or "
                             "more: a second process tracks the scans between updates, matches some particles, "
                             "weighs some and writes their maps; the same results)")
    args = parser.parse_args(argv)
    out = Path(args.out)
    try:
        overrides = dict(parse_override(s) for s in args.set)
        if args.seed is not None:
            overrides["seed"] = args.seed
        cfg = SlamConfig.from_yaml(args.config, overrides)
        problem = startup_problem(cfg, default_limits(cfg), OFFLINE_LIMIT)
        if problem:
            raise ConfigError(problem)
        with staged_folder(out) as work:   # checked before the run; filled only if it succeeds
            data = read_bag(args.bag, args.scan_topic, args.odom_topic)
            reference = load_reference(data, args.bag, args.reference)
            _check_usable(data)
            for parent, child in data.bad_tf:
                if not data.mount.found:
                    raise BagError(f"the laser's mounting {data.mount.base_frame} -> {data.mount.laser_frame} "
                                   f"cannot be read: tf {parent} -> {child} has a zero quaternion")
                print(f"warning: tf {parent} -> {child} has a zero quaternion: ignored", file=sys.stderr)
            if not data.mount.found:
                print(f"warning: no tf from '{data.mount.base_frame}' to '{data.mount.laser_frame}' in the bag; "
                      "assuming the laser sits at the base origin", file=sys.stderr)
            result = run_bag(data, cfg, progress=not args.quiet and sys.stderr.isatty(),
                             pipeline=cfg.track_scans and not args.serial and available())
            result.reference = reference
            if result.updates == 0:
                why = ", ".join(f"{k} ({n})" for k, n in result.dropped.items()) or "none was due"
                raise NothingUsable(f"none of the bag's {result.scans} scans could be used: {why}")
            write_results(work, result, cfg, args.format)
    except OSError as err:  # the message without "[Errno N]"
        print(f"error: {err.strerror or err}" + (f": {err.filename}" if err.filename else ""), file=sys.stderr)
        return 2
    except (ConfigError, BagError, NothingUsable, TrajectoryError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted: nothing written", file=sys.stderr)
        return 130
    except Exception as err:  # a fault of ours: one line to report, never a traceback or half a folder
        where = traceback.extract_tb(err.__traceback__)[-1]
        what = ": ".join(part for part in (type(err).__name__, str(err)) if part)
        print(f"error: the run stopped on an internal error, nothing written: {what} "
              f"({Path(where.filename).name}:{where.lineno}; please report it with the command)", file=sys.stderr)
        return 1
    for event in result.events:
        print(f"warning: {event}", file=sys.stderr)
    for key, n in result.dropped.items():   # one line per kind of drop
        print(f"warning: {n} message{'s' if n > 1 else ''} dropped: {result.drop_reasons[key]}", file=sys.stderr)
    s = result.stats()
    print(f"{s['scans']} scans, {s['updates']} updates in {s['wall_seconds']:.1f} s "
          f"({s['ms_per_update_median']:.1f} ms median per update), peak {s['peak_memory_mb']:.0f} MB; "
          f"dropped {sum(result.dropped.values())}; results in {args.out}")
    acc = s.get("accuracy")
    if acc:
        print(f"against {acc['reference']}: " + (f"ATE {acc['ate_rmse']:.3f} m RMS, RPE {acc['rpe_trans']:.3f} m / "
                                                   f"{acc['rpe_rot']:.2f} deg per pose ({acc['matched']} poses)"
                                                   if acc["matched"] else acc["error"]))
    return 0


if __name__ == "__main__":
    sys.exit(main())
