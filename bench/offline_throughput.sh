#!/usr/bin/env bash
# Driver of bench/offline_bench (offline_fit on a bag of one million IMU messages vs. a plain
# Python rosbag loop and vs. real-time replay). Builds it in $ACCEL_WS if needed and runs it;
# extra arguments go to offline_bench (--bag PATH, --messages N, --runs R, --no-python,
# --benchmark_filter=...). Prints `name: value unit` lines, then the in-process benchmarks.
#   ACCEL_WS=/tmp/ws_offline bash bench/offline_throughput.sh
source "$(dirname "${BASH_SOURCE[0]}")/../tools/common.sh"
bench="$ACCEL_WS/devel/lib/accel_intrinsics/offline_bench"
if [ ! -x "$bench" ] || [ ! -x "$ACCEL_WS/devel/lib/accel_intrinsics/offline_fit" ]; then
  bash "$REPO_DIR/tools/build.sh" offline_fit offline_bench
fi
source_workspace
echo "machine: $(nproc) cores, $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //')"
exec "$bench" "$@"
