#!/usr/bin/env bash
# Builds the tests with AddressSanitizer + UndefinedBehaviorSanitizer (cmake -DACCEL_SANITIZE=ON)
# in a workspace of their own and runs them: core_tests (ROS-free) and ros_unit_tests (skip the
# latter with ACCEL_SANITIZE_ROS=0); a target that does not build fails the run. Any sanitizer report (ASan, LeakSanitizer, UBSan
# "runtime error") fails the run. Ends with one line "N passed, N failed" (gtest cases, plus one
# failure per binary that a sanitizer stopped or that reported an error).
#
# Environment:
#   ACCEL_SANITIZE_WS  workspace (default ~/accel_ws_asan). ACCEL_WS is NOT used, so the normal
#                      workspace is never reconfigured with sanitizer flags.
#   ACCEL_JOBS         parallel build jobs (default: all cores)
#   GTEST_FILTER       optional gtest filter for both binaries
#   ACCEL_CMAKE_ARGS   extra cmake arguments (appended after -DACCEL_SANITIZE=ON)
# Example: ACCEL_SANITIZE_WS=/tmp/ws_asan ACCEL_JOBS=1 tools/sanitize.sh
export ACCEL_WS="${ACCEL_SANITIZE_WS:-$HOME/accel_ws_asan}"
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
export ACCEL_CMAKE_ARGS="-DACCEL_SANITIZE=ON ${ACCEL_CMAKE_ARGS:-}"

log_dir="$ACCEL_WS/sanitize"
rm -rf "$log_dir"
mkdir -p "$log_dir/xml"

echo "[sanitize] building core_tests with ASan + UBSan in $ACCEL_WS"
if ! bash "$REPO_DIR/tools/build.sh" core_tests >"$log_dir/build_core.log" 2>&1; then
  tail -n 30 "$log_dir/build_core.log"
  echo "[sanitize] core_tests did not build (log: $log_dir/build_core.log)"
  echo "0 passed, 1 failed"
  exit 1
fi
binaries=(core_tests)
if [ "${ACCEL_SANITIZE_ROS:-1}" != 0 ]; then
  echo "[sanitize] building ros_unit_tests (ACCEL_SANITIZE_ROS=0 skips them)"
  if bash "$REPO_DIR/tools/build.sh" ros_unit_tests >"$log_dir/build_ros_unit.log" 2>&1; then
    binaries+=(ros_unit_tests)
  else
    # A target that does not build is a failure, not a skip.
    tail -n 30 "$log_dir/build_ros_unit.log"
    echo "[sanitize] ros_unit_tests did not build (log: $log_dir/build_ros_unit.log)"
    echo "0 passed, 1 failed"
    exit 1
  fi
fi

# ROS libraries for ros_unit_tests (and the node executables it runs).
source_workspace
# detect_leaks: LeakSanitizer at exit. halt_on_error for UBSan: the first undefined behaviour
# stops the binary with a stack trace instead of scrolling by.
# log_path: every process writes its reports to files (the tests run the node executables as
# child processes, whose stderr the tests capture), so no report is lost.
mkdir -p "$log_dir/reports"
export ASAN_OPTIONS="detect_leaks=1:strict_string_checks=1:check_initialization_order=1:log_path=$log_dir/reports/asan:${ASAN_OPTIONS:-}"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:log_path=$log_dir/reports/ubsan:${UBSAN_OPTIONS:-}"

extra_failed=0
for name in "${binaries[@]}"; do
  binary="$(find "$ACCEL_WS/devel" "$ACCEL_WS/build" -name "$name" -type f -perm -u+x 2>/dev/null | head -n 1)"
  if [ -z "$binary" ]; then
    echo "[sanitize] $name: binary not found"
    extra_failed=$((extra_failed + 1))
    continue
  fi
  echo "[sanitize] running $binary"
  args=(--gtest_output="xml:$log_dir/xml/$name.xml")
  [ -n "${GTEST_FILTER:-}" ] && args+=(--gtest_filter="$GTEST_FILTER")
  set +e
  "$binary" "${args[@]}" >"$log_dir/$name.log" 2>&1
  status=$?
  set -e
  grep -E "^\[  FAILED  \]|^\[==========\] .* ran|^\[  PASSED  \]" "$log_dir/$name.log" | awk '!seen[$0]++' || true
  report_files=("$log_dir"/reports/*)
  [ -e "${report_files[0]}" ] || report_files=()
  reports="$(grep -cE "ERROR: (AddressSanitizer|LeakSanitizer)|runtime error:" "$log_dir/$name.log" || true)"
  if [ "$reports" != 0 ] || [ ${#report_files[@]} != 0 ]; then
    echo "[sanitize] $name: sanitizer report(s) (${#report_files[@]} report file(s)):"
    grep -E -A12 "ERROR: (AddressSanitizer|LeakSanitizer)|runtime error:" "$log_dir/$name.log" | head -n 60
    for f in "${report_files[@]}"; do
      echo "--- $f"
      head -n 40 "$f"
      mv "$f" "$log_dir/$name.$(basename "$f").report"
    done
    extra_failed=$((extra_failed + 1))
  elif [ "$status" != 0 ] && [ ! -s "$log_dir/xml/$name.xml" ]; then
    echo "[sanitize] $name: exit status $status without a result file"
    tail -n 20 "$log_dir/$name.log"
    extra_failed=$((extra_failed + 1))
  fi
  echo "[sanitize] $name: full output in $log_dir/$name.log"
done

# gtest cases from the XML files; a binary stopped by a sanitizer leaves none, so it is counted
# above as one extra failure.
summary="$(python3 "$REPO_DIR/tools/summarize_tests.py" "$log_dir/xml" 2>&1 || true)"
echo "$summary" | sed '$d'
passed="$(echo "$summary" | tail -n 1 | sed -n 's/^\([0-9]*\) passed, \([0-9]*\) failed.*/\1/p')"
failed="$(echo "$summary" | tail -n 1 | sed -n 's/^\([0-9]*\) passed, \([0-9]*\) failed.*/\2/p')"
passed="${passed:-0}"
failed=$(( ${failed:-0} + extra_failed ))
echo "$passed passed, $failed failed"
[ "$failed" = 0 ] && [ "$passed" != 0 ]
