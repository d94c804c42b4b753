#!/usr/bin/env bash
# Mutation testing (issue 24): each mutation of tools/mutants.txt (a file, a literal pattern that
# must occur there exactly once, a replacement, the tests expected to fail) is applied alone to a
# scratch copy of this checkout, built incrementally in the scratch copy's own catkin workspace,
# and its tests are run (gtest binaries with --gtest_filter, or rostests); the verdict is "caught"
# (a test failed) or "SURVIVED". The tests are first run unmutated: they must pass.
#
# Usage: bash tools/mutants.sh [--check] [--only NAME[,NAME...]] [--list FILE] [--skip-baseline]
#        bash tools/mutants.sh --sample N [--seed S] [--table FILE]
#        bash tools/mutants.sh --recheck [--table FILE]
#   --check   only check the list (every pattern once in its file), no build: seconds
#   --only    a batch: these mutations only (the whole list takes about an hour on 2 cores)
#   --sample  instead of the list, N mutations drawn by rule with the seed (issue 37,
#             tools/mutants_sample.py and tools/mutant_rules.py), each run against the fast tier
#             of every unit binary (tools/fast_tier.py); the table goes to
#             docs/generated/mutants_sample.md (--table). See docs/mutation_testing.md.
#   --recheck the survivors of that table run again with today's tests, the table rewritten with
#             a triage section and the score after triage (tools/mutants_recheck.py).
# Environment: MUTANTS_DIR (default ${ACCEL_WS}_mutants: the copy in a directory named as this
# checkout, ws/ its workspace,
# logs/ a log per mutation, mutants_table.md the table), MUTANTS_TEST_TIMEOUT (s per test spec,
# default 900), ACCEL_BUILD_LOCK (a file flocked while building: held across mutations for at
# most MUTANTS_LOCK_HOLD_S s, default 600, then released for other builds on a shared machine),
# ACCEL_ROSTEST_LOCK (flocked around each rostest). The copy keeps unchanged files' times, so a
# second run rebuilds only the mutated files; with ccache (ACCEL_CMAKE_ARGS) and CCACHE_BASEDIR
# a common parent of both workspaces, the first build reuses the main workspace's objects.
# Ends with "N caught, N survived, N list errors or builds that failed"; exit status 0 only when
# every mutation was caught.
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
export MUTANTS_DIR="${MUTANTS_DIR:-${ACCEL_WS}_mutants}"
exec python3 "$REPO_DIR/tools/mutants.py" "$@"
