#!/usr/bin/env bash
# Builds the node tests with ThreadSanitizer (cmake -DACCEL_TSAN=ON) in a workspace of their own
# and runs them: ros_unit_tests (they start the node executables as child processes) and rostests
# of the multithreaded calibration node (IMU callbacks on the transport threads with
# immediate_imu, the fit worker thread, services). A target that does not build fails the run;
# so does any ThreadSanitizer report ("WARNING: ThreadSanitizer", in a log or a report file of any
# process, nodes included; tools/tsan.supp suppresses reports inside the uninstrumented ROS
# libraries). Ends with one line "N passed, N failed" (gtest cases and rostests,
# plus one failure per binary or rostest with a report).
#
# Environment:
#   ACCEL_TSAN_WS      workspace (default ~/accel_ws_tsan). ACCEL_WS is NOT used, so the normal
#                      workspace is never reconfigured with sanitizer flags.
#   ACCEL_JOBS         parallel build jobs (default: all cores)
#   GTEST_FILTER       gtest filter for ros_unit_tests (default: all)
#   TSAN_ROSTESTS      rostests to run, NAME or NAME:ARG,ARG with launch arguments (default
#                      "calibration_node analysis_node:time_scale:=3.0 kill_in_dwell"; "" = none)
#   ACCEL_TSAN_UNIT=0  skip ros_unit_tests
#   ACCEL_CMAKE_ARGS   extra cmake arguments (appended after -DACCEL_TSAN=ON)
# Example: ACCEL_TSAN_WS=/tmp/ws_tsan ACCEL_JOBS=2 bash tools/tsan.sh
export ACCEL_WS="${ACCEL_TSAN_WS:-$HOME/accel_ws_tsan}"
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
export ACCEL_CMAKE_ARGS="-DACCEL_TSAN=ON -DACCEL_SANITIZE=OFF ${ACCEL_CMAKE_ARGS:-}"
# An entry NAME:ARG,ARG passes launch arguments: analysis_node runs its stand at 3x instead of
# 10x (the instrumented accelerometer node cannot feed 10x; a dwell then arrives too late).
rostests="${TSAN_ROSTESTS-calibration_node analysis_node:time_scale:=3.0 kill_in_dwell}"

log_dir="$ACCEL_WS/tsan"
rm -rf "$log_dir"
mkdir -p "$log_dir/xml" "$log_dir/reports"

targets=()
[ "${ACCEL_TSAN_UNIT:-1}" != 0 ] && targets+=(ros_unit_tests)
for entry in $rostests; do targets+=("rostest_${entry%%:*}"); done
# The Python messages: rostests run scripts/supervise.
[ -n "$rostests" ] && targets+=(accel_intrinsics_generate_messages_py)
if [ ${#targets[@]} = 0 ]; then
  echo "[tsan] nothing to run"
  echo "0 passed, 1 failed"
  exit 1
fi
echo "[tsan] building ${targets[*]} with ThreadSanitizer in $ACCEL_WS"
if ! bash "$REPO_DIR/tools/build.sh" "${targets[@]}" >"$log_dir/build.log" 2>&1; then
  # A target that does not build is a failure, not a skip.
  tail -n 30 "$log_dir/build.log"
  echo "[tsan] the build failed (log: $log_dir/build.log)"
  echo "0 passed, 1 failed"
  exit 1
fi

source_workspace
# log_path: every process (the test binaries and the nodes they or roslaunch start) writes its
# reports to a file of its own, so none is lost in a node's log. second_deadlock_stack: both
# stacks of a lock-order inversion.
# suppressions: tools/tsan.supp (reports inside the uninstrumented ROS libraries only).
# exitcode=0: a report does not change exit statuses (tests that check a node's exit status
# stay meaningful); reports are counted from the files.
export TSAN_OPTIONS="log_path=$log_dir/reports/tsan:second_deadlock_stack=1:history_size=4:exitcode=0:suppressions=$REPO_DIR/tools/tsan.supp:${TSAN_OPTIONS:-}"
export ROS_LOG_DIR="$log_dir/ros_log"

extra_failed=0
passed=0
failed=0
# Moves the report files written since the last call to $log_dir/$1.*.report; prints them.
collect_reports() {
  local name="$1" files=("$log_dir"/reports/*)
  [ -e "${files[0]}" ] || return 0
  echo "[tsan] $name: ${#files[@]} ThreadSanitizer report file(s):"
  for f in "${files[@]}"; do
    echo "--- $f"
    head -n 60 "$f"
    mv "$f" "$log_dir/$name.$(basename "$f").report"
  done
  return 1
}

if [ "${ACCEL_TSAN_UNIT:-1}" != 0 ]; then
  binary="$(find "$ACCEL_WS/devel" "$ACCEL_WS/build" -name ros_unit_tests -type f -perm -u+x 2>/dev/null | head -n 1)"
  if [ -z "$binary" ]; then
    echo "[tsan] ros_unit_tests: binary not found"
    extra_failed=$((extra_failed + 1))
  else
    echo "[tsan] running $binary"
    args=(--gtest_output="xml:$log_dir/xml/ros_unit_tests.xml")
    [ -n "${GTEST_FILTER:-}" ] && args+=(--gtest_filter="$GTEST_FILTER")
    set +e
    "$binary" "${args[@]}" >"$log_dir/ros_unit_tests.log" 2>&1
    status=$?
    set -e
    grep -E "^\[  FAILED  \]|^\[==========\] .* ran|^\[  PASSED  \]" "$log_dir/ros_unit_tests.log" | awk '!seen[$0]++' || true
    if ! collect_reports ros_unit_tests || grep -q "WARNING: ThreadSanitizer" "$log_dir/ros_unit_tests.log"; then
      extra_failed=$((extra_failed + 1))
    elif [ "$status" != 0 ] && [ ! -s "$log_dir/xml/ros_unit_tests.xml" ]; then
      echo "[tsan] ros_unit_tests: exit status $status without a result file"
      tail -n 20 "$log_dir/ros_unit_tests.log"
      extra_failed=$((extra_failed + 1))
    fi
    summary="$(python3 "$REPO_DIR/tools/summarize_tests.py" "$log_dir/xml" 2>&1 || true)"
    echo "$summary" | sed '$d'
    p="$(echo "$summary" | tail -n 1 | sed -n 's/^\([0-9]*\) passed, \([0-9]*\) failed.*/\1/p')"
    f="$(echo "$summary" | tail -n 1 | sed -n 's/^\([0-9]*\) passed, \([0-9]*\) failed.*/\2/p')"
    passed=$((passed + ${p:-0}))
    failed=$((failed + ${f:-0}))
  fi
fi

for entry in $rostests; do
  t="${entry%%:*}"
  launch_args=()
  [ "$entry" != "$t" ] && IFS=, read -r -a launch_args <<<"${entry#*:}"
  echo "[tsan] rostest $t ${launch_args[*]}"
  set +e
  rostest accel_intrinsics "$t.test" "${launch_args[@]}" >"$log_dir/rostest_$t.log" 2>&1
  status=$?
  set -e
  if [ "$status" = 0 ]; then
    passed=$((passed + 1))
  else
    echo "[tsan] rostest $t failed (exit status $status; log: $log_dir/rostest_$t.log)"
    grep -E "FAILURE|FAILED|Failure" "$log_dir/rostest_$t.log" | head -n 10 || true
    failed=$((failed + 1))
  fi
  if ! collect_reports "rostest_$t"; then
    extra_failed=$((extra_failed + 1))
  fi
done

failed=$((failed + extra_failed))
echo "$passed passed, $failed failed"
[ "$failed" = 0 ] && [ "$passed" != 0 ]
