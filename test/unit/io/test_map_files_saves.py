"""Map saves that overwrite a map in use: the YAML and the image it names always match,
whatever moment a save is killed at, and what killed saves leave is cleaned."""
from __future__ import annotations

import numpy as np
import pytest
import yaml

from fastslam.io import map_files
from fastslam.io.map_files import MapSaveError, load_map, remove_stale, save_map

OCC = np.array([[-1, 0, 100], [0, 0, 100]], dtype=np.int8)


def _image(yaml_path):
    return yaml.safe_load(yaml_path.read_text())["image"]


def test_each_versioned_save_leaves_one_yaml_and_the_one_image_it_names(tmp_path):
    for k in range(5):
        occ = OCC.copy()
        occ[0, 0] = 100 if k % 2 else -1
        pgm, yml = save_map(tmp_path / "m", occ, 0.05, (1.0, 2.0, 0.0), versioned=True)
        assert yml == tmp_path / "m.yaml" and pgm.name == _image(yml)
        assert pgm.name.startswith("m.saved-") and pgm.suffix == ".pgm"
        assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["m.yaml", pgm.name])
        np.testing.assert_array_equal(load_map(yml)[0], occ)


def test_a_save_failing_before_the_yaml_keeps_the_previous_pair(tmp_path, monkeypatch):
    _, yml = save_map(tmp_path / "m", OCC, 0.05, (0.0, 0.0, 0.0), versioned=True)
    before = (yml.read_text(), _image(yml))
    real = map_files._atomic_write_all

    def full_disk_for_yaml(files):
        if files[0][0].suffix == ".yaml":
            raise MapSaveError("cannot write map file m.yaml: No space left on device")
        real(files)

    monkeypatch.setattr(map_files, "_atomic_write_all", full_disk_for_yaml)
    with pytest.raises(MapSaveError, match="No space"):
        save_map(tmp_path / "m", np.zeros((2, 3), np.int8), 0.05, (0.0, 0.0, 0.0), versioned=True)
    assert (yml.read_text(), _image(yml)) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["m.yaml", before[1]])
    np.testing.assert_array_equal(load_map(yml)[0], OCC)


def test_what_killed_saves_left_is_removed_and_the_map_kept(tmp_path):
    _, yml = save_map(tmp_path / "m", OCC, 0.05, (0.0, 0.0, 0.0), versioned=True)
    kept = _image(yml)
    leftovers = [".m.pgm.a1b2.tmp", ".m.yaml.c3d4.tmp", "m.saved-orphan.pgm"]
    for name in leftovers:
        (tmp_path / name).write_bytes(b"x" * 100)
    (tmp_path / "m.old.pgm").write_bytes(b"a user's own file")     # not ours: kept
    removed = remove_stale(tmp_path / "m")
    assert sorted(p.name for p in removed) == sorted(leftovers)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["m.yaml", kept, "m.old.pgm"])
    np.testing.assert_array_equal(load_map(yml)[0], OCC)
