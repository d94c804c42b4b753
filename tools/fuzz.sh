#!/usr/bin/env bash
# Builds the libFuzzer targets in fuzz/ with clang (AddressSanitizer + UBSan) and runs each for
# FUZZ_SECONDS (default 60). A crashing input is written to fuzz/crashes/; commit it under
# fuzz/corpus/<target>/ so the regression test (test/core/fuzz_regression_test.cpp) replays it.
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
command -v clang++ >/dev/null || { apt-get install -y -qq clang libclang-rt-14-dev >/dev/null; }
seconds="${FUZZ_SECONDS:-60}"
out="${FUZZ_BUILD_DIR:-/tmp/accel_intrinsics_fuzz}"
mkdir -p "$out" "$REPO_DIR/fuzz/crashes"
flags=(-std=c++17 -O1 -g -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=undefined
       -I"$REPO_DIR/include" -I/usr/include/eigen3)
core_sources=("$REPO_DIR/src/core/position_table.cpp" "$REPO_DIR/src/core/protocol.cpp"
              "$REPO_DIR/src/core/effects.cpp" "$REPO_DIR/src/core/model.cpp"
              "$REPO_DIR/src/core/constants.cpp")
echo "[fuzz] building position_table_fuzz"
clang++ "${flags[@]}" "$REPO_DIR/fuzz/position_table_fuzz.cpp" "${core_sources[@]}" -o "$out/position_table_fuzz"
work_corpus="$out/corpus_position_table"
mkdir -p "$work_corpus"
cp -n "$REPO_DIR"/fuzz/corpus/position_table/* "$work_corpus"/ 2>/dev/null || true
echo "[fuzz] running position_table_fuzz for ${seconds}s"
"$out/position_table_fuzz" -max_total_time="$seconds" -max_len=4096 \
  -artifact_prefix="$REPO_DIR/fuzz/crashes/" "$work_corpus" 2>&1 | tail -n 5
