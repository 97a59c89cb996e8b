#!/usr/bin/env bash
# Runs every test: ruff, mypy, pytest (ROS-free core, integration), the README's commands
# (test/user) in a fresh home folder, then each rostest graph test.
# Ends with one line 'N passed, M failed' and exits non-zero on any failure.
# Usage: scripts/run-tests.sh [pytest|user|rostest|all] [extra pytest args...]
# TEST_OUT=dir chooses the results folder; ROSTESTS="test/ros/a.test ..." runs only those.
set -o pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
cd "$here"
export PATH="$here/.venv/bin:/usr/bin:/bin:$PATH"
what="${1:-all}"; shift || true
outdir="${TEST_OUT:-$here/out/test-results}"; rm -rf "$outdir"; mkdir -p "$outdir"
passed=0; failed=0

# Adds the results of a pytest run (exit code $1, junit file $2) to the counts.
count_junit() {
  local rc=$1 p f
  read -r p f < <(python - "$2" <<'PY'
import sys, xml.etree.ElementTree as ET
try:
    root = ET.parse(sys.argv[1]).getroot()
except Exception:
    print(0, 1); sys.exit()
suites = [root] if root.tag == "testsuite" else list(root)
t = sum(int(s.get("tests", 0)) for s in suites)
bad = sum(int(s.get("failures", 0)) + int(s.get("errors", 0)) for s in suites)
skip = sum(int(s.get("skipped", 0)) for s in suites)
print(t - bad - skip, bad + skip)   # a skipped test is not a passed one
PY
)
  [ "$rc" -ne 0 ] && [ "$f" = 0 ] && f=1
  passed=$((passed + p)); failed=$((failed + f))
}

if [ "$what" = all ] || [ "$what" = pytest ]; then
  # Lint, types and the oldest Python first: each counts as one test (rules in ruff.toml,
  # mypy.ini; vermin knows which Python added each syntax, module, function and keyword).
  for check in "ruff check ." "mypy" "vermin -q -t=3.8- --violations --no-tips src bench test setup.py"; do
    if $check > "$outdir/${check%% *}.log" 2>&1; then passed=$((passed + 1))
    else echo "FAILED $check:"; cat "$outdir/${check%% *}.log"; failed=$((failed + 1)); fi
  done
  python -m pytest -p no:cacheprovider --junitxml="$outdir/pytest.xml" "$@"
  count_junit $? "$outdir/pytest.xml"
  # ROS Noetic's platform: the ROS-free tests again under Python 3.8 with Ubuntu 20.04's
  # numpy 1.17.4, Pillow, tqdm, matplotlib and PyYAML (.venv38, made by scripts/setup.sh).
  if [ -x .venv38/bin/python ]; then
    echo "=== Python 3.8 (ROS Noetic's platform): $(.venv38/bin/python -c 'import sys, numpy; print(sys.version.split()[0], "numpy", numpy.__version__)')"
    # These test modules import rospy (through the module they test): not even collected there.
    .venv38/bin/python -m pytest -p no:cacheprovider -m "not ros" \
      --ignore-glob='*/test_convert.py' --ignore-glob='*/test_run_report.py' --ignore-glob='*/test_sim_node.py' \
      --ignore-glob='*/test_packed.py' --ignore-glob='*/test_mounts.py' \
      --junitxml="$outdir/pytest-py38.xml" "$@"
    count_junit $? "$outdir/pytest-py38.xml"
  else
    echo "FAILED Python 3.8 run: no .venv38 (scripts/setup.sh found no Python 3.8; set PYTHON38)"
    failed=$((failed + 1))
  fi
fi

# The README's commands as a new user types them, in a fresh home folder (test/user; its
# home folders are pytest's tmp_path, outside the package folder).
if [ "$what" = all ] || [ "$what" = user ]; then
  echo "=== user paths (test/user): the README's commands in a fresh catkin workspace"
  python -m pytest -p no:cacheprovider --junitxml="$outdir/user.xml" test/user "$@"
  count_junit $? "$outdir/user.xml"
fi

if [ "$what" = all ] || [ "$what" = rostest ]; then
  # devel/setup.bash reads unset variables: never source it under 'set -u'.
  source "$(bash "$here/scripts/ws.sh")/devel/setup.bash"
  export ROS_HOME="$outdir/ros_home" ROS_LOG_DIR="$outdir/ros_log"
  for t in ${ROSTESTS:-test/ros/*.test}; do
    [ -e "$t" ] || continue
    name=$(basename "$t" .test)
    echo "=== rostest $name"
    timeout 900 rostest --text assign5 "$name.test" > "$outdir/$name.log" 2>&1
    rc=$?
    n=$(sed -n 's/^.* \* TESTS: \([0-9]*\).*/\1/p' "$outdir/$name.log" | tail -1)
    e=$(sed -n 's/^ \* ERRORS: \([0-9]*\).*/\1/p' "$outdir/$name.log" | tail -1)
    fl=$(sed -n 's/^ \* FAILURES: \([0-9]*\).*/\1/p' "$outdir/$name.log" | tail -1)
    n=${n:-0}; e=${e:-0}; fl=${fl:-0}
    grep -q 'RESULT: SUCCESS' "$outdir/$name.log" || rc=${rc/#0/1}
    if [ $rc -ne 0 ] || [ "$n" = 0 ]; then
      echo "FAILED rostest $name (exit $rc); what failed, then the last lines of $outdir/$name.log:"
      grep -A40 -E '^(FAIL|ERROR): ' "$outdir/$name.log" | grep -v 'TF_REPEATED_DATA\|buffer_core.cpp' | head -80
      tail -40 "$outdir/$name.log"
      failed=$((failed + (e + fl > 0 ? e + fl : 1))); passed=$((passed + (n - e - fl > 0 ? n - e - fl : 0)))
    else
      echo "ok: $n tests"; passed=$((passed + n))
    fi
  done
fi

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ] && [ "$passed" -gt 0 ]
