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


# -- issue 13 items 3, 5, 6: the node's rules and bounds, offline too ----------------------

REAR = StaticTransform("base_footprint", "base_scan", (0.0, 0.0, 0.0), (0.0, 0.0, 1.0, 0.0))   # facing backwards


def _front_quarter(s):
    """The scan's beams within 45 degrees of the laser's axis only (a 90-degree laser)."""
    k = int(round((-np.pi / 4 - s.angle_min) / s.angle_increment)) % len(s.ranges)
    ranges = np.roll(s.ranges, -k)[:90]
    return ScanRecord(s.t, ranges, -np.pi / 4, s.angle_increment, s.range_min, s.range_max, frame_id=s.frame_id)


def test_a_field_of_view_with_no_beam_is_a_drop_with_its_reason_and_one_warning(tmp_path, capsys, sim_records):
    scans, odoms = sim_records
    # every other scan from a 90-degree laser facing backwards: none of its beams lies in -30..30
    mixed = [_front_quarter(s) if i % 2 else s for i, s in enumerate(scans)]
    bag = tmp_path / "b.bag"
    write_bag(bag, mixed, odoms, static_transforms=[REAR])
    code = offline.main([str(bag), "--out", str(tmp_path / "out"), "--quiet", "--set", "fov_min=-30",
                         "--set", "fov_max=30"])
    err = capsys.readouterr().err
    assert code == 0 and "Traceback" not in err
    n = len(scans) // 2
    warned = [line for line in err.splitlines() if "no beam in the field of view" in line]
    assert warned == [f"warning: {n} messages dropped: no beam in the field of view fov_min..fov_max = -30..30 deg "
                      "(the scan sweeps from 135 to -136 deg in the base frame)"]
    import json

    stats = json.loads((tmp_path / "out" / "stats.json").read_text())
    assert stats["dropped"] == {"no beam in the field of view fov_min..fov_max = #..# deg": n}
    assert stats["updates"] == len(scans) - n
    # all of them: nothing usable, said with the reason
    bag = tmp_path / "c.bag"
    write_bag(bag, [_front_quarter(s) for s in scans], odoms, static_transforms=[REAR])
    code, errors = _run([bag, "--out", tmp_path / "out2", "--set", "fov_min=-30", "--set", "fov_max=30"], capsys)
    assert code == 2 and errors == [f"error: none of the bag's {len(scans)} scans could be used: no beam in the "
                                    f"field of view fov_min..fov_max = #..# deg ({len(scans)})"]


def test_scans_of_too_many_beams_are_subsampled_with_one_notice(tmp_path, capsys, sim_records):
    scans, odoms = sim_records
    dense = [ScanRecord(s.t, np.repeat(s.ranges, 20), s.angle_min, s.angle_increment / 20, s.range_min,
                        s.range_max, frame_id=s.frame_id) for s in scans]      # 7200 beams
    bag = tmp_path / "b.bag"
    write_bag(bag, dense, odoms, static_transforms=[MOUNT])
    code = offline.main([str(bag), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err
    assert code == 0
    assert [line for line in err.splitlines() if "subsampled" in line] == [
        "warning: scans of 7200 beams (> max_beams 4096) are evenly subsampled to 4096 beams (said once)"]


def test_a_configuration_that_cannot_fit_in_memory_fails_before_the_run(tmp_path, capsys):
    code, errors = _run(["missing.bag", "--out", tmp_path / "out", "--set", "particles=10000", "--set",
                         "map_width=1000", "--set", "map_height=1000"], capsys)
    assert code == 2 and len(errors) == 1
    assert errors[0].startswith("error: the memory limit (80% of this machine's): particles=10000 maps of "
                                "1000 x 1000 m at map_resolution=0.05 m (20000 x 20000 cells) need 3814698 MB")
    assert errors[0].endswith("a coarser map_resolution or more memory")
    assert not (tmp_path / "out").exists()
