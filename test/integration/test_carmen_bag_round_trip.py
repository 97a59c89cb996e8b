"""The Intel CARMEN log -> bag -> fastslam.io.bag_reader round trip, and the converter CLI."""
from __future__ import annotations

import gzip
import math

import numpy as np
import pytest

from fastslam import carmen_to_bag as carmen_cli
from fastslam.carmen_to_bag import convert, reference_path
from fastslam.eval.trajectory import ate
from fastslam.geometry import wrap_angle
from fastslam.io.bag_reader import read_bag
from fastslam.io.carmen_log import read_log
from fastslam.io.trajectory_files import read_trajectory

N = 50


@pytest.fixture(scope="session")
def intel(dev_data):
    """The Intel Research Lab log of the development data (the test fails if it is missing)."""
    return dev_data("intel-corrected.log.gz")


def raw_flaser(intel, n: int) -> list[list[str]]:
    """The first n FLASER lines split into fields, read independently of the parser."""
    rows = []
    with gzip.open(intel, "rt") as f:
        for line in f:
            if line.startswith("FLASER "):
                rows.append(line.split())
                if len(rows) == n:
                    break
    return rows


@pytest.fixture(scope="module")
def intel_slice(tmp_path_factory, intel):
    out = tmp_path_factory.mktemp("intel") / "intel50.bag"
    result = convert(read_log(intel, limit=N), out, odom_noise=0.0)
    return result, read_bag(out)


def test_ranges_survive_the_round_trip(intel_slice, intel):
    _, data = intel_slice
    rows = raw_flaser(intel, N)
    assert len(data.scans) == N
    for row, scan in zip(rows, data.scans):
        raw = np.array(row[2:182], dtype=np.float64)
        expected = np.where(raw >= 81.83, np.inf, raw).astype(np.float32)
        np.testing.assert_array_equal(scan.ranges, expected)
        assert scan.angle_min == pytest.approx(-math.pi / 2)
        assert scan.angle_increment == pytest.approx(math.pi / 180)
        assert scan.range_max == pytest.approx(81.83) and scan.frame_id == "laser"
    assert sum(np.isinf(s.ranges).sum() for s in data.scans) > 0    # the slice has no-returns


def test_times_and_poses_survive_the_round_trip(intel_slice, intel):
    result, data = intel_slice
    rows = raw_flaser(intel, N)
    times = np.array([float(r[-1]) for r in rows])
    poses = np.array([[float(v) for v in r[185:188]] for r in rows])   # odom_x odom_y odom_theta
    assert np.all(np.diff(times) > 0)
    np.testing.assert_allclose([s.t for s in data.scans], times, atol=1e-6)
    np.testing.assert_allclose([o.t for o in data.odoms], times, atol=1e-6)
    odo = data.odom_poses()
    np.testing.assert_allclose(odo[:, 1:3], poses[:, :2], atol=1e-9)       # level 0 = the log
    np.testing.assert_allclose(wrap_angle(odo[:, 3] - poses[:, 2]), 0.0, atol=1e-9)
    assert data.mount.found and (data.mount.x, data.mount.y, data.mount.yaw) == (0.0, 0.0, 0.0)
    gt_t, gt = read_trajectory(result.reference)
    np.testing.assert_array_equal(gt_t, result.times)
    np.testing.assert_array_equal(gt, poses)


def test_cli_noise_is_deterministic_and_seeded(tmp_path, capsys, intel):
    def run(name: str, seed: int) -> np.ndarray:
        out = tmp_path / name
        assert carmen_cli.main([str(intel), "--out", str(out), "--limit", "200",
                                "--odom-noise", "1", "--seed", str(seed)]) == 0
        return read_bag(out).odom_poses()

    a, b, c = run("a.bag", 4), run("b.bag", 4), run("c.bag", 5)
    assert "dead-reckoning ATE" in capsys.readouterr().out
    np.testing.assert_array_equal(a, b)
    assert np.abs(a[:, 1:3] - c[:, 1:3]).max() > 0.05
    gt_t, gt = read_trajectory(tmp_path / "a.bag.gt.txt")
    _, odo = read_trajectory(tmp_path / "a.bag.odom.txt")
    np.testing.assert_array_equal(odo[:, :2], a[:, 1:3])
    assert ate(gt, odo) > 0.1          # 200 scans of level-1 noise leave a visible drift


def test_cli_refuses_to_overwrite(tmp_path, capsys, intel):
    (tmp_path / "x.bag").write_bytes(b"old")
    assert carmen_cli.main([str(intel), "--out", str(tmp_path / "x.bag"), "--limit", "3"]) == 1
    assert "exists" in capsys.readouterr().err
    assert (tmp_path / "x.bag").read_bytes() == b"old"


ROBOTLASER = ("ROBOTLASER1 0 -1.5 3.0 0.5 20.0 0.01 0 3 1.0 20.0 2.5 0 {lx} {ly} 0.0 {rx} 0.0 0.0 "
              "0.3 0.1 0.5 0.4 0.0 {t} host {t}\n")


def test_robotlaser_mount_goes_to_tf_static(tmp_path):
    # laser 0.4 m ahead of the robot centre in every line
    text = "".join(ROBOTLASER.format(lx=0.4 + k, ly=0.0, rx=float(k), t=5.0 + k) for k in range(3))
    (tmp_path / "r.log").write_text(text)
    result = convert(read_log(tmp_path / "r.log"), tmp_path / "r.bag")
    data = read_bag(tmp_path / "r.bag")
    assert result.mount == pytest.approx((0.4, 0.0, 0.0))
    assert (data.mount.x, data.mount.y, data.mount.yaw) == pytest.approx((0.4, 0.0, 0.0))
    assert data.mount.found and not data.mount.upside_down
    np.testing.assert_allclose(data.odom_poses()[:, 1], [0.0, 1.0, 2.0])   # robot poses, not laser poses
    np.testing.assert_array_equal(data.scans[0].ranges, np.array([1.0, np.inf, 2.5], np.float32))
    assert data.scans[0].range_max == 20.0
    assert reference_path(tmp_path / "r.bag").is_file()


def test_tum_trajectories_parse_back_to_the_same_numbers(tmp_path, intel):
    """The converter's --format tum files, as evo reads them: t x y z qx qy qz qw, the same
    stamps and positions to the last bit and the same headings through the quaternion."""
    plain, tum = tmp_path / "plain.bag", tmp_path / "tum.bag"
    for out, extra in ((plain, []), (tum, ["--format", "tum"])):
        assert carmen_cli.main([str(intel), "--out", str(out), "--limit", "40", "--odom-noise", "1",
                                "--quiet", *extra]) == 0
    for kind in ("gt", "odom"):
        rows = [ln.split() for ln in reference_path(tum, kind).read_text().splitlines() if not ln.startswith("#")]
        assert len(rows) == 40 and all(len(r) == 8 and r[3:6] == ["0.0", "0.0", "0.0"] for r in rows)
        q = np.array([[float(v) for v in r[4:]] for r in rows])
        np.testing.assert_allclose(np.linalg.norm(q, axis=1), 1.0, rtol=0, atol=1e-12)   # unit quaternions
        t0, p0 = read_trajectory(reference_path(plain, kind))
        t1, p1 = read_trajectory(reference_path(tum, kind))
        np.testing.assert_array_equal(t1, t0)
        np.testing.assert_array_equal(p1[:, :2], p0[:, :2])
        np.testing.assert_allclose(wrap_angle(p1[:, 2] - p0[:, 2]), 0.0, rtol=0, atol=1e-12)
    # yaw from the quaternion by hand (evo's convention, w last): theta = 2 atan2(qz, qw)
    first = [float(v) for v in next(ln for ln in reference_path(tum, "gt").read_text().splitlines()
                                    if not ln.startswith("#")).split()]
    assert wrap_angle(2 * math.atan2(first[6], first[7])) == pytest.approx(read_trajectory(
        reference_path(plain, "gt"))[1][0, 2], abs=1e-12)
