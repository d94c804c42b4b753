# Shared by the tools/ scripts: paths and the ROS environment. Source it, don't run it.
# The catkin workspace lives outside the repository (ACCEL_WS, default ~/accel_ws) with a
# symlink to this checkout in its src/.
set -euo pipefail
REPO_DIR="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
ACCEL_WS="${ACCEL_WS:-$HOME/accel_ws}"
# Debian's ROS Python modules live in /usr/bin/python3; a pyenv python3 on PATH lacks them.
export PATH="/usr/bin:/bin:/usr/sbin:/sbin:$PATH"
export PYTHONNOUSERSITE=1
unset PYTHONHOME PYTHONPATH 2>/dev/null || true

source_workspace() {
  set +u
  # shellcheck disable=SC1091
  source "$ACCEL_WS/devel/setup.bash"
  set -u
}

# Runs tools/build.sh with its output in $ACCEL_WS/build.log; on failure shows the errors.
build_quietly() {
  mkdir -p "$ACCEL_WS"
  echo "[build] building in $ACCEL_WS (log: $ACCEL_WS/build.log) ..."
  if ! bash "$REPO_DIR/tools/build.sh" "$@" > "$ACCEL_WS/build.log" 2>&1; then
    grep -E "error|Error" "$ACCEL_WS/build.log" | head -n 30 >&2
    tail -n 20 "$ACCEL_WS/build.log" >&2
    echo "[build] FAILED (full log: $ACCEL_WS/build.log)" >&2
    return 1
  fi
  echo "[build] done"
}

# Runs every test of the built workspace (gtests, then rostests) and prints the closing line
# "N passed, N failed"; returns 1 when anything failed. Results land in build/test_results.
run_all_tests() {
  cd "$ACCEL_WS"
  source_workspace
  rm -rf "$ACCEL_WS/build/test_results/accel_intrinsics"
  # run_tests exits 0 even when tests fail; catkin_test_results gives the verdict below.
  catkin_make -DPYTHON_EXECUTABLE=/usr/bin/python3 run_tests_accel_intrinsics -j1 2>&1 \
    | tee "$ACCEL_WS/run_tests.log" \
    | grep -E "^\[ *(RUN|  OK|  FAILED|  PASSED|==========) |FAILURE|ERROR|Traceback" || true
  python3 "$REPO_DIR/tools/summarize_tests.py" "$ACCEL_WS/build/test_results"
}
