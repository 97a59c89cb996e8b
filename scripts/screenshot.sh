#!/usr/bin/env bash
# make screenshot: RViz (rviz/slam.rviz) on a virtual display during a simulator run,
# saved to docs/rviz.png. Needs Debian's rviz, xvfb and imagemagick (installed if missing).
here="$(cd "$(dirname "$0")/.." && pwd)"
cd "$here"
export PATH="$here/.venv/bin:/usr/bin:/bin:$PATH"
need=()
for p in rviz xvfb xauth imagemagick; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || need+=("$p")
done
if [ ${#need[@]} -gt 0 ]; then
  [ "$(id -u)" -eq 0 ] || { echo "screenshot: install as root first: apt-get install -y ${need[*]}"; exit 1; }
  DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need[@]}" >/dev/null || { echo "screenshot: apt-get install ${need[*]} failed"; exit 1; }
fi
source "$(bash "$here/scripts/ws.sh")/devel/setup.bash"
set -eo pipefail
port=$(/usr/bin/python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')
export ROS_MASTER_URI="http://127.0.0.1:$port" ROS_HOME="$here/out/ros_home"
wait_s=${SCREENSHOT_AFTER:-60}
mkdir -p docs out
xvfb-run -a -s "-screen 0 1280x860x24" bash -c "
  roslaunch -p $port assign5 burger.launch world:=turtlebot3_world \
      route:=$here/worlds/turtlebot3_world.route.yaml speed:=2.0 seed:=0 > out/screenshot.log 2>&1 &
  launch=\$!
  sleep $wait_s
  import -window root docs/rviz.png
  kill -INT \$launch; wait \$launch || true
"
echo "screenshot: docs/rviz.png"
