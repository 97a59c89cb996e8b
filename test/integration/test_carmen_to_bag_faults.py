"""The CARMEN converter under bad input: one clear line with the line number, a
non-zero exit, and no output file left behind."""
from __future__ import annotations

import gzip
from pathlib import Path

import pytest

from fastslam import carmen_to_bag
from fastslam.io.bag_writer import BagWriter

FLASER = "FLASER 4 1.0 2.0 3.0 4.0 0.1 0.2 0.3 0.1 0.2 0.3 {t} host {t}"


def _log(tmp_path: Path, stamps: list[str], name: str = "x.log") -> Path:
    path = tmp_path / name
    path.write_text("".join(FLASER.format(t=t) + "\n" for t in stamps))
    return path


def _outputs(tmp_path: Path) -> list[str]:
    return sorted(p.name for p in tmp_path.iterdir() if not p.name.endswith((".log", ".gz")))


@pytest.mark.parametrize("stamp", ["inf", "-5", "1e30", "nan"])
def test_a_bad_timestamp_names_its_line_and_writes_nothing(tmp_path, capsys, stamp):
    log = _log(tmp_path, ["1.0", "1.1", stamp, "1.3"])
    assert carmen_to_bag.main([str(log), "--out", str(tmp_path / "x.bag")]) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert err == [f"error: line 3: bad FLASER message: timestamp {stamp} is not in [0, 2^32) s"]
    assert _outputs(tmp_path) == []


def test_a_truncated_gzip_is_reported_not_raised(tmp_path, capsys):
    text = "".join(FLASER.format(t=f"{1 + 0.1 * i:.1f}") + "\n" for i in range(2000)).encode()
    whole = gzip.compress(text)
    (tmp_path / "x.gz").write_bytes(whole[:len(whole) // 2])
    assert carmen_to_bag.main([str(tmp_path / "x.gz"), "--out", str(tmp_path / "x.bag")]) == 1
    err = capsys.readouterr().err
    assert "the file ends early or is corrupt (truncated gzip?)" in err and "Traceback" not in err
    assert _outputs(tmp_path) == []


def test_a_failure_while_writing_leaves_no_partial_bag(tmp_path, capsys, monkeypatch):
    log = _log(tmp_path, [f"{1 + 0.1 * i:.1f}" for i in range(20)])
    calls = []

    def failing_scan(self, rec, topic=None):
        calls.append(rec.t)
        if len(calls) == 10:
            raise OSError(28, "No space left on device")
        return original(self, rec, topic)

    original = BagWriter.scan
    monkeypatch.setattr(BagWriter, "scan", failing_scan)
    assert carmen_to_bag.main([str(log), "--out", str(tmp_path / "x.bag")]) == 1
    assert "No space left on device" in capsys.readouterr().err
    assert len(calls) == 10
    assert _outputs(tmp_path) == []          # neither the bag nor the trajectories, nor temporaries


def test_an_existing_output_is_refused_and_kept(tmp_path, capsys):
    log = _log(tmp_path, ["1.0", "1.1"])
    (tmp_path / "x.bag").write_text("keep me")
    assert carmen_to_bag.main([str(log), "--out", str(tmp_path / "x.bag")]) == 1
    assert "exists" in capsys.readouterr().err
    assert (tmp_path / "x.bag").read_text() == "keep me"


def test_a_good_log_gives_all_three_files(tmp_path):
    log = _log(tmp_path, ["1.0", "1.1", "1.2"])
    assert carmen_to_bag.main([str(log), "--out", str(tmp_path / "x.bag")]) == 0
    assert _outputs(tmp_path) == ["x.bag", "x.bag.gt.txt", "x.bag.odom.txt"]
