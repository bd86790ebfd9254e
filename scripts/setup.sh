#!/usr/bin/env bash
# Installs every dependency of textile_handling from Debian 12's own packages (idempotent: nothing is
# installed twice) and builds the package in a catkin workspace under .build/ws (incremental).
# Usage: bash scripts/setup.sh
set -euo pipefail
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"

PACKAGES=(
  build-essential cmake pkg-config
  ros-base-dev catkin libroscpp-dev libcv-bridge-dev libimage-transport-dev
  libtf2-ros-dev libtf2-eigen-dev libpcl-dev libpcl-conversions-dev
  librosbag-dev librostest-dev python3-rostest ros-message-generation
  libroslib-dev libvisualization-msgs-dev libtf2-geometry-msgs-dev libtf2-msgs-dev
  python3-geometry-msgs  # print_recognition.py imports the RecognitionResult message (PoseArray)
  libsqlite3-dev libeigen3-dev libopencv-dev libyaml-cpp-dev libgtest-dev googletest
  libpq-dev postgresql  # the PostgreSQL backend; tests start a throw-away server (scripts/throwaway_postgres.sh)
  openmpi-bin libopenmpi-dev  # the MPI build farm (drape_db build --mpi)
)

missing=()
for p in "${PACKAGES[@]}"; do
  if ! dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed"; then
    missing+=("$p")
  fi
done
if ((${#missing[@]})); then
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  echo "[setup] installing ${#missing[@]} Debian packages: ${missing[*]}"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
else
  echo "[setup] all Debian packages already installed"
fi

# A catkin workspace whose only package is this repository (linked, so edits build in place).
WS="$REPO/.build/ws"
mkdir -p "$WS/src"
ln -sfn "$REPO" "$WS/src/textile_handling"
cd "$WS"
JOBS="${TEXTILE_HANDLING_JOBS:-$(nproc)}"
echo "[setup] building in $WS with $JOBS jobs"
# The pyenv python3 first on PATH has no catkin_pkg: use Debian's.
catkin_make -DPYTHON_EXECUTABLE=/usr/bin/python3 -DPython3_EXECUTABLE=/usr/bin/python3 -DCMAKE_BUILD_TYPE=Release -j"$JOBS" > "$WS/build.log" 2>&1 || {
  tail -n 60 "$WS/build.log"; echo "[setup] build FAILED (full log: $WS/build.log)"; exit 1; }
echo "[setup] build OK"
