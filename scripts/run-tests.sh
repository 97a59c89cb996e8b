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
  # Lint and types first: each counts as one test (rules in ruff.toml and mypy.ini).
  for check in "ruff check ." "mypy"; do
    if python -m $check > "$outdir/${check%% *}.log" 2>&1; then passed=$((passed + 1))
    else echo "FAILED $check:"; cat "$outdir/${check%% *}.log"; failed=$((failed + 1)); fi
  done
  python -m pytest -p no:cacheprovider --junitxml="$outdir/pytest.xml" "$@"
  count_junit $? "$outdir/pytest.xml"
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
      echo "FAILED rostest $name (exit $rc), last lines of $outdir/$name.log:"; tail -40 "$outdir/$name.log"
      failed=$((failed + (e + fl > 0 ? e + fl : 1))); passed=$((passed + (n - e - fl > 0 ? n - e - fl : 0)))
    else
      echo "ok: $n tests"; passed=$((passed + n))
    fi
  done
fi

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ] && [ "$passed" -gt 0 ]
