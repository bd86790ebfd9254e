#!/usr/bin/env bash
# Installs dependencies, builds, and runs every test of textile_handling: all gtest suites (no ROS
# master needed) and all rostest launch tests (rostest starts its own master). Ends with the line
# "N passed, N failed" over all test cases and exits non-zero if any failed or none ran.
# Usage: bash scripts/test.sh
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$REPO/scripts/setup.sh"

WS="$REPO/.build/ws"
# shellcheck disable=SC1091
set +u; source "$WS/devel/setup.bash"; set -u
RESULTS="$WS/build/test_results"
rm -rf "$RESULTS"
cd "$WS"
JOBS="${TEXTILE_HANDLING_JOBS:-$(nproc)}"
echo "[test] building and running tests"
# run_tests returns 0 even when tests fail; the result files are judged below.
set +e
catkin_make run_tests -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 -j"$JOBS" > "$WS/test.log" 2>&1
rc=$?
set -e
if [ $rc -ne 0 ]; then
  tail -n 80 "$WS/test.log"
  echo "[test] building or running the tests failed (exit $rc; full log: $WS/test.log)"
fi
/usr/bin/python3 "$REPO/scripts/summarize_test_results.py" "$RESULTS" || rc=1
exit $rc
