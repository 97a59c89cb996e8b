"""Messages serialised by numpy send exactly the bytes genpy sends for the plain message."""
from __future__ import annotations

import io

import numpy as np
import pytest
import rospy
from nav_msgs.msg import OccupancyGrid, Path
from nav_msgs.srv import GetMapResponse
from std_msgs.msg import Header

from assign5.convert import occupancy_msgs, path_msg
from assign5.packed import PackedMapResponse, PathCache, pack_poses
from fastslam.filter.history import History

pytestmark = pytest.mark.ros


def wire(msg) -> bytes:
    buff = io.BytesIO()
    msg.serialize(buff)
    return buff.getvalue()


def same_path(packed, plain) -> None:
    """The same message on the wire: the same length and fields, the quaternions to the
    last bits (numpy's sin and cos, packed's, round otherwise than math's, genpy's
    message's, on CPUs with AVX-512)."""
    a, b = wire(packed), wire(plain)
    assert len(a) == len(b)
    got, want = Path(), Path()
    got.deserialize(a)
    want.deserialize(b)
    assert got.header == want.header and len(got.poses) == len(want.poses)
    for g, w in zip(got.poses, want.poses):
        assert g.header == w.header and g.pose.position == w.pose.position
        q, r = g.pose.orientation, w.pose.orientation
        np.testing.assert_allclose([q.x, q.y, q.z, q.w], [r.x, r.y, r.z, r.w], rtol=0, atol=1e-15)


def test_a_packed_map_is_the_plain_map_on_the_wire():
    occ = np.random.default_rng(0).integers(-1, 101, (30, 40)).astype(np.int8)
    msg, meta = occupancy_msgs(occ, 0.05, np.array([-1.5, 2.0]), "map", rospy.Time(7, 5))
    plain = OccupancyGrid(header=msg.header, info=meta, data=occ.ravel().tolist())
    assert wire(msg) == wire(plain)
    back = OccupancyGrid()
    back.deserialize(wire(msg))
    assert back.data == tuple(occ.ravel().tolist()) and (back.info.width, back.info.height) == (40, 30)
    assert wire(PackedMapResponse(map=msg)) == wire(GetMapResponse(map=plain))


def test_packed_poses_are_a_plain_path_on_the_wire():
    traj = np.array([[10.5, 0.0, 0.0, 0.0], [11.0, 1.0, 0.5, 0.2], [1e9 + 0.123456789, -3.0, 2.0, -3.1]])
    plain = path_msg(traj, "map", rospy.Time(12))
    cache = PathCache("map")
    packed = cache.message(traj, 0, plain.header)
    same_path(packed, plain)
    back = Path()
    back.deserialize(wire(packed))
    assert [p.header.stamp for p in back.poses] == [p.header.stamp for p in plain.poses]
    assert pack_poses(traj[:0], "map") == b""


def test_the_cache_packs_settled_rows_once_and_follows_the_best_particle(monkeypatch):
    import fastslam.filter.history as history_module

    monkeypatch.setattr(history_module, "PRUNE_EVERY", 4)
    rng = np.random.default_rng(1)
    h, cache = History(), PathCache("odom_combined")
    for k in range(60):
        poses = np.stack([np.full(4, float(k)), rng.normal(size=4), rng.normal(size=4)], axis=1)
        h.append(0.1 * k + 1.0, poses, rng.integers(0, 4, 4).astype(np.intp) if k % 5 else np.zeros(4, np.intp))
        best = int(rng.integers(0, 4))
        tail = h.path(best, cache.rows)
        msg = cache.message(tail, h.settled, Header(stamp=rospy.Time(k), frame_id="odom_combined"))
        same_path(msg, path_msg(h.path(best), "odom_combined", rospy.Time(k)))
    assert cache.rows == h.settled > 30
    cache.forget()
    header = Header(stamp=rospy.Time(1), frame_id="odom_combined")
    same_path(cache.message(h.path(0, cache.rows), h.settled, header), path_msg(h.path(0), "odom_combined",
                                                                                rospy.Time(1)))
