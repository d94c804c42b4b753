#!/usr/bin/env python3
"""The fast tier of the unit binaries (issue 37): core_tests, io_tests, drivers_tests and
ros_unit_tests without the long studies listed in tools/slow_tests.txt, for the mutation
sample (each mutant runs the whole tier). The studies stay in the normal suite
(tools/test.sh runs every test): the tier only passes --gtest_filter=-SLOW:SLOW:... and no
test code changes.

    flock LOCK /usr/bin/python3 tools/fast_tier.py [--ws WORKSPACE] [--times]

runs the tier in the workspace (default $ACCEL_WS) and prints each binary's time and the total;
--times also lists each test slower than 2 s in the tier (to find a new slow study). Exit status
0 when every binary passed.
"""
import argparse
import os
import re
import subprocess
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SLOW_LIST = os.path.join(REPO, "tools", "slow_tests.txt")
BINARIES = ("core_tests", "io_tests", "drivers_tests", "ros_unit_tests")


def read_slow(path=SLOW_LIST):
    """{binary: [gtest pattern]} from lines `binary Suite.Test  # why`."""
    out = {b: [] for b in BINARIES}
    with open(path) as f:
        for number, raw in enumerate(f, 1):
            line = raw.split("#", 1)[0].strip()
            if not line:
                continue
            fields = line.split()
            if len(fields) != 2 or fields[0] not in BINARIES or "." not in fields[1]:
                raise ValueError("%s:%d: expected 'BINARY Suite.Test'" % (path, number))
            out[fields[0]].append(fields[1])
    return out


def gtest_filter(binary, path=SLOW_LIST):
    """The --gtest_filter value of the binary's fast tier: everything but its slow studies."""
    slow = read_slow(path)[binary]
    return "-" + ":".join(slow) if slow else "*"


def unmatched(ws, binary):
    """The slow patterns of the binary that name no test of it (a renamed study would otherwise
    slip back into the tier unnoticed)."""
    path = os.path.join(ws, "devel", "lib", "accel_intrinsics", binary)
    out = []
    for pattern in read_slow()[binary]:
        listing = subprocess.run([path, "--gtest_list_tests", "--gtest_filter=" + pattern],
                                 stdout=subprocess.PIPE, universal_newlines=True).stdout
        if not re.search(r"^  \S", listing, re.M):
            out.append(pattern)
    return out


def run(ws, show_times):
    total, failed = 0.0, []
    for binary in BINARIES:
        path = os.path.join(ws, "devel", "lib", "accel_intrinsics", binary)
        for pattern in unmatched(ws, binary):
            print("%s: the slow pattern %s names no test (tools/slow_tests.txt)"
                  % (binary, pattern))
            failed.append(binary + " (slow list)")
        t0 = time.time()
        r = subprocess.run([path, "--gtest_filter=" + gtest_filter(binary),
                            "--gtest_print_time=1"], stdout=subprocess.PIPE,
                           stderr=subprocess.STDOUT, universal_newlines=True)
        seconds = time.time() - t0
        total += seconds
        counted = re.search(r"\[==========\] (\d+) tests? from", r.stdout)
        print("%-15s %6.1f s  %s tests  %s" % (binary, seconds,
                                               counted.group(1) if counted else "?",
                                               "passed" if r.returncode == 0 else "FAILED"))
        if r.returncode != 0:
            failed.append(binary)
        if show_times:
            for name, ms in re.findall(r"^\[       OK \] (\S+) \((\d+) ms\)", r.stdout, re.M):
                if int(ms) > 2000:
                    print("    %-70s %6.1f s" % (name, int(ms) / 1000.0))
    print("fast tier: %.1f s in all%s"
          % (total, (", FAILED: " + " ".join(failed)) if failed else ""))
    return 1 if failed else 0


def main():
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--ws", default=os.environ.get("ACCEL_WS",
                                                       os.path.expanduser("~/accel_ws")))
    parser.add_argument("--times", action="store_true")
    args = parser.parse_args()
    sys.exit(run(args.ws, args.times))


if __name__ == "__main__":
    main()
