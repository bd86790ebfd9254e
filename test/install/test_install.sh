#!/usr/bin/env bash
# Install-space test: installs textile_handling from an existing build into a temporary prefix and checks
# that it works from there alone, in a clean environment (system paths plus the prefix's setup.bash; no
# devel space, no source tree). One JUnit test case per check:
#   install           catkin_make install -DCMAKE_INSTALL_PREFIX=<temporary>; the build's own prefix is
#                     restored afterwards (the build directory is reused, nothing is recompiled)
#   environment       rospack finds the package in the prefix; no ROS path, no installed text file and no
#                     installed binary's run path names the source or build tree; the binaries find the
#                     package's libraries in the prefix
#   launch_files      every installed launch file parses; every launch file it includes, every node it runs
#                     and every bag or YAML file it names resolve inside the prefix (or to another
#                     installed package under /usr)
#   tools             drape_db --help; drape_sim on a tiny scene (installed scene, installed material); material_lab
#   downstream_build  a project that uses only the installed headers and the catkin exports builds and
#                     runs (test/install/consumer: every installed header compiles; OpenCV, Eigen exported)
#   demo              demo.launch with its installed default bag and installed printer, against a tiny
#                     database built by the installed drape_db: the recognizer loads the database and the
#                     printer prints a result (success or not: a 2x2 grid is too coarse to promise one)
# Every step has a time limit; the whole test takes 2-3 minutes.
# Usage: bash test/install/test_install.sh WORKSPACE RESULT_XML   (WORKSPACE built, e.g. .build/ws)
set -uo pipefail
HERE="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
REPO="$(cd "$HERE/../.." && pwd)"
WS="$(cd "$1" && pwd)"
XML="$2"
BUILD="$WS/build"
TMP="$(mktemp -d "${TMPDIR:-/tmp}/textile_handling_install.XXXXXX")"
PREFIX="$TMP/install"
LOGS="$WS/test_install_logs"  # kept after the run for failures; replaced by the next run
rm -rf "$LOGS" && mkdir -p "$LOGS" "$(dirname "$XML")"
ORIGINAL_PREFIX="$(sed -n 's/^CMAKE_INSTALL_PREFIX:PATH=//p' "$BUILD/CMakeCache.txt")"
SHARE="$PREFIX/share/textile_handling"
BIN="$PREFIX/lib/textile_handling"
export HERE REPO WS TMP PREFIX SHARE BIN LOGS

# A command in a clean environment: only system paths (so no sourced devel space leaks in).
clean_env() {
  env -i HOME="$HOME" PATH=/usr/sbin:/usr/bin:/sbin:/bin LANG=C.UTF-8 ROS_HOME="$TMP/ros_home" \
    OMP_WAIT_POLICY=passive CCACHE_DIR="${CCACHE_DIR:-}" CCACHE_BASEDIR="${CCACHE_BASEDIR:-}" "$@"
}
# A bash snippet in the clean environment after sourcing the install space.
in_prefix() { clean_env bash -c "source '$PREFIX/setup.bash' && $1"; }
export -f clean_env in_prefix

NAMES=() OUTCOMES=() SECONDS_TAKEN=()
prefix_changed=0
install_ok=0

finish() {
  if ((prefix_changed)); then
    (cd "$WS" && clean_env cmake -DCMAKE_INSTALL_PREFIX="$ORIGINAL_PREFIX" "$BUILD") > "$LOGS/restore_prefix.log" 2>&1 ||
      echo "[install test] could not restore CMAKE_INSTALL_PREFIX=$ORIGINAL_PREFIX (see $LOGS/restore_prefix.log)"
  fi
  # JUnit XML: failure messages are the tails of the case logs, stripped of characters XML cannot hold.
  /usr/bin/python3 - "$XML" "$LOGS" "${#NAMES[@]}" "${NAMES[@]}" "${OUTCOMES[@]}" "${SECONDS_TAKEN[@]}" <<'EOF'
import re, sys
import xml.etree.ElementTree as ET
xml_path, logs, n = sys.argv[1], sys.argv[2], int(sys.argv[3])
names, outcomes, times = sys.argv[4:4 + n], sys.argv[4 + n:4 + 2 * n], sys.argv[4 + 2 * n:4 + 3 * n]
suite = ET.Element("testsuite", name="test_install", tests=str(n),
                   failures=str(sum(o != "ok" for o in outcomes)), errors="0")
for name, outcome, t in zip(names, outcomes, times):
    case = ET.SubElement(suite, "testcase", classname="textile_handling.test_install", name=name, time=t)
    if outcome != "ok":
        try:
            with open(f"{logs}/{name}.log", errors="replace") as f:
                tail = "".join(f.readlines()[-40:])
        except OSError:
            tail = ""
        tail = re.sub(r"\x1b\[[0-9;]*m", "", tail)
        tail = re.sub(r"[^\x09\x0a\x20-\ud7ff\ue000-\ufffd]", "", tail)
        ET.SubElement(case, "failure", message=outcome).text = tail
ET.ElementTree(suite).write(xml_path, encoding="utf-8", xml_declaration=True)
EOF
  rm -rf "$TMP"
}
trap finish EXIT

# run_case NAME TIME_LIMIT_S FUNCTION: runs the exported FUNCTION under a time limit, output to its log.
run_case() {
  local name=$1 limit=$2 fn=$3 start rc outcome
  start=$(date +%s)
  # (timeout signals its whole process group: roslaunch and its nodes too)
  timeout -k 10 "$limit" bash -c "$fn" > "$LOGS/$name.log" 2>&1
  rc=$?
  case $rc in
    0) outcome=ok ;;
    124|137) outcome="time limit of ${limit} s exceeded" ;;
    *) outcome="failed (exit $rc)" ;;
  esac
  NAMES+=("$name") OUTCOMES+=("$outcome") SECONDS_TAKEN+=("$(($(date +%s) - start))")
  echo "[install test] $name: $outcome ($(($(date +%s) - start)) s)"
  [ "$outcome" = ok ]
}

# ---- the checks (each runs in its own bash, which inherits no shell options: set -eo pipefail inside) ----

check_install() {
  set -eo pipefail
  cd "$WS"
  clean_env catkin_make install -DCMAKE_INSTALL_PREFIX="$PREFIX" -j1
  test -f "$PREFIX/setup.bash"
}

check_environment() {
  set -eo pipefail
  found=$(in_prefix 'rospack find textile_handling')
  echo "rospack find textile_handling: $found"
  [ "$found" = "$SHARE" ] || { echo "expected $SHARE"; exit 1; }
  in_prefix 'env' | grep -E '^(ROS_PACKAGE_PATH|CMAKE_PREFIX_PATH|LD_LIBRARY_PATH|PYTHONPATH)=' | tee "$TMP/env.txt"
  if grep -F -e "$REPO" -e "$WS" "$TMP/env.txt"; then echo "the environment names the source or build tree"; exit 1; fi
  if grep -rIl -F -e "$REPO" -e "$WS" "$PREFIX"; then echo "installed text files name the source or build tree"; exit 1; fi
  for exe in "$BIN"/* "$PREFIX"/lib/lib*.so; do
    if readelf -d "$exe" 2>/dev/null | grep -E 'R(UN)?PATH' | grep -F -e "$REPO" -e "$WS"; then
      echo "$exe: run path into the source or build tree"; exit 1
    fi
  done
  in_prefix "ldd '$BIN/drape_db' '$BIN/textile_recognizer'" | tee "$TMP/ldd.txt"
  if grep -E 'textile_handling.* => ' "$TMP/ldd.txt" | grep -v -F "=> $PREFIX/lib/"; then
    echo "a package library resolves outside the prefix"; exit 1
  fi
  if grep 'not found' "$TMP/ldd.txt"; then exit 1; fi
  # the message module print_recognition.py imports
  in_prefix "python3 -c 'import textile_handling.msg as m; print(m.__file__)'" | tee "$TMP/msg.txt"
  grep -q -F "$PREFIX/" "$TMP/msg.txt"
}

check_launch_files() {
  set -eo pipefail
  bag="$SHARE/test/data/towel_replay_a.bag"
  specs=()
  for launch in "$SHARE"/launch/*.launch; do
    if [ "$(basename "$launch")" = replay.launch ]; then specs+=("$launch,bag:=$bag"); else specs+=("$launch"); fi
  done
  in_prefix "/usr/bin/python3 '$HERE/check_launch_files.py' '$SHARE' '$PREFIX:/usr' ${specs[*]}" | tee "$TMP/nodes.txt"
  # demo.launch's default bag is the installed one
  grep "^demo.launch: player: " "$TMP/nodes.txt" | grep -q -F " $bag"
}

check_tools() {
  set -eo pipefail
  in_prefix "'$BIN/drape_db' --help" 2>&1 | tee "$TMP/help.txt"
  grep -q "usage: drape_db" "$TMP/help.txt"
  # a tiny scene: the installed towel scene at d = 4 cm with the installed cotton material file
  sed -e "s#^material: .*#material: $SHARE/data/materials/cotton.yaml#" -e "s#^spacing_m: .*#spacing_m: 0.04#" \
    "$SHARE/config/scenes/towel_corner.yaml" > "$TMP/tiny_scene.yaml"
  in_prefix "'$BIN/drape_sim' '$TMP/tiny_scene.yaml' --out '$TMP/sim' --until 0.05"
  for f in result.yaml rest_positions.csv rest_shape.png state.txt; do test -s "$TMP/sim/$f"; done
  # the material lab with the installed cotton file
  in_prefix "'$BIN/material_lab' --material '$SHARE/data/materials/cotton.yaml' --tests shear --directions warp --out '$TMP/lab'"
  for f in figures.csv shear_warp.csv shear.png; do test -s "$TMP/lab/$f"; done
}

check_downstream_build() {
  set -eo pipefail
  mkdir -p "$TMP/consumer"
  # one source including every installed header: each must compile with the exported include directories
  (cd "$PREFIX/include" && find textile_handling -name '*.h' | sort | sed 's/.*/#include <&>/') > "$TMP/consumer/all_headers.cpp"
  wc -l < "$TMP/consumer/all_headers.cpp"
  in_prefix "cmake -S '$HERE/consumer' -B '$TMP/consumer/build' -DCMAKE_BUILD_TYPE=Release \
    -DALL_HEADERS_FILE='$TMP/consumer/all_headers.cpp' && cmake --build '$TMP/consumer/build' -j1 && \
    '$TMP/consumer/build/install_consumer'"
}

check_demo() {
  set -eo pipefail
  db="$TMP/demo.sqlite"
  in_prefix "'$BIN/drape_db' build --db '$db' --textile towel --grid 2x2 --spacing 0.04 --threads 2 --quiet"
  port=$(/usr/bin/python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  # The printer ends the launch after one successful result, or after 45 s without one (exit 1).
  in_prefix "export ROS_MASTER_URI=http://localhost:$port; \
    roslaunch -p $port textile_handling demo.launch database_path:='$db' results:=1 timeout:=45" \
    > "$LOGS/demo_roslaunch.log" 2>&1 || true
  log=$(tr '\r' '\n' < "$LOGS/demo_roslaunch.log")
  grep -E "process\[|ready:|\[recognition\]|warning|ERROR|FATAL" <<< "$log" || true
  grep -q "ready: [1-9][0-9]* silhouettes" <<< "$log" || { echo "the recognizer did not load the database"; exit 1; }
  grep -q "\[recognition\] frame at" <<< "$log" || { echo "no result printed (log: $LOGS/demo_roslaunch.log)"; exit 1; }
}
export -f check_install check_environment check_launch_files check_tools check_downstream_build check_demo

echo "[install test] installing into $PREFIX (logs: $LOGS)"
prefix_changed=1
if run_case install 600 check_install; then install_ok=1; fi
# The build's own prefix back before anything else, so that an interrupted run leaves it right.
(cd "$WS" && clean_env cmake -DCMAKE_INSTALL_PREFIX="$ORIGINAL_PREFIX" "$BUILD") > "$LOGS/restore_prefix.log" 2>&1 &&
  prefix_changed=0
if ((install_ok)); then
  run_case environment 120 check_environment
  run_case launch_files 180 check_launch_files
  run_case tools 120 check_tools
  run_case downstream_build 300 check_downstream_build
  run_case demo 180 check_demo
fi
for o in "${OUTCOMES[@]}"; do [ "$o" = ok ] || exit 1; done
exit 0
