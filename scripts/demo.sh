#!/usr/bin/env bash
# make demo: a headless FastSLAM run on the built-in simulator (turtlebot3_world replica,
# scripted route, faster than real time). Results in out/demo/. Extra args go to roslaunch,
# e.g. scripts/demo.sh world:=office config:=$PWD/config/real.yaml
here="$(cd "$(dirname "$0")/.." && pwd)"
cd "$here"
export PATH="$here/.venv/bin:/usr/bin:/bin:$PATH"
source "$here/.ws/devel/setup.bash"   # not under 'set -u': it reads unset variables
set -eo pipefail
# A master of our own on a free port, so a running roscore is left alone.
port=$(/usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
export ROS_MASTER_URI="http://127.0.0.1:$port" ROS_HOME="$here/out/ros_home"
unset DISPLAY
mkdir -p out/demo
echo "demo: simulator + slam.py on turtlebot3_world (master $ROS_MASTER_URI); progress every 5 s"
timeout 900 roslaunch -p "$port" assign5 demo.launch out:="$here/out/demo" "$@" 2>&1 \
  | grep -vE '^(\.\.\. logging|started roslaunch|process\[|setting /run_id|ROS_MASTER_URI|SUMMARY|=+$|PARAMETERS|NODES|auto-starting|core service|\s*\*|\s*/|\s*$)' || true
test -s out/demo/metrics.json || { echo "demo: failed, see $ROS_HOME/log"; exit 1; }
echo "demo: done. Picture: out/demo/map.png"
