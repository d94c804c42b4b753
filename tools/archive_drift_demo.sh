#!/usr/bin/env bash
# The lab archive on the simulated stand (DESIGN.md section 13, issue 25): a simulated device
# that drifts (config/simulated_device.yaml device/aging) is calibrated RUNS times, AGE_STEP_DAYS
# apart, each run by `supervise --archive URL --time DATE`; then `history` must find the drift
# of |u| (significant, rate within 3 of its standard uncertainties of the simulated one) and give
# a recalibrate_by date. The simulated clock is not a calendar, hence --time: the date of each
# run is the simulated device's age.
#
#   bash tools/archive_drift_demo.sh [URL]      (default: a SQLite file in a temporary directory)
#
# Needs the built workspace ($ACCEL_WS, tools/build.sh offline_fit calibration accelerometer
# gimbal_controller sim_clock). Ends with "archive drift demo: OK" or a FAILED line (exit 1).
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
source_workspace
export PATH=/usr/bin:/bin:$PATH

RUNS=${RUNS:-5}
AGE_STEP_DAYS=${AGE_STEP_DAYS:-30}
RATE_U=${RATE_U:-2e-6}  # relative drift of |u| per day
work=$(mktemp -d /tmp/archive_drift_demo.XXXXXX)
URL=${1:-sqlite:///$work/archive.db}
port=$((20000 + RANDOM % 20000))
export ROS_MASTER_URI=http://localhost:$port

for ((i = 0; i < RUNS; i++)); do
  age=$((i * AGE_STEP_DAYS))
  date=$(date -u -d "2026-01-01 + $age days" +%Y-%m-%dT10:00:00Z)
  cat >"$work/aging_$age.yaml" <<EOF
device:
  aging:
    age_days: $age
    responsivity_per_day: [$RATE_U, 0.0, 0.0]
    offset_per_day: [0.0, 0.0, 0.0]
seed: $((i + 1))
EOF
  echo "[demo] run $((i + 1))/$RUNS: device age $age days, date $date"
  roslaunch -p "$port" accel_intrinsics test_stand.launch steps:=12 time_scale:=20 \
    output:=log output_dir:="$work/run_$age" device_extra_config:="$work/aging_$age.yaml" \
    >"$work/roslaunch_$age.log" 2>&1 &
  launch_pid=$!
  ok=0
  rosrun accel_intrinsics supervise --archive "$URL" --device SIM-AGING-1 --rig sim_stand \
    --time "$date" --quiet --yes --timeout 900 --service-timeout 60 \
    --json "$work/supervise_$age.json" || ok=$?
  kill -INT "$launch_pid" 2>/dev/null || true
  wait "$launch_pid" 2>/dev/null || true
  if [ "$ok" != 0 ]; then
    echo "archive drift demo: FAILED: supervise exit status $ok (logs in $work)"
    exit 1
  fi
done

rosrun accel_intrinsics history SIM-AGING-1 --archive "$URL" --json "$work/history.json" \
  --plot "$work/history.png" | tail -n 3
status=0
/usr/bin/python3 - "$work/history.json" "$RATE_U" <<'EOF' || status=$?
import json, sys
doc = json.load(open(sys.argv[1]))
rate_true = float(sys.argv[2])
first = doc["records"][0]["values"]["responsivity_u"]
drift = doc["drift"]["responsivity_u"]
# the simulated rate is relative: |u| grows by |u|_0 * rate per day
expected = rate_true * first
z = (drift["rate_per_day"] - expected) / drift["rate_std_per_day"]
print("drift of |u|: %.3g +- %.2g per day (simulated %.3g, z %.2f); recalibrate by %s" % (
    drift["rate_per_day"], drift["rate_std_per_day"], expected, z,
    doc["recalibrate_by"]["responsivity_u"]))
problems = []
if len(doc["records"]) < 3:
    problems.append("only %d records" % len(doc["records"]))
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
EOF
echo "[demo] files in $work"
exit $status
