#!/usr/bin/env bash
# Prepares a fresh Debian 12 machine for assign5; safe to re-run.
#   1. Debian's ROS 1 packages (apt-get, as root or through sudo)
#   2. .venv from /usr/bin/python3 with the tools Debian lacks
#   3. a catkin workspace holding this package, built with catkin_make, outside the package
#      folder (scripts/ws.sh prints where: ~/.cache/assign5/ws-NAME-HASH)
set -eo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
cd "$here"
# Debian's ROS runs on /usr/bin/python3; a pyenv python3 first on PATH breaks catkin.
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:$PATH"

die() { echo "setup: $*" >&2; exit 1; }

if [ ! -r /etc/debian_version ] || ! command -v apt-get >/dev/null || ! command -v dpkg-query >/dev/null; then
  die "this machine is not Debian. Install ROS 1 (rospy, roslaunch, rostest, rosbag, tf2_ros, the sensor/nav/geometry/std/visualization message packages, catkin) with Python 3 and numpy by hand, then run 'make test' again. Needed Debian package names: $(grep -v '^#' scripts/debian-packages.txt | tr '\n' ' ')"
fi

mapfile -t pkgs < <(grep -v '^#' scripts/debian-packages.txt | sed '/^$/d')
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing Debian packages: ${missing[*]}"
  if [ "$(id -u)" -eq 0 ]; then sudo=(); 
  elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then sudo=(sudo -n);
  else die "need root to install: ${missing[*]}. Run as root: apt-get update && apt-get install -y ${missing[*]}"; fi
  "${sudo[@]}" apt-get update -qq || die "apt-get update failed (no network to Debian's mirrors?)"
  DEBIAN_FRONTEND=noninteractive "${sudo[@]}" apt-get install -y -qq --no-install-recommends "${missing[@]}" \
    || die "apt-get install failed for: ${missing[*]}"
fi

if [ ! -x .venv/bin/python ] || ! .venv/bin/python -c 'import rospy' 2>/dev/null; then
  echo "setup: creating .venv from /usr/bin/python3 (--system-site-packages)"
  rm -rf .venv
  /usr/bin/python3 -m venv --system-site-packages .venv
fi
if ! cmp -s scripts/requirements-dev.txt .venv/.requirements 2>/dev/null; then
  .venv/bin/python -m pip install -q --disable-pip-version-check -r scripts/requirements-dev.txt \
    || die "pip install of scripts/requirements-dev.txt failed"
  cp scripts/requirements-dev.txt .venv/.requirements
fi

# ROS Noetic's platform for make test: a Python 3.8 venv with Ubuntu 20.04's library
# versions (scripts/requirements-py38.txt); git and catkin ignore .venv38.
py38=""
for c in "${PYTHON38:-}" "${PYENV_ROOT:-$HOME/.pyenv}"/versions/3.8*/bin/python3.8 "$(command -v python3.8)"; do
  [ -n "$c" ] && "$c" -c 'import sys; assert sys.version_info[:2] == (3, 8)' 2>/dev/null && { py38=$c; break; }
done
if [ -z "$py38" ]; then
  echo "setup: no Python 3.8 (set PYTHON38=/path/to/python3.8): make test's Python 3.8 run will fail" >&2
elif ! cmp -s scripts/requirements-py38.txt .venv38/.requirements 2>/dev/null; then
  echo "setup: creating .venv38 from $py38 (Ubuntu 20.04's numpy, Pillow, tqdm, matplotlib, PyYAML)"
  rm -rf .venv38
  "$py38" -m venv .venv38 || die "$py38 -m venv .venv38 failed"
  touch .venv38/CATKIN_IGNORE .venv38/rospack_nosubdirs
  .venv38/bin/python -m pip install -q --disable-pip-version-check -r scripts/requirements-py38.txt \
    || die "pip install of scripts/requirements-py38.txt into .venv38 failed"
  cp scripts/requirements-py38.txt .venv38/.requirements
fi

# The workspace links the whole package folder; it lies outside it (scripts/ws.sh).
ws="$(bash scripts/ws.sh)"
# The same requirements kept as wheels beside it: make test sets up a fresh copy of the
# package (test/user) and must manage without a network (isolated test runs).
wheels="$(dirname "$ws")/wheels"
for venv in .venv .venv38; do
  req=scripts/requirements-dev.txt; [ "$venv" = .venv38 ] && req=scripts/requirements-py38.txt
  [ -x "$venv/bin/python" ] && ! cmp -s "$req" "$wheels/.$(basename "$req")" 2>/dev/null || continue
  if "$venv/bin/python" -m pip download -q --disable-pip-version-check -d "$wheels" -r "$req" >/dev/null 2>&1; then
    cp "$req" "$wheels/.$(basename "$req")"
  else
    echo "setup: could not keep the wheels of $req in $wheels (no network?): make test's user paths need them"
  fi
done
if [ -d .ws ]; then   # the old place, inside the package: rosrun would find its copies of slam.py
  echo "setup: removing .ws/ (the workspace now lives in $ws)"
  rm -rf .ws
fi
mkdir -p "$ws/src"
[ "$(readlink "$ws/src/assign5")" = "$here" ] || ln -sfn "$here" "$ws/src/assign5"
stamp="$ws/.built"
if [ ! -f "$stamp" ] || [ -n "$(find CMakeLists.txt package.xml setup.py src -maxdepth 1 -newer "$stamp" -print -quit)" ]; then
  echo "setup: catkin_make in $ws"
  (cd "$ws" && catkin_make -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCATKIN_ENABLE_TESTING=ON > build.log 2>&1) \
    || { tail -30 "$ws/build.log"; die "catkin_make failed (full log: $ws/build.log)"; }
  touch "$stamp"
fi
echo "setup: ok"
