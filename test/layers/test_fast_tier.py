"""The fast tier's list of slow studies (tools/slow_tests.txt, read by tools/fast_tier.py): it
parses, every entry names a test written in the binary's sources (a renamed study would slip back
into the tier), and the filter keeps the studies out of the tier only. Run by the pytest layers
target."""
import glob
import os
import re
import sys

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(REPO, "tools"))

import fast_tier  # noqa: E402

SOURCES = {"core_tests": "test/core/**/*_test.cpp", "io_tests": "test/io/*_test.cpp",
           "drivers_tests": "test/drivers/*_test.cpp", "ros_unit_tests": "test/ros_unit/*_test.cpp"}


def written(binary):
    text = ""
    for path in glob.glob(os.path.join(REPO, SOURCES[binary]), recursive=True):
        with open(path) as f:
            text += f.read()
    return text


def test_every_slow_entry_names_a_test_of_its_binary():
    slow = fast_tier.read_slow()
    assert sum(len(v) for v in slow.values()) >= 10
    missing = []
    for binary, patterns in slow.items():
        text = written(binary)
        for pattern in patterns:
            suite, _, name = pattern.split("/")[-1].partition(".")
            if name == "*":
                ok = re.search(r"\bTEST(_F|_P)?\(\s*%s\s*," % re.escape(suite), text)
            else:
                ok = re.search(r"\bTEST(_F|_P)?\(\s*%s\s*,\s*%s\s*\)" % (re.escape(suite),
                                                                       re.escape(name)), text)
            if not ok:
                missing.append("%s %s" % (binary, pattern))
    assert not missing, "slow entries naming no test: %s" % missing


def test_filter_is_a_negative_list_of_the_entries(tmp_path):
    path = tmp_path / "slow.txt"
    path.write_text("# comment\ncore_tests A.B  # 3 s\ncore_tests C/D.*\n\nio_tests E.F\n")
    assert fast_tier.gtest_filter("core_tests", str(path)) == "-A.B:C/D.*"
    assert fast_tier.gtest_filter("io_tests", str(path)) == "-E.F"
    assert fast_tier.gtest_filter("drivers_tests", str(path)) == "*"


@pytest.mark.parametrize("line", ["nonsense_tests A.B\n", "core_tests AB\n", "core_tests A.B C\n"])
def test_a_malformed_line_is_refused(tmp_path, line):
    path = tmp_path / "slow.txt"
    path.write_text(line)
    with pytest.raises(ValueError):
        fast_tier.read_slow(str(path))


def test_the_normal_suite_does_not_use_the_list():
    # tools/test.sh runs every test (catkin run_tests); only the mutation sample reads the list.
    for rel in ("tools/test.sh", "tools/common.sh", "tools/build.sh", "CMakeLists.txt"):
        with open(os.path.join(REPO, rel)) as f:
            text = f.read()
        assert "slow_tests" not in text and "fast_tier" not in text, rel
    users = [p for p in glob.glob(os.path.join(REPO, "tools", "*.py"))
             if "import fast_tier" in open(p).read()]
    assert sorted(os.path.basename(p) for p in users) == ["mutants_sample.py"]
