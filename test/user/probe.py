#!/usr/bin/env python3
"""Looks at a running ROS graph for test/user and prints one JSON line. Runs with the
user's ROS (/usr/bin/python3, workspace sourced), so the test process needs no master.

    probe.py message TOPIC TYPE TIMEOUT        first message: frame, stamp, size
    probe.py route_done TIMEOUT                 the simulator's route_done became true
    probe.py moved TIMEOUT DIST                 /ground_truth moved DIST metres from its first pose
    probe.py frames RVIZ TIMEOUT                each RViz display's message frame reaches the fixed frame in tf
    probe.py param NAME                         a parameter's value
    probe.py call SERVICE TIMEOUT               a std_srvs/Trigger call
    probe.py clock_and_tf TIMEOUT               /clock and the stamp of map->odom
"""
import json
import math
import sys
import time

import rospy


def init() -> None:
    end = time.monotonic() + 60
    while True:
        try:
            rospy.init_node("probe", anonymous=True, disable_signals=True)
            rospy.get_param("/run_id")  # the master answers
            return
        except Exception:
            if time.monotonic() > end:
                raise
            time.sleep(0.5)


def msg_type(name: str):
    pkg, kind = name.split("/")
    module = __import__(f"{pkg}.msg", fromlist=[kind])
    return getattr(module, kind)


def summary(msg) -> dict:
    out = {}
    header = getattr(msg, "header", None)
    if header is not None:
        out.update(frame=header.frame_id, stamp=header.stamp.to_sec())
    for name in ("poses", "data", "ranges"):
        if hasattr(msg, name):
            value = getattr(msg, name)
            out[name] = len(value) if name != "data" or not isinstance(value, (int, float)) else value
    if hasattr(msg, "data") and isinstance(msg.data, (int, float)):
        out["value"] = msg.data
    if hasattr(msg, "info") and hasattr(msg.info, "width"):
        out.update(width=msg.info.width, height=msg.info.height, known=sum(1 for v in msg.data if v >= 0))
    return out


def main(args: list) -> dict:
    init()
    cmd = args[0]
    if cmd == "message":
        msg = rospy.wait_for_message(args[1], msg_type(args[2]), timeout=float(args[3]))
        return summary(msg)
    if cmd == "route_done":
        from std_msgs.msg import Bool

        end = time.monotonic() + float(args[1])
        while time.monotonic() < end:
            if rospy.wait_for_message("/route_done", Bool, timeout=end - time.monotonic()).data:
                return {"done": True}
        return {"done": False}
    if cmd == "moved":
        from nav_msgs.msg import Odometry

        first = rospy.wait_for_message("/ground_truth", Odometry, timeout=30).pose.pose.position
        end = time.monotonic() + float(args[1])
        while time.monotonic() < end:
            p = rospy.wait_for_message("/ground_truth", Odometry, timeout=30).pose.pose.position
            if math.hypot(p.x - first.x, p.y - first.y) >= float(args[2]):
                return {"moved": math.hypot(p.x - first.x, p.y - first.y)}
        return {"moved": 0.0}
    if cmd == "frames":
        return frames(args[1], float(args[2]))
    if cmd == "param":
        return {"value": rospy.get_param(args[1], None)}
    if cmd == "call":
        from std_srvs.srv import Trigger

        rospy.wait_for_service(args[1], timeout=float(args[2]))
        res = rospy.ServiceProxy(args[1], Trigger)()
        return {"success": res.success, "message": res.message}
    if cmd == "clock_and_tf":
        import tf2_ros
        from rosgraph_msgs.msg import Clock

        clock = rospy.wait_for_message("/clock", Clock, timeout=float(args[1])).clock.to_sec()
        buf = tf2_ros.Buffer()
        tf2_ros.TransformListener(buf)
        t = buf.lookup_transform("map", "odom", rospy.Time(0), rospy.Duration(float(args[1])))
        return {"clock": clock, "tf_stamp": t.header.stamp.to_sec()}
    raise SystemExit(f"unknown probe {cmd}")


def frames(rviz: str, timeout: float) -> dict:
    """Every display with a topic: a message arrives and tf links its frame to the fixed frame."""
    import tf2_ros
    import yaml

    cfg = yaml.safe_load(open(rviz))["Visualization Manager"]
    fixed = cfg["Global Options"]["Fixed Frame"]
    buf = tf2_ros.Buffer()
    tf2_ros.TransformListener(buf)
    kinds = {"rviz/Map": "nav_msgs/OccupancyGrid", "rviz/PoseArray": "geometry_msgs/PoseArray",
             "rviz/LaserScan": "sensor_msgs/LaserScan", "rviz/Path": "nav_msgs/Path",
             "rviz/Odometry": "nav_msgs/Odometry"}
    out = {}
    for d in cfg["Displays"]:
        if "Topic" not in d:
            continue
        try:
            msg = rospy.wait_for_message(d["Topic"], msg_type(kinds[d["Class"]]), timeout=timeout)
            frame = msg.header.frame_id
            ok = buf.can_transform(fixed, frame, rospy.Time(0), rospy.Duration(timeout))
            out[d["Name"]] = f"{frame}: ok" if ok else f"{frame}: no tf to {fixed}"
        except Exception as err:
            out[d["Name"]] = f"no message on {d['Topic']}: {err}"
    return out


if __name__ == "__main__":
    try:
        print(json.dumps(main(sys.argv[1:])))
    except Exception as err:
        print(json.dumps({"error": f"{type(err).__name__}: {err}"}))
