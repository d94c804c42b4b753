#!/usr/bin/env bash
# Installs, builds and runs every test (core gtests without a roscore, then rostests).
# Ends with one line "N passed, N failed".
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
bash "$REPO_DIR/tools/install_deps.sh"
build_quietly all tests
cd "$ACCEL_WS"
source_workspace
rm -rf "$ACCEL_WS/build/test_results/accel_intrinsics"
jobs="${ACCEL_JOBS:-$(nproc)}"
# run_tests exits 0 even when tests fail; catkin_test_results gives the verdict below.
catkin_make -DPYTHON_EXECUTABLE=/usr/bin/python3 run_tests_accel_intrinsics -j1 2>&1 \
  | tee "$ACCEL_WS/run_tests.log" | grep -E "^\[ *(RUN|  OK|  FAILED|  PASSED|==========) |FAILURE|ERROR|Traceback" || true
python3 "$REPO_DIR/tools/summarize_tests.py" "$ACCEL_WS/build/test_results"
