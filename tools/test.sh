#!/usr/bin/env bash
# Installs, builds and runs every test (core gtests without a roscore, then rostests).
# Ends with one line "N passed, N failed".
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
bash "$REPO_DIR/tools/install_deps.sh"
build_quietly all tests
run_all_tests
