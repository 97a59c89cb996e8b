"""map_server files: exact pixels and YAML, round trip, atomic failure behaviour, versioned
saves over a map in use (the YAML and the image it names always match) and their clean-up."""
from __future__ import annotations

import errno
import os

import numpy as np
import pytest
import yaml

from fastslam.io import map_files as mapfile
from fastslam.io.map_files import MapLoadError, MapSaveError, load_map, remove_stale, save_map

# grid row 0 (bottom) = [-1, 0, 25], row 1 (top) = [26, 65, 100]
OCC = np.array([[-1, 0, 25], [26, 65, 100]], dtype=np.int8)
HEADER = b"P5\n3 2\n255\n"   # Pillow's, as map_server reads it
# image rows top first: grid row 1 -> 205 0 0, then grid row 0 -> 205 254 254
PIXELS = bytes([205, 0, 0, 205, 254, 254])


def test_pgm_bytes_are_exact(tmp_path):
    pgm, yml = save_map(tmp_path / "m", OCC, 0.05, (-1.5, 2.0, 0.25))
    assert pgm == tmp_path / "m.pgm" and yml == tmp_path / "m.yaml"
    assert pgm.read_bytes() == HEADER + PIXELS


def test_yaml_fields(tmp_path):
    save_map(tmp_path / "maps.yaml", OCC, 0.05, (-1.5, 2.0, 0.25), occupied_thresh=0.7, free_thresh=0.2)
    meta = yaml.safe_load((tmp_path / "maps.yaml").read_text())
    assert meta == {"image": "maps.pgm", "resolution": 0.05, "origin": [-1.5, 2.0, 0.25], "negate": 0,
                    "occupied_thresh": 0.7, "free_thresh": 0.2, "mode": "trinary"}


def test_round_trip_follows_the_trinary_rule(tmp_path):
    save_map(tmp_path / "m", OCC, 0.05, (-1.5, 2.0, 0.25))
    occ, res, origin = load_map(tmp_path / "m.yaml")
    # 205 -> p = 50/255 = 0.19608 in [free, occ] -> -1; 254 -> p = 0.0039 -> 0; 0 -> p = 1 -> 100
    np.testing.assert_array_equal(occ, [[-1, 0, 0], [-1, 100, 100]])
    assert occ.dtype == np.int8 and res == 0.05 and origin == (-1.5, 2.0, 0.25)


def test_clean_maps_round_trip_exactly(tmp_path):
    rng = np.random.default_rng(0)
    occ = rng.choice(np.array([-1, 0, 100], dtype=np.int8), size=(37, 53))
    save_map(tmp_path / "r", occ, 0.1, (0.0, 0.0, 0.0))
    back, _, _ = load_map(tmp_path / "r.yaml")
    np.testing.assert_array_equal(back, occ)


def test_load_negate_and_comment_lines(tmp_path):
    (tmp_path / "n.pgm").write_bytes(b"P5\n# a comment\n# another\n2 1\n255\n" + bytes([0, 255]))
    (tmp_path / "n.yaml").write_text("image: n.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 1\n"
                                     "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    occ, _, _ = load_map(tmp_path / "n.yaml")
    np.testing.assert_array_equal(occ, [[0, 100]])   # negate: p = v / 255


def test_missing_image_is_a_clear_error(tmp_path):
    (tmp_path / "x.yaml").write_text("image: nope.pgm\nresolution: 0.1\norigin: [0, 0, 0]\n")
    with pytest.raises(MapLoadError, match="nope.pgm"):
        load_map(tmp_path / "x.yaml")


def test_parent_is_a_file_raises_map_save_error(tmp_path):
    (tmp_path / "file").write_text("not a folder")
    with pytest.raises(MapSaveError, match="cannot write map file"):
        save_map(tmp_path / "file" / "map", OCC, 0.05, (0, 0, 0))


def _old_map(tmp_path):
    save_map(tmp_path / "m", OCC, 0.05, (0.0, 0.0, 0.0))
    return (tmp_path / "m.pgm").read_bytes(), (tmp_path / "m.yaml").read_text()


def test_failed_rename_keeps_old_files_and_removes_temps(tmp_path, monkeypatch):
    old_pgm, old_yaml = _old_map(tmp_path)

    def full_disk(src, dst):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(mapfile.os, "replace", full_disk)
    with pytest.raises(MapSaveError, match="No space left"):
        save_map(tmp_path / "m", np.zeros((4, 4), np.int8), 0.1, (1.0, 1.0, 0.0))
    assert (tmp_path / "m.pgm").read_bytes() == old_pgm
    assert (tmp_path / "m.yaml").read_text() == old_yaml
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.pgm", "m.yaml"]


def test_failure_staging_the_yaml_leaves_both_old_files(tmp_path, monkeypatch):
    old_pgm, old_yaml = _old_map(tmp_path)
    calls = []
    real_fsync = os.fsync

    def fsync_fails_second_time(fd):
        calls.append(fd)
        if len(calls) == 2:
            raise OSError(errno.EIO, "Input/output error")
        real_fsync(fd)

    monkeypatch.setattr(mapfile.os, "fsync", fsync_fails_second_time)
    with pytest.raises(MapSaveError):
        save_map(tmp_path / "m", np.zeros((4, 4), np.int8), 0.1, (1.0, 1.0, 0.0))
    assert len(calls) == 2
    assert (tmp_path / "m.pgm").read_bytes() == old_pgm          # the PGM was not replaced either
    assert (tmp_path / "m.yaml").read_text() == old_yaml
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.pgm", "m.yaml"]


def _save_as_unprivileged(folder):
    """save_map in a child process that cannot write to folder (root drops to nobody)."""
    pid = os.fork()
    if pid == 0:  # child: report through the exit code, never return into pytest
        code = 3
        try:
            if os.geteuid() == 0:
                os.setgid(65534)
                os.setuid(65534)
            save_map(folder / "m", np.zeros((4, 4), np.int8), 0.1, (0.0, 0.0, 0.0))
            code = 0
        except MapSaveError:
            code = 1
        finally:
            os._exit(code)
    status = os.waitpid(pid, 0)[1]
    return os.WEXITSTATUS(status) if os.WIFEXITED(status) else -1   # (os.waitstatus_to_exitcode is 3.9)


def test_read_only_folder(tmp_path):
    old_pgm, _ = _old_map(tmp_path)
    tmp_path.chmod(0o555)
    try:
        assert _save_as_unprivileged(tmp_path) == 1  # MapSaveError, not a crash or success
    finally:
        tmp_path.chmod(0o755)
    assert (tmp_path / "m.pgm").read_bytes() == old_pgm


def test_rejects_non_2d(tmp_path):
    with pytest.raises(ValueError, match="shape"):
        save_map(tmp_path / "m", np.zeros(5, np.int8), 0.1, (0, 0, 0))


def _load(tmp_path, name, data, negate=0):
    (tmp_path / name).write_bytes(data)
    (tmp_path / "x.yaml").write_text(f"image: {name}\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: {negate}\n"
                                     "occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n")
    return load_map(tmp_path / "x.yaml")[0]


# p = (maxval - v) / maxval: 1.0, 0.7, 0.5, 0.1, 0.0 -> occupied, occupied, unknown, free, free
EXPECTED_ROW = [[100, 100, -1, 0, 0]]


def test_pgm_with_maxval_100_reads_by_its_own_scale(tmp_path):
    occ = _load(tmp_path, "a.pgm", b"P5\n5 1\n100\n" + bytes([0, 30, 50, 90, 100]))
    np.testing.assert_array_equal(occ, EXPECTED_ROW)


def test_sixteen_bit_pgm_with_maxval_1000(tmp_path):
    values = np.array([0, 300, 500, 900, 1000], dtype=">u2")
    occ = _load(tmp_path, "b.pgm", b"P5\n# 16 bit\n5 1\n1000\n" + values.tobytes())
    np.testing.assert_array_equal(occ, EXPECTED_ROW)
    np.testing.assert_array_equal(_load(tmp_path, "b.pgm", b"P5\n5 1\n1000\n" + values.tobytes(), negate=1),
                                  [[0, -1, -1, 100, 100]])   # negate: p = v / maxval


def test_png_map_averages_the_colour_channels_as_map_server(tmp_path):
    from PIL import Image

    rgba = np.array([[[0, 0, 0, 255], [255, 255, 0, 255], [254, 254, 254, 0]]], dtype=np.uint8)
    Image.fromarray(rgba, "RGBA").save(tmp_path / "c.png")
    # yellow: mean 170 -> p = 0.33 -> unknown (Pillow's luma, 226, would say free);
    # alpha is not part of the mean: a transparent white pixel is free
    np.testing.assert_array_equal(_load(tmp_path, "c.png", (tmp_path / "c.png").read_bytes()), [[100, -1, 0]])


def test_saved_pgm_opens_in_pillow_with_map_saver_pixels(tmp_path):
    from PIL import Image

    pgm, _ = save_map(tmp_path / "m", OCC, 0.05, (0.0, 0.0, 0.0))
    with Image.open(pgm) as img:
        assert (img.format, img.mode, img.size) == ("PPM", "L", (3, 2))
        np.testing.assert_array_equal(np.asarray(img), np.frombuffer(PIXELS, np.uint8).reshape(2, 3))


def test_unknown_image_is_a_map_load_error(tmp_path):
    with pytest.raises(MapLoadError, match="cannot read image"):
        _load(tmp_path, "d.pgm", b"not an image at all")
def test_trinary_rule_by_hand():
    # p = (255 - v) / 255: 0 -> 1.0 (occupied), 89 -> 0.651 (occupied), 90 -> 0.647 (unknown),
    # 205 -> 0.196 (unknown: not below free_thresh 0.196), 206 -> 0.192 (free), 254 -> 0.004
    pixels = np.array([[0, 89, 90, 205, 206, 254]], dtype=np.uint8)
    np.testing.assert_array_equal(mapfile.trinary(pixels, negate=False), [[100, 100, -1, -1, 0, 0]])
    # negate: p = v / 255: 0 -> 0 (free), 89 and 90 -> 0.35 (unknown), 205 .. 254 -> 0.8 .. 1 (occupied)
    np.testing.assert_array_equal(mapfile.trinary(pixels, negate=True), [[0, -1, -1, 100, 100, 100]])


def test_occupancy_to_pixels_flips_rows_and_keeps_map_savers_thresholds():
    occ = np.array([[-1, 0, 25, 26], [64, 65, 100, 50]], dtype=np.int8)
    np.testing.assert_array_equal(mapfile.occupancy_to_pixels(occ), [[205, 0, 0, 205], [205, 254, 254, 205]])


def test_map_paths_from_a_stem_or_either_file(tmp_path):
    for name in ("m", "m.yaml", "m.pgm"):
        pgm, yml = save_map(tmp_path / name, OCC, 0.05, (0.0, 0.0, 0.0))
        assert (pgm.name, yml.name) == ("m.pgm", "m.yaml")


def test_read_image_header_forms_and_errors(tmp_path):
    (tmp_path / "a.pgm").write_bytes(b"P5 2\n# width above, height below\n1 255\n" + bytes([7, 9]))
    values, white = mapfile.read_image(tmp_path / "a.pgm")
    np.testing.assert_array_equal(values, [[7, 9]])
    assert white == 255
    for data in (b"P5\n3 3\n255\n" + bytes(4), b"P5\n3", b"P5\nx 3 255\n", b""):
        (tmp_path / "b.pgm").write_bytes(data)
        with pytest.raises(MapLoadError, match="cannot read image .*b.pgm"):
            mapfile.read_image(tmp_path / "b.pgm")


def test_saved_files_are_readable_by_others(tmp_path):
    pgm, yml = save_map(tmp_path / "m", OCC, 0.05, (0.0, 0.0, 0.0))
    assert pgm.stat().st_mode & 0o777 == 0o644 and yml.stat().st_mode & 0o777 == 0o644


# -- versioned saves: whatever moment a save is killed at, the YAML names an image that exists

SAVED = np.array([[-1, 0, 100], [0, 0, 100]], dtype=np.int8)


def _image(yaml_path):
    return yaml.safe_load(yaml_path.read_text())["image"]


def test_each_versioned_save_leaves_one_yaml_and_the_one_image_it_names(tmp_path):
    for k in range(5):
        occ = SAVED.copy()
        occ[0, 0] = 100 if k % 2 else -1
        pgm, yml = save_map(tmp_path / "m", occ, 0.05, (1.0, 2.0, 0.0), versioned=True)
        assert yml == tmp_path / "m.yaml" and pgm.name == _image(yml)
        assert pgm.name.startswith("m.saved-") and pgm.suffix == ".pgm"
        assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["m.yaml", pgm.name, "m.pgm"])
        np.testing.assert_array_equal(load_map(yml)[0], occ)
        # map_server's own file names keep working: m.pgm is the image the YAML names
        assert (tmp_path / "m.pgm").read_bytes() == pgm.read_bytes()


def test_a_save_failing_before_the_yaml_keeps_the_previous_pair(tmp_path, monkeypatch):
    _, yml = save_map(tmp_path / "m", SAVED, 0.05, (0.0, 0.0, 0.0), versioned=True)
    before = (yml.read_text(), _image(yml))
    real = mapfile._atomic_write_all

    def full_disk_for_yaml(files):
        if files[0][0].suffix == ".yaml":
            raise MapSaveError("cannot write map file m.yaml: No space left on device")
        real(files)

    monkeypatch.setattr(mapfile, "_atomic_write_all", full_disk_for_yaml)
    with pytest.raises(MapSaveError, match="No space"):
        save_map(tmp_path / "m", np.zeros((2, 3), np.int8), 0.05, (0.0, 0.0, 0.0), versioned=True)
    assert (yml.read_text(), _image(yml)) == before
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["m.yaml", before[1], "m.pgm"])
    np.testing.assert_array_equal(load_map(yml)[0], SAVED)


def test_what_killed_saves_left_is_removed_and_the_map_kept(tmp_path):
    _, yml = save_map(tmp_path / "m", SAVED, 0.05, (0.0, 0.0, 0.0), versioned=True)
    kept = _image(yml)
    leftovers = [".m.pgm.a1b2.tmp", ".m.yaml.c3d4.tmp", "m.saved-orphan.pgm", ".m-20260101-120000.pgm.e5f6.tmp"]
    for name in leftovers:
        (tmp_path / name).write_bytes(b"x" * 100)
    (tmp_path / "m.old.pgm").write_bytes(b"a user's own file")     # not ours: kept
    (tmp_path / ".m-notes.tmp").write_bytes(b"not a save of ours")  # no date after the stem: kept
    removed = remove_stale(tmp_path / "m")
    assert sorted(p.name for p in removed) == sorted(leftovers)
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["m.yaml", kept, "m.pgm", "m.old.pgm", ".m-notes.tmp"])
    np.testing.assert_array_equal(load_map(yml)[0], SAVED)


def test_the_plain_image_is_a_copy_where_hard_links_fail(tmp_path, monkeypatch):
    def no_links(src, dst):
        raise OSError(1, "Operation not permitted")

    monkeypatch.setattr(mapfile.os, "link", no_links)
    pgm, yml = save_map(tmp_path / "m", SAVED, 0.05, (0.0, 0.0, 0.0), versioned=True)
    assert (tmp_path / "m.pgm").read_bytes() == pgm.read_bytes()
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(["m.yaml", pgm.name, "m.pgm"])


def test_a_save_killed_at_any_step_leaves_a_yaml_naming_a_matching_image(tmp_path, monkeypatch):
    # the first save is the map in use; the second is killed before each of its renames
    first = np.full((2, 3), 100, np.int8)
    save_map(tmp_path / "m", first, 0.05, (0.0, 0.0, 0.0), versioned=True)
    real = mapfile.os.replace
    def killed_at(kill_at):
        calls = []

        def replace(src, dst):
            calls.append(dst)
            if len(calls) > kill_at:
                raise KeyboardInterrupt   # stands for SIGKILL: nothing after runs
            real(src, dst)
        return replace

    for kill_at in range(3):
        monkeypatch.setattr(mapfile.os, "replace", killed_at(kill_at))
        with pytest.raises(KeyboardInterrupt):
            save_map(tmp_path / "m", np.zeros((4, 5), np.int8), 0.1, (1.0, 1.0, 0.0), versioned=True)
        monkeypatch.setattr(mapfile.os, "replace", real)
        occ, res, origin = load_map(tmp_path / "m.yaml")
        assert (occ.shape, res, origin) in (((2, 3), 0.05, (0.0, 0.0, 0.0)), ((4, 5), 0.1, (1.0, 1.0, 0.0)))
        remove_stale(tmp_path / "m")
        assert not list(tmp_path.glob(".*.tmp"))
        save_map(tmp_path / "m", first, 0.05, (0.0, 0.0, 0.0), versioned=True)
