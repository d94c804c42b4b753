#!/usr/bin/env bash
# The lab archive on the simulated stand (docs/design.md section 13, issue 25): a simulated device
# that drifts (config/simulated_device.yaml device/aging) is calibrated RUNS times, AGE_STEP_DAYS
# apart, each run by `supervise --archive URL --time DATE`; then `history` must find the drift
# of |u| (significant, rate within 3 of its standard uncertainties of the simulated one) and give
# a recalibrate_by date. The simulated clock is not a calendar, hence --time: the date of each
# run is the simulated device's age. The calibration node's own `archive` parameter puts every
# result into a second archive (time: the wall clock), which must hold RUNS records.
#
#   bash tools/archive_drift_demo.sh [URL]      (default: a SQLite file in a temporary directory)
#
# Needs the built workspace (the sourced one, else $ACCEL_WS; tools/build.sh calibration
# accelerometer gimbal_controller sim_clock accel_intrinsics_generate_messages_py). Ends with
# "archive drift demo: OK" or a FAILED line (exit 1). test/python/test_drift_on_stand.py runs it.
sourced_pythonpath=${PYTHONPATH:-}
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
# run_tests (test/python/test_drift_on_stand.py) runs it in the sourced workspace already
if rospack find accel_intrinsics >/dev/null 2>&1 && [ -n "$sourced_pythonpath" ]; then
  export PYTHONPATH=$sourced_pythonpath  # the workspace's messages (common.sh unset it)
else
  source_workspace
fi

RUNS=${RUNS:-5}
AGE_STEP_DAYS=${AGE_STEP_DAYS:-30}
RATE_U=${RATE_U:-2e-6}  # relative drift of |u| per day
work=${ARCHIVE_DEMO_DIR:-$(mktemp -d /tmp/archive_drift_demo.XXXXXX)}
mkdir -p "$work"
URL=${1:-sqlite:///$work/archive.db}
NODE_URL=sqlite:///$work/node_archive.db
port=$((20000 + RANDOM % 20000))
export ROS_MASTER_URI=http://localhost:$port

printf 'archive: %s\narchive_device: SIM-AGING-1\narchive_rig: sim_stand\n' "$NODE_URL" \
  >"$work/node_archive.yaml"
for ((i = 0; i < RUNS; i++)); do
  age=$((i * AGE_STEP_DAYS))
  date=$(date -u -d "2026-01-01 + $age days" +%Y-%m-%dT10:00:00Z)
  printf 'device:\n  aging:\n    age_days: %s\n    responsivity_per_day: [%s, 0.0, 0.0]\nseed: %s\n' \
    "$age" "$(printf '%.6e' "$RATE_U")" "$((i + 1))" >"$work/aging_$age.yaml"  # YAML 1.1: a float needs its dot
  echo "[demo] run $((i + 1))/$RUNS: device age $age days, date $date"
  roslaunch -p "$port" accel_intrinsics test_stand.launch steps:=12 time_scale:=20 \
    output:=log output_dir:="$work/run_$age" device_extra_config:="$work/aging_$age.yaml" \
    calibration_extra_config:="$work/node_archive.yaml" \
    >"$work/roslaunch_$age.log" 2>&1 &
  launch_pid=$!
  for ((wait_s = 0; wait_s < 60; wait_s++)); do  # the master and the parameters are up
    rosparam get /calibration/output_dir >/dev/null 2>&1 && break
    sleep 1
  done
  ok=0
  rosrun accel_intrinsics supervise --archive "$URL" --device SIM-AGING-1 --rig sim_stand \
    --time "$date" --quiet --yes --timeout 900 --service-timeout 60 \
    --json "$work/supervise_$age.json" || ok=$?
  sleep 3  # the node archives on a thread of its own
  kill -INT "$launch_pid" 2>/dev/null || true
  wait "$launch_pid" 2>/dev/null || true
  if [ "$ok" != 0 ]; then
    echo "archive drift demo: FAILED: supervise exit status $ok (logs in $work)"
    exit 1
  fi
done

rosrun accel_intrinsics history SIM-AGING-1 --archive "$URL" --json "$work/history.json" \
  --plot "$work/history.png" | tail -n 2
rosrun accel_intrinsics history SIM-AGING-1 --archive "$NODE_URL" --json "$work/node_history.json" \
  >/dev/null
status=0
/usr/bin/python3 - "$work/history.json" "$work/node_history.json" "$RATE_U" "$RUNS" <<'PYTHON' \
  || status=$?
import json, sys
doc = json.load(open(sys.argv[1]))
node_doc = json.load(open(sys.argv[2]))
rate_true, runs = float(sys.argv[3]), int(sys.argv[4])
first = doc["records"][0]["values"]["responsivity_u"]
drift = doc["drift"]["responsivity_u"]
# the simulated rate is relative: |u| grows by |u|_0 * rate per day
expected = rate_true * first
z = (drift["rate_per_day"] - expected) / drift["rate_std_per_day"]
print("drift of |u|: %.3g +- %.2g per day (simulated %.3g, z %.2f); recalibrate by %s" % (
    drift["rate_per_day"], drift["rate_std_per_day"], expected, z,
    doc["recalibrate_by"]["responsivity_u"]))
print("records: %d by supervise --archive, %d by the node's archive parameter" % (
    len(doc["records"]), len(node_doc["records"])))
problems = []
if len(doc["records"]) != runs:
    problems.append("%d records, not %d" % (len(doc["records"]), runs))
if len(node_doc["records"]) != runs:
    problems.append("the node archived %d results, not %d" % (len(node_doc["records"]), runs))
if not drift["significant"]:
    problems.append("the drift of |u| is not found")
if abs(z) > 3.0:
    problems.append("the drift rate is %.1f standard uncertainties from the simulated one" % z)
if not doc["recalibrate_by"]["responsivity_u"]:
    problems.append("no recalibrate_by date for |u|")
if problems:
    print("archive drift demo: FAILED: " + "; ".join(problems))
    sys.exit(1)
print("archive drift demo: OK")
PYTHON
echo "[demo] files in $work"
exit $status
