"""What the clocked graph tests share: a test node that owns /clock (at wall speed from
START; it can jump), publishes odometry, a static tf base_footprint -> base_scan (and a
rear-facing base_scan_rear) and scans of a ring of walls 1 m away, and watches slam.py's
poses, trajectory, ~stats, map metadata and /rosout. Conditions are waited on with
deadlines, never with sleeps.
"""
import json
import math
import threading
import time
import unittest

import rospkg
import rospy
import tf2_ros
from geometry_msgs.msg import PoseWithCovarianceStamped, TransformStamped
from nav_msgs.msg import MapMetaData, Odometry, Path
from rosgraph_msgs.msg import Clock, Log
from sensor_msgs.msg import LaserScan
from std_msgs.msg import String

START = 1000.0  # [s] sim time when the test starts its clock
PKG = rospkg.RosPack().get_path("assign5")


class SimClock:
    """/clock at 200 Hz, at wall speed from START; jump() moves it on or back."""

    def __init__(self):
        self.pub = rospy.Publisher("/clock", Clock, queue_size=10)
        self.lock = threading.Lock()
        self.offset = START - time.monotonic()
        threading.Thread(target=self._run, daemon=True).start()

    def now(self):
        with self.lock:
            return rospy.Time.from_sec(self.offset + time.monotonic())

    def jump(self, seconds):
        with self.lock:
            self.offset += seconds
        self.pub.publish(Clock(self.now()))

    def _run(self):
        while not rospy.is_shutdown():
            try:
                self.pub.publish(Clock(self.now()))
            except rospy.ROSException:      # closed by the shutdown under way
                return
            time.sleep(0.005)


class Connected(rospy.SubscribeListener):
    """Wakes the test when slam.py connects to one of its publishers."""

    def __init__(self, cond):
        super().__init__()
        self.cond = cond

    def peer_subscribe(self, topic_name, topic_publish, peer_publish):
        with self.cond:
            self.cond.notify_all()


def ring(n=360):
    return [1.0] * n


def own_names(name):
    """A second slam.py named name, its map, service and tf apart from the one under test."""
    return [f"__name:={name}", f"map:={name}/map", f"map_metadata:={name}/map_metadata",
            f"particles:={name}/particles", f"dynamic_map:={name}/dynamic_map", f"/tf:=/{name}/tf"]


class ClockedCase(unittest.TestCase):
    NODE = "clocked_test"

    @classmethod
    def setUpClass(cls):
        rospy.init_node(cls.NODE)
        cls.clock = SimClock()
        cls.changed = threading.Condition()
        listener = Connected(cls.changed)
        cls.pub_scan = rospy.Publisher("scan", LaserScan, queue_size=200, subscriber_listener=listener)
        cls.pub_odom = rospy.Publisher("odom", Odometry, queue_size=200, subscriber_listener=listener)
        cls.static = tf2_ros.StaticTransformBroadcaster()
        cls.mounts = [cls.mount("base_scan", 0.0), cls.mount("base_scan_rear", math.pi)]
        cls.static.sendTransform(cls.mounts)
        cls.poses, cls.path, cls.stats, cls.meta, cls.logs = {}, None, None, None, []
        cls.stats_count = 0
        rospy.Subscriber("slam/pose", PoseWithCovarianceStamped, cls._on_pose, queue_size=200)
        rospy.Subscriber("slam/trajectory", Path, cls._keep("path"), queue_size=5)
        rospy.Subscriber("slam/stats", String, cls._on_stats, queue_size=5)
        rospy.Subscriber("map_metadata", MapMetaData, cls._keep("meta"), queue_size=5)
        rospy.Subscriber("/rosout", Log, cls._on_log, queue_size=500)
        cls.x = 0.0
        cls.last_stamp = rospy.Time(0)
        cls.wait(lambda: cls.pub_scan.get_num_connections() and cls.pub_odom.get_num_connections(), 30,
                 "slam.py subscribing to scan and odom")

    @staticmethod
    def mount(frame, yaw):
        t = TransformStamped()
        t.header.stamp = rospy.Time(0)
        t.header.frame_id, t.child_frame_id = "base_footprint", frame
        t.transform.rotation.z, t.transform.rotation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        return t

    @classmethod
    def wait(cls, predicate, timeout, what):
        with cls.changed:
            ok = cls.changed.wait_for(predicate, timeout)
        assert ok, f"no {what} within {timeout} s"

    @classmethod
    def _on_pose(cls, msg):
        with cls.changed:
            cls.poses[round(msg.header.stamp.to_sec(), 6)] = msg.pose.pose.position.x
            cls.changed.notify_all()

    @classmethod
    def _keep(cls, name):
        def keep(msg):
            with cls.changed:
                setattr(cls, name, msg)
                cls.changed.notify_all()
        return keep

    @classmethod
    def _on_stats(cls, msg):
        with cls.changed:
            cls.stats = json.loads(msg.data)
            cls.stats_count += 1
            cls.changed.notify_all()

    @classmethod
    def _on_log(cls, msg):
        if msg.name == "/slam":
            with cls.changed:
                cls.logs.append(msg)
                cls.changed.notify_all()

    # -- messages ---------------------------------------------------------------------
    def odom(self, x, stamp):
        o = Odometry()
        o.header.stamp = stamp
        o.header.frame_id, o.child_frame_id = "odom", "base_footprint"
        o.pose.pose.position.x = x
        o.pose.pose.orientation.w = 1.0
        self.pub_odom.publish(o)

    def scan(self, stamp, frame="base_scan", ranges=None, angle_min=-math.pi, sweep=2 * math.pi):
        s = LaserScan()
        s.header.stamp, s.header.frame_id = stamp, frame
        ranges = ring() if ranges is None else ranges
        s.angle_min, s.angle_increment = angle_min, sweep / len(ranges)
        s.angle_max = angle_min + (len(ranges) - 1) * s.angle_increment
        s.range_min, s.range_max = 0.12, 3.5
        s.ranges = ranges
        self.pub_scan.publish(s)

    def stamp(self):
        """The clock's now, but at least 2 ms after the last stamp."""
        type(self).last_stamp = max(self.clock.now(), self.last_stamp + rospy.Duration(0.002))
        return self.last_stamp

    def updated(self, stamp, timeout=5.0):
        key = round(stamp.to_sec(), 6)
        with self.changed:
            return self.changed.wait_for(lambda: key in self.poses, timeout)

    def step(self, dx=0.002, timeout=5.0, **scan):
        """Odometry dx further, then a scan at the same stamp; the stamp if an update came out."""
        type(self).x += dx
        now = self.stamp()
        self.odom(self.x, now)
        self.scan(now, **scan)
        return now if self.updated(now, timeout) else None

    def ready(self):
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            stamp = self.step(timeout=2.0)
            if stamp:
                return stamp
        self.fail("slam.py never updated on good input")

    def path_after(self, stamp, timeout=10.0):
        """The first trajectory published that holds the pose of the scan stamped stamp
        (good steps until then); after the clock went back, older paths end later."""
        def holds(path):
            for p in reversed(path.poses if path is not None else []):
                t = p.header.stamp.to_sec()
                if abs(t - stamp.to_sec()) < 1e-6:
                    return True
                if t < stamp.to_sec():
                    return False
            return False

        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            with self.changed:
                if holds(self.path):
                    return self.path
            self.step()
        self.fail(f"no trajectory published after {stamp.to_sec():.2f}")

    def stats_when(self, predicate, what, timeout=10.0):
        self.wait(lambda: self.stats is not None and predicate(self.stats), timeout, what)
        return self.stats

    @staticmethod
    def rss_mb(node="/slam"):
        """The resident memory of a node's process [MB], asked of the node itself for its pid."""
        import xmlrpc.client

        import rosgraph

        uri = rosgraph.Master(rospy.get_name()).lookupNode(node)
        _, _, pid = xmlrpc.client.ServerProxy(uri).getPid(rospy.get_name())
        with open(f"/proc/{pid}/status") as f:
            return next(int(line.split()[1]) for line in f if line.startswith("VmRSS")) / 1024

    def fresh_stats(self, timeout=10.0):
        """~stats made after this call (the second message from now)."""
        seen = self.stats_count
        self.wait(lambda: self.stats_count >= seen + 2, timeout, "fresh ~stats")
        return self.stats

    def logged(self, text, level=None):
        with self.changed:
            return [m.msg for m in self.logs if text in m.msg and (level is None or m.level == level)]

    def long_path(self, poses=6):
        stamp = self.ready()
        while len(self.path_after(stamp).poses) < poses:
            stamp = self.step() or stamp
        return len(self.path.poses)
