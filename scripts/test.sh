#!/usr/bin/env bash
# Installs dependencies, builds, and runs every test of textile_handling: all gtest suites (no ROS
# master needed), all rostest launch tests (rostest starts its own master) and the install-space test
# (test/install/test_install.sh: the package installed into a temporary prefix and run from there).
# Ends with the line "N passed, N failed" over all test cases and exits non-zero if any failed or none ran.
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
# One throw-away PostgreSQL server for every test that needs one (the database suites' PostgreSQL runs,
# the libpq tests); each test works in a schema of its own. Stopped and removed on exit.
PG_DIR="$(mktemp -d /tmp/th_test_postgres.XXXXXX)"
stop_postgres() { bash "$REPO/scripts/throwaway_postgres.sh" stop "$PG_DIR" > /dev/null 2>&1 || true; rm -rf "$PG_DIR"; }
trap stop_postgres EXIT
if TH_TEST_POSTGRES_URL="$(bash "$REPO/scripts/throwaway_postgres.sh" start "$PG_DIR")"; then
  export TH_TEST_POSTGRES_URL
  echo "[test] PostgreSQL test server at $TH_TEST_POSTGRES_URL"
else
  echo "[test] could not start the PostgreSQL test server; the tests that need it will fail"
fi
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
# The install-space test reconfigures this build directory (install prefix) and restores it, so it runs
# after run_tests, never beside it. Its JUnit file is counted with the others; a run that wrote none
# (killed) counts as a failure through a MISSING- file.
echo "[test] install-space test (test/install/test_install.sh)"
INSTALL_XML="$RESULTS/textile_handling/script-test_install.xml"
bash "$REPO/test/install/test_install.sh" "$WS" "$INSTALL_XML" || true
if [ ! -f "$INSTALL_XML" ]; then
  mkdir -p "$RESULTS/textile_handling"
  echo '<testsuite name="test_install" tests="1" failures="1"><testcase classname="textile_handling.test_install" name="missing_results"><failure message="test_install.sh wrote no results"/></testcase></testsuite>' \
    > "$RESULTS/textile_handling/MISSING-script-test_install.xml"
fi
/usr/bin/python3 "$REPO/scripts/summarize_test_results.py" "$RESULTS" || rc=1
exit $rc
