#!/usr/bin/env bash
# make demo: a headless FastSLAM run on the built-in simulator (turtlebot3_world replica,
# scripted route, faster than real time). Results in out/demo/. Extra args go to roslaunch,
# e.g. scripts/demo.sh world:=office config:=$PWD/config/real.yaml
here="$(cd "$(dirname "$0")/.." && pwd)"
cd "$here"
export PATH="$here/.venv/bin:/usr/bin:/bin:$PATH"
source "$(bash "$here/scripts/ws.sh")/devel/setup.bash"   # not under 'set -u': it reads unset variables
set -eo pipefail
# A master of our own on a free port, so a running roscore is left alone.
port=$(/usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
export ROS_MASTER_URI="http://127.0.0.1:$port" ROS_HOME="$here/out/ros_home"
unset DISPLAY
rm -rf out/demo; mkdir -p out/demo
world=turtlebot3_world
for a in "$@"; do case "$a" in world:=*) world="${a#world:=}" ;; esac; done
echo "demo: simulator + slam.py on $world (own master at $ROS_MASTER_URI), faster than real time"
roslaunch -p "$port" assign5 demo.launch "$@" > out/demo/launch.log 2>&1 &
launch=$!
trap 'kill -INT $launch 2>/dev/null; wait $launch 2>/dev/null' EXIT
for i in $(seq 100); do rosnode list >/dev/null 2>&1 && break; sleep 0.2; done
status=0
timeout 900 rosrun assign5 run_report.py _out:="$here/out/demo" \
  _world_file:="$(rospack find assign5)/worlds/$world.yaml" || status=$?
test $status -eq 0 -a -s out/demo/metrics.json || { echo "demo: failed (exit $status); see out/demo/launch.log"; exit 1; }
echo "demo: done. Picture: out/demo/map.png, log: out/demo/launch.log"
