#!/usr/bin/env bash
# Runs the whole suite RUNS times in a row (default 5) with CPU hogs busy beside it, to show
# that no test depends on an idle machine. ACCEL_HOGS busy loops (default 1, one of the two
# cores of the reference machine) run at normal priority for the whole of each run.
# Usage: bash tools/test_under_load.sh [RUNS]
# Each run's closing line goes to $ACCEL_WS/under_load/summary.txt; its filtered output to
# run_N.txt and its full log and JUnit files to run_N/. The script ends with "N of RUNS runs
# passed" and exits 1 when any run failed.
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
runs="${1:-5}"
hogs="${ACCEL_HOGS:-1}"
if ! [[ "$runs" =~ ^[1-9][0-9]*$ && "$hogs" =~ ^[0-9]+$ ]]; then
  echo "usage: [ACCEL_HOGS=N] bash tools/test_under_load.sh [RUNS >= 1] (got RUNS '$runs', ACCEL_HOGS '$hogs')" >&2
  exit 2
fi
bash "$REPO_DIR/tools/install_deps.sh"
build_quietly all tests
out="$ACCEL_WS/under_load"
rm -rf "$out"
mkdir -p "$out"

hog_pids=()
stop_hogs() {
  if ((${#hog_pids[@]})); then
    kill "${hog_pids[@]}" 2>/dev/null || true
    wait "${hog_pids[@]}" 2>/dev/null || true
  fi
  hog_pids=()
}
trap stop_hogs EXIT

clean_runs=0
for ((run = 1; run <= runs; ++run)); do
  for ((h = 0; h < hogs; ++h)); do
    bash -c 'while :; do :; done' &
    hog_pids+=($!)
  done
  echo "[under load] run $run of $runs with $hogs CPU hog(s), started $(date -u +%H:%M:%S)"
  start=$(date +%s)
  if run_all_tests > "$out/run_$run.txt" 2>&1; then clean_runs=$((clean_runs + 1)); fi
  stop_hogs
  mkdir -p "$out/run_$run"
  cp "$ACCEL_WS/run_tests.log" "$out/run_$run/" 2>/dev/null || true
  cp -r "$ACCEL_WS/build/test_results/accel_intrinsics" "$out/run_$run/test_results" 2>/dev/null || true
  line="run $run: $(tail -n 1 "$out/run_$run.txt") in $(($(date +%s) - start)) s"
  echo "$line" | tee -a "$out/summary.txt"
  grep "^FAILED " "$out/run_$run.txt" | head -n 20 || true
done
echo "$clean_runs of $runs runs passed (hogs: $hogs; per-run output in $out)"
((clean_runs == runs))
