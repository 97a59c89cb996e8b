"""The offline tool under bad input: one clear line, a non-zero exit, no traceback and
no output folder (or an untouched one) after any failure."""
from __future__ import annotations

import numpy as np
import pytest

from fastslam import offline, simrun
from fastslam.config import SlamConfig
from fastslam.io.bag_writer import write_bag
from fastslam.io.records import OdomRecord, ScanRecord
from fastslam.transforms import StaticTransform

MOUNT = StaticTransform.planar("base_footprint", "base_scan", x=-0.032)


@pytest.fixture(scope="module")
def sim_records():
    run = simrun.run("room", SlamConfig(seed=0, particles=2), seed=0, record=True, max_time=4.0)
    return run.scans, run.odoms


def _run(args, capsys):
    code = offline.main([*map(str, args), "--quiet"])
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return code, [line for line in err.splitlines() if line.startswith("error:")]


def test_an_output_that_is_a_file_fails_before_the_run(tmp_path, capsys, sim_records):
    bag = tmp_path / "b.bag"
    write_bag(bag, *sim_records, static_transforms=[MOUNT])
    (tmp_path / "out").write_text("a file")
    code, errors = _run([bag, "--out", tmp_path / "out"], capsys)
    assert code == 2 and errors == [f"error: --out {tmp_path / 'out'} is a file, not a folder"]
    assert (tmp_path / "out").read_text() == "a file"


def test_a_failure_while_writing_leaves_no_output(tmp_path, capsys, monkeypatch, sim_records):
    bag = tmp_path / "b.bag"
    write_bag(bag, *sim_records, static_transforms=[MOUNT])
    real = offline.write_results

    def disk_full(out, *args, **kwargs):
        (out / "map.pgm").write_bytes(b"half")
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(offline, "write_results", disk_full)
    code, errors = _run([bag, "--out", tmp_path / "out"], capsys)
    assert code == 2 and errors == ["error: No space left on device"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["b.bag"]      # no out/, no temporary folder
    monkeypatch.setattr(offline, "write_results", real)
    assert offline.main([str(bag), "--out", str(tmp_path / "out"), "--quiet"]) == 0
    assert (tmp_path / "out" / "map.yaml").is_file()


def test_random_bytes_are_not_a_bag(tmp_path, capsys):
    bag = tmp_path / "x.bag"
    bag.write_bytes(np.random.default_rng(0).bytes(4096))
    code, errors = _run([bag, "--out", tmp_path / "out"], capsys)
    assert code == 2 and len(errors) == 1 and "is not a readable ROS 1 bag" in errors[0]
    assert "ROS 2 and MCAP bags are not supported" in errors[0]
    assert not (tmp_path / "out").exists()


def test_a_malformed_config_names_the_file_and_line(tmp_path, capsys, sim_records):
    bag = tmp_path / "b.bag"
    write_bag(bag, *sim_records, static_transforms=[MOUNT])
    cfg = tmp_path / "bad.yaml"
    cfg.write_text("particles: 30\nmap_resolution: [0.05\n")
    code, errors = _run([bag, "--out", tmp_path / "out", "--config", cfg], capsys)
    assert code == 2 and len(errors) == 1
    assert errors[0].startswith(f"error: {cfg}: line 3: not valid YAML")


def test_a_zero_quaternion_on_the_laser_mounting_is_an_error(tmp_path, capsys, sim_records):
    bag = tmp_path / "b.bag"
    broken = StaticTransform("base_footprint", "base_scan", (0.1, 0.0, 0.0), (0.0, 0.0, 0.0, 0.0))
    write_bag(bag, *sim_records, static_transforms=[broken])
    code, errors = _run([bag, "--out", tmp_path / "out"], capsys)
    assert code == 2 and errors == ["error: the laser's mounting base_footprint -> base_scan cannot be read: "
                                    "tf base_footprint -> base_scan has a zero quaternion"]


def test_a_bag_without_odometry_is_nothing_usable(tmp_path, capsys, sim_records):
    scans = [s for s in sim_records[0] if s.t > 1.0]
    bag = tmp_path / "b.bag"
    write_bag(bag, scans, [OdomRecord(0.01, 0.0, 0.0, 0.0)], static_transforms=[MOUNT])
    odomless = tmp_path / "c.bag"
    write_bag(odomless, scans, [], static_transforms=[MOUNT])
    code, errors = _run([odomless, "--out", tmp_path / "out"], capsys)
    assert code == 2 and len(errors) == 1 and "odometry" in errors[0]
    # odometry only long before the scans: every scan is dropped, with the reason counted
    code, errors = _run([bag, "--out", tmp_path / "out"], capsys)
    assert code == 2 and errors == [f"error: none of the bag's {len(scans)} scans could be used: "
                                    f"no odometry at the scan's time ({len(scans)})"]
    assert not (tmp_path / "out").exists()


def test_a_scan_with_zero_readings_only_is_still_a_good_input(tmp_path, capsys, sim_records):
    scans, odoms = sim_records
    blank = [ScanRecord(s.t, np.zeros_like(s.ranges), s.angle_min, s.angle_increment, s.range_min, s.range_max,
                        frame_id=s.frame_id) for s in scans]
    bag = tmp_path / "b.bag"
    write_bag(bag, blank, odoms, static_transforms=[MOUNT])
    code, errors = _run([bag, "--out", tmp_path / "out"], capsys)
    assert code == 0 and errors == []
