#!/usr/bin/env python3
"""Counts test cases in the JUnit XML files that catkin writes, prints failures, skipped cases
(one "SKIPPED name (file): reason" line each and a line "N skipped", only when there are any) and
one closing line "N passed, N failed" (exactly that: .ci/run, tools/sanitize.sh and tools/tsan.sh
read it). A skipped case counts as neither passed nor failed. Exit status 1 when anything failed
or nothing ran."""
import glob
import os
import sys
import xml.etree.ElementTree as ET


def main():
    root = sys.argv[1]
    passed, failed, failures, skipped = 0, 0, [], []
    files = sorted(glob.glob(os.path.join(root, "**", "*.xml"), recursive=True))
    names = set(os.path.basename(f) for f in files)
    for path in files:
        # rostest writes rostest-test_ros_NAME.xml (one case for the whole launch) beside
        # rosunit-NAME.xml (the gtest cases inside it): count the inner cases, and the launch
        # only when it has no inner file or itself failed (a node that never came up).
        base = os.path.basename(path)
        inner = None
        if base.startswith("rostest-"):
            inner = "rosunit-" + base[len("rostest-"):].split("test_ros_", 1)[-1]
        if inner in names:
            try:
                launch_failed = any(c.find("failure") is not None or c.find("error") is not None
                                    for c in ET.parse(path).iter("testcase"))
            except ET.ParseError:
                launch_failed = True
            if not launch_failed:
                continue
        try:
            tree = ET.parse(path)
        except ET.ParseError as error:
            failed += 1
            failures.append("%s: unreadable result file (%s)" % (path, error))
            continue
        for case in tree.iter("testcase"):
            bad = case.find("failure") is not None or case.find("error") is not None
            name = "%s.%s" % (case.get("classname", "?"), case.get("name", "?"))
            skip = case.find("skipped")
            # gtest marks GTEST_SKIP() cases result="skipped" (with or without a <skipped>
            # element) and disabled ones status="notrun".
            if skip is None and (case.get("result") in ("skipped", "suppressed")
                                 or case.get("status") == "notrun"):
                skip = case
            if skip is not None and not bad:
                reason = (skip.get("message") or skip.text or "").strip().splitlines()
                skipped.append("%s (%s)%s" % (name, os.path.basename(path),
                                              ": " + reason[0] if reason else ""))
                continue
            if bad:
                failed += 1
                node = case.find("failure")
                if node is None:
                    node = case.find("error")
                # The whole message on one line (location, then the values gtest printed): a
                # CI log that keeps only this summary still says what went wrong.
                message = (node.get("message") or node.text or "").strip().splitlines()
                text = " | ".join(l.strip() for l in message if l.strip())
                failures.append("%s (%s): %s" % (name, os.path.basename(path),
                                                 text[:400] + ("..." if len(text) > 400 else "")))
            else:
                passed += 1
    for line in failures:
        print("FAILED " + line)
    for line in skipped:
        print("SKIPPED " + line)
    if skipped:
        print("%d skipped" % len(skipped))
    if not files:
        print("no test result files under %s" % root)
    print("%d passed, %d failed" % (passed, failed))
    sys.exit(1 if failed or passed == 0 else 0)


if __name__ == "__main__":
    main()
