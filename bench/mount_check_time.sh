#!/usr/bin/env bash
# A mount check timed on the simulated stand (docs/hardware.md, Mount check; goal: under one
# minute): a private roscore on $BENCH_ROS_PORT (default 11431), launch/test_stand.launch in real
# time (time_scale 1, the default protocol: 5 s phase changes, 1 s moves, 0.5 s settling), then
# `supervise --check-mount`, whose wall time from its start to its verdict is printed as
#   mount_check_wall_s: VALUE s
# Exits non-zero (and prints no figure) when the check does not say "mount correct".
# Used by bench/run; the workspace must hold gimbal_controller, accelerometer, calibration and
# check_mount.
source "$(dirname "${BASH_SOURCE[0]}")/../tools/common.sh"
source_workspace
PORT="${BENCH_ROS_PORT:-11431}"
LOG="${BENCH_LOG_DIR:-$ACCEL_WS/bench_logs}"
mkdir -p "$LOG"
export ROS_MASTER_URI="http://localhost:$PORT" ROS_HOSTNAME=localhost
export ROS_HOME="$LOG/ros_home" ROS_LOG_DIR="$LOG/ros_log"
unset ROS_IP
if rosparam get /run_id >/dev/null 2>&1; then
  echo "mount_check: port $PORT already has a ROS master (set BENCH_ROS_PORT)" >&2
  exit 1
fi
launch_pid=""
cleanup() {
  if [ -n "$launch_pid" ] && kill -0 "$launch_pid" 2>/dev/null; then
    kill -INT "$launch_pid" 2>/dev/null
    for _ in $(seq 100); do kill -0 "$launch_pid" 2>/dev/null || break; sleep 0.2; done
    kill -0 "$launch_pid" 2>/dev/null && kill -TERM "$launch_pid" 2>/dev/null
    wait "$launch_pid" 2>/dev/null
  fi
}
trap cleanup EXIT
roslaunch -p "$PORT" accel_intrinsics test_stand.launch steps:=24 time_scale:=1.0 output:=log \
  output_dir:="$LOG/mount_check" >"$LOG/mount_check_launch.log" 2>&1 &
launch_pid=$!
for _ in $(seq 150); do
  rosservice list 2>/dev/null | grep -q '^/gimbal_controller/resume$' && break
  sleep 0.2
done
start=$(date +%s.%N)
rosrun accel_intrinsics supervise --check-mount --timeout 120 >"$LOG/mount_check.out" 2>&1
rc=$?
end=$(date +%s.%N)
if [ "$rc" != 0 ] || ! grep -q "mount correct" "$LOG/mount_check.out"; then
  echo "mount_check: supervise --check-mount exit $rc (log: $LOG/mount_check.out)" >&2
  exit 1
fi
awk -v a="$start" -v b="$end" 'BEGIN { printf "mount_check_wall_s: %.3g s\n", b - a }'
