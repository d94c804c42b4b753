#!/usr/bin/env bash
# Builds the libFuzzer targets in fuzz/ with clang (AddressSanitizer + UBSan) and runs each for
# FUZZ_SECONDS (default 60). A crashing input is written to fuzz/crashes/; commit it (minimized:
# `<binary> -minimize_crash=1 -runs=10000 <input>`) under fuzz/corpus/<target>/ so the regression
# tests replay it (test/core/dwells/fuzz_regression_test.cpp, test/ros_unit/bag_fuzz_regression_test.cpp).
#
# Targets (FUZZ_TARGETS, default "position_table bag_input"):
#   position_table  the position-table CSV reader (core sources only)
#   bag_input       bag reading (src/ros/bag_input.cpp: the chunk scan, the structure check and
#                   the rosbag fallback), linked against the system ROS libraries (rosbag_storage,
#                   roscpp_serialization, rostime, cpp_common, console_bridge, roslz4, boost) and
#                   ceres; include flags and the generated message headers come from the catkin
#                   workspace $ACCEL_WS (configured here if it is not yet).
# Environment: FUZZ_SECONDS, FUZZ_TARGETS, FUZZ_BUILD_DIR (default /tmp/accel_intrinsics_fuzz),
#   FUZZ_JOBS (parallel libFuzzer workers per target, default 1), ACCEL_WS, ACCEL_JOBS.
# Exit status: 0 when every target ran its time without a finding; 1 when a target crashed,
# hung, ran out of memory or a sanitizer reported (the input is in fuzz/crashes/), or a target
# did not build.
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
command -v clang++ >/dev/null || { apt-get install -y -qq clang libclang-rt-14-dev >/dev/null; }
seconds="${FUZZ_SECONDS:-60}"
targets="${FUZZ_TARGETS:-position_table bag_input}"
workers="${FUZZ_JOBS:-1}"
out="${FUZZ_BUILD_DIR:-/tmp/accel_intrinsics_fuzz}"
mkdir -p "$out" "$REPO_DIR/fuzz/crashes"
findings=0
sanitize=(-fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined)
flags=(-std=c++17 -O1 -g "${sanitize[@]}" -I"$REPO_DIR/include" -I/usr/include/eigen3)

# Runs target $1 (binary $out/$1_fuzz) on a working copy of fuzz/corpus/$1 for $seconds.
run_target() {
  local name="$1"; shift
  local work_corpus="$out/corpus_$name"
  mkdir -p "$work_corpus"
  cp -n "$REPO_DIR"/fuzz/corpus/"$name"/* "$work_corpus"/ 2>/dev/null || true
  echo "[fuzz] running ${name}_fuzz for ${seconds}s ($workers worker(s))"
  local extra=()
  [ "$workers" -gt 1 ] && extra=(-fork="$workers" -ignore_crashes=1)
  local status=0
  "$out/${name}_fuzz" -max_total_time="$seconds" -print_final_stats=1 "${extra[@]}" "$@" \
    -artifact_prefix="$REPO_DIR/fuzz/crashes/" "$work_corpus" >"$out/$name.log" 2>&1 || status=$?
  grep -E "^stat::number_of_executed_units|^stat::average_exec_per_sec|^stat::peak_rss_mb|SUMMARY|Test unit written|^#[0-9]+ *DONE" \
    "$out/$name.log" | tail -n 8
  # libFuzzer exits non-zero on a crash, a timeout or an out-of-memory; with -fork the crashes
  # are ignored, so the log decides too.
  if [ "$status" -ne 0 ] || grep -qE "^SUMMARY: |Test unit written|ERROR: libFuzzer" "$out/$name.log"; then
    echo "[fuzz] $name: FINDING (exit status $status; inputs in $REPO_DIR/fuzz/crashes/)"
    findings=$((findings + 1))
  fi
  echo "[fuzz] $name: full log in $out/$name.log"
}

if [[ " $targets " == *" position_table "* ]]; then
  core_sources=("$REPO_DIR/src/core/dwells/position_table.cpp" "$REPO_DIR/src/core/model/protocol.cpp"
                "$REPO_DIR/src/core/model/effects.cpp" "$REPO_DIR/src/core/model/model.cpp"
                "$REPO_DIR/src/core/model/constants.cpp")
  echo "[fuzz] building position_table_fuzz"
  clang++ "${flags[@]}" "$REPO_DIR/fuzz/position_table_fuzz.cpp" "${core_sources[@]}" -o "$out/position_table_fuzz" \
    || { echo "[fuzz] position_table_fuzz did not build"; exit 1; }
  run_target position_table -max_len=4096
fi

if [[ " $targets " == *" bag_input "* ]]; then
  # Include flags (ROS, pluginlib, Eigen, the generated GimbalCommand.h) and ceres's link line
  # from the workspace's build of accel_intrinsics_ros.
  ros_dir="$ACCEL_WS/build/accel_intrinsics/CMakeFiles/accel_intrinsics_ros.dir"
  if [ ! -f "$ros_dir/flags.make" ] || [ ! -f "$ACCEL_WS/devel/include/accel_intrinsics/GimbalCommand.h" ]; then
    echo "[fuzz] configuring $ACCEL_WS and generating the message headers"
    bash "$REPO_DIR/tools/build.sh" accel_intrinsics_generate_messages_cpp >"$out/build_messages.log" 2>&1 \
      || { tail -n 20 "$out/build_messages.log"; exit 1; }
  fi
  read -r -a includes <<<"$(sed -n 's/^CXX_INCLUDES = //p' "$ros_dir/flags.make")"
  # Ceres and its dependencies: on the core library's link line (or, with older CMakeLists, the
  # ROS library's).
  ceres_libs=()
  while read -r lib; do ceres_libs+=("$lib"); done < <(cat "$ros_dir/link.txt" "${ros_dir%_ros.dir}_core.dir/link.txt" \
    2>/dev/null | tr ' ' '\n' \
    | grep -E "ceres|glog|gflags|blas|lapack|amd|colamd|cholmod|cxsparse|spqr|suitesparse|atlas|tbb" \
    | awk '!seen[$0]++')
  [ ${#ceres_libs[@]} -gt 0 ] || ceres_libs=(-lceres -lglog -lgflags -llapack -lblas)
  ros_libs=(-lrosbag_storage -lroslz4 -llz4 -lroscpp_serialization -lrostime -lcpp_common -lconsole_bridge
            -lclass_loader -lboost_filesystem -lboost_system -lboost_regex -lpthread -fopenmp)
  bag_sources=("$REPO_DIR/src/ros/bag_input.cpp" "$REPO_DIR/src/ros/bag_format.cpp"
               "$REPO_DIR/src/ros/bag_topics.cpp" "$REPO_DIR/src/ros/conversions.cpp"
               "$REPO_DIR/fuzz/bag_input_fuzz.cpp")
  # The whole core (conversions.cpp reaches the calibration run's status names).
  for core in "$REPO_DIR"/src/core/*/*.cpp; do bag_sources+=("$core"); done
  obj_dir="$out/bag_input_obj"
  mkdir -p "$obj_dir"
  echo "[fuzz] building bag_input_fuzz (${#bag_sources[@]} sources, -j${ACCEL_JOBS:-$(nproc)})"
  objects=()
  pids=()
  for source in "${bag_sources[@]}"; do
    object="$obj_dir/$(basename "$source" .cpp).o"
    objects+=("$object")
    # Rebuilt when the source is newer (headers: delete $obj_dir to force a full rebuild).
    if [ ! -f "$object" ] || [ "$source" -nt "$object" ]; then
      clang++ -std=c++17 -O1 -g -fsanitize=fuzzer-no-link,address,undefined -fno-sanitize-recover=undefined \
        "${includes[@]}" -c "$source" -o "$object" &
      pids+=($!)
      if [ ${#pids[@]} -ge "${ACCEL_JOBS:-$(nproc)}" ]; then wait "${pids[0]}" || exit 1; pids=("${pids[@]:1}"); fi
    fi
  done
  for pid in "${pids[@]}"; do wait "$pid" || exit 1; done
  clang++ "${sanitize[@]}" "${objects[@]}" "${ros_libs[@]}" "${ceres_libs[@]}" -o "$out/bag_input_fuzz" \
    2> >(grep -v "^/usr/bin/ld: warning" >&2) || { echo "[fuzz] bag_input_fuzz did not build"; exit 1; }
  seeds="$REPO_DIR/fuzz/corpus/bag_input"
  if ! ls "$seeds"/run_*.bag >/dev/null 2>&1; then
    echo "[fuzz] writing the seed bags into $seeds"
    mkdir -p "$seeds"
    clang++ -std=c++17 -O1 "${includes[@]}" "$REPO_DIR/fuzz/make_bag_seeds.cpp" "${ros_libs[@]}" \
      -o "$out/make_bag_seeds" 2> >(grep -v "^/usr/bin/ld: warning" >&2)
    "$out/make_bag_seeds" "$seeds"
  fi
  # -timeout: a hang is a finding; -rss_limit_mb: so is a corrupt length that makes a reader
  # allocate gigabytes. Seeds stay under 20 kB.
  run_target bag_input -max_len=20000 -timeout=10 -rss_limit_mb=2048
fi

if [ "$findings" -gt 0 ]; then
  echo "[fuzz] $findings target(s) with findings"
  exit 1
fi
echo "[fuzz] no findings"
