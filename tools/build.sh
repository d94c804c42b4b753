#!/usr/bin/env bash
# Builds the package (and its tests) in the catkin workspace $ACCEL_WS (default ~/accel_ws).
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
mkdir -p "$ACCEL_WS/src"
link="$ACCEL_WS/src/accel_intrinsics"
if [ "$(readlink -f "$link" 2>/dev/null)" != "$REPO_DIR" ]; then
  rm -rf "$link"
  ln -s "$REPO_DIR" "$link"
fi
cd "$ACCEL_WS"
set +u
source /opt/ros/*/setup.bash 2>/dev/null || true
set -u
jobs="${ACCEL_JOBS:-$(nproc)}"
echo "[build] catkin_make in $ACCEL_WS (-j$jobs)"
# Targets default to "all"; e.g. `tools/build.sh core_tests` builds just the core tests.
targets=("$@")
[ ${#targets[@]} -gt 0 ] || targets=(all)
catkin_make -DPYTHON_EXECUTABLE=/usr/bin/python3 -DCMAKE_BUILD_TYPE=Release \
  ${ACCEL_CMAKE_ARGS:-} -j"$jobs" "${targets[@]}"
