"""The layer check (tools/check_layers.py): the package's own tree passes, and every rule fails a
fake tree written here with one violation, naming the file, the line and the rule."""
import os
import subprocess
import sys

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
CHECKER = os.path.join(REPO, "tools", "check_layers.py")


def write(root, rel, text):
    path = os.path.join(str(root), rel)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write(text)


def run(root):
    return subprocess.run([sys.executable, CHECKER, str(root)], stdout=subprocess.PIPE,
                          stderr=subprocess.STDOUT, universal_newlines=True)


@pytest.fixture
def tree(tmp_path):
    """A small clean tree: each folder includes only from below, tests use the simulator."""
    write(tmp_path, "include/accel_intrinsics/core/model/model.h", "#pragma once\n")
    write(tmp_path, "include/accel_intrinsics/core/fit/fit.h",
          '#pragma once\n#include "accel_intrinsics/core/model/model.h"\n')
    write(tmp_path, "include/accel_intrinsics/core/analysis/gap.h",
          '#pragma once\n#include "accel_intrinsics/core/fit/fit.h"\n')
    write(tmp_path, "include/accel_intrinsics/core/simulation/simulator.h",
          '#pragma once\n#include "accel_intrinsics/core/model/model.h"\n')
    write(tmp_path, "include/accel_intrinsics/io/writer.h",
          '#pragma once\n#include "accel_intrinsics/core/fit/fit.h"\n')
    write(tmp_path, "include/accel_intrinsics/ros/node.h",
          '#pragma once\n#include <ros/ros.h>\n#include "accel_intrinsics/io/writer.h"\n')
    write(tmp_path, "src/core/fit/fit_internal.h",
          '#pragma once\n#include "accel_intrinsics/core/fit/fit.h"\n')
    write(tmp_path, "src/core/fit/fit.cpp",
          '#include "accel_intrinsics/core/fit/fit.h"\n\n#include <Eigen/Dense>\n'
          '#include "fit_internal.h"\n')
    write(tmp_path, "src/core/analysis/gap.cpp",
          '#include "accel_intrinsics/core/analysis/gap.h"\n#include "../fit/fit_internal.h"\n')
    write(tmp_path, "src/drivers/gimbal_driver.cpp",
          '#include "accel_intrinsics/core/simulation/simulator.h"\n')
    write(tmp_path, "test/core/fit/fit_test.cpp",
          '#include "accel_intrinsics/core/simulation/simulator.h"\n'
          '#include "accel_intrinsics/core/fit/fit.h"\n')
    write(tmp_path, "bench/fit_bench.cpp",
          '#include "accel_intrinsics/core/simulation/simulator.h"\n')
    return tmp_path


def test_the_package_tree_passes():
    result = run(REPO)
    assert result.returncode == 0, result.stdout


def test_a_clean_fake_tree_passes(tree):
    result = run(tree)
    assert result.returncode == 0, result.stdout
    assert "the layers hold" in result.stdout


def test_an_include_going_up_fails(tree):
    write(tree, "src/core/fit/eq4_fit.cpp",
          '#include "accel_intrinsics/core/fit/fit.h"\n'
          '#include "accel_intrinsics/core/analysis/gap.h"\n')
    result = run(tree)
    assert result.returncode == 1
    assert "src/core/fit/eq4_fit.cpp:2: up:" in result.stdout
    assert "core/analysis" in result.stdout


def test_a_header_going_up_fails(tree):
    write(tree, "include/accel_intrinsics/core/model/effects.h",
          '#pragma once\n\n#include "accel_intrinsics/core/fit/fit.h"\n')
    result = run(tree)
    assert result.returncode == 1
    assert "include/accel_intrinsics/core/model/effects.h:3: up:" in result.stdout


def test_an_internal_header_of_a_folder_above_fails(tree):
    write(tree, "src/core/model/model.cpp", '#include "../fit/fit_internal.h"\n')
    result = run(tree)
    assert result.returncode == 1
    assert "src/core/model/model.cpp:1: up:" in result.stdout


def test_the_simulator_outside_tests_fails(tree):
    write(tree, "src/core/analysis/screening.cpp",
          '#include "accel_intrinsics/core/simulation/simulator.h"\n')
    write(tree, "src/ros/node.cpp", '#include "accel_intrinsics/core/simulation/simulator.h"\n')
    result = run(tree)
    assert result.returncode == 1
    assert "src/core/analysis/screening.cpp:1: simulation:" in result.stdout
    assert "src/ros/node.cpp:1: simulation:" in result.stdout
    assert "2 violation(s)" in result.stdout


def test_the_core_including_ros_io_or_drivers_fails(tree):
    write(tree, "include/accel_intrinsics/drivers/serial.h", "#pragma once\n")
    write(tree, "src/core/run/run.cpp",
          '#include <ros/ros.h>\n#include "accel_intrinsics/io/writer.h"\n'
          '#include "accel_intrinsics/drivers/serial.h"\n#include "accel_intrinsics/ros/node.h"\n')
    result = run(tree)
    assert result.returncode == 1
    for line in (1, 2, 3, 4):
        assert "src/core/run/run.cpp:%d: core-ros:" % line in result.stdout


def test_io_including_ros_fails(tree):
    write(tree, "src/io/writer.cpp",
          '#include "accel_intrinsics/io/writer.h"\n#include "accel_intrinsics/ros/node.h"\n'
          '#include <sensor_msgs/Imu.h>\n')
    result = run(tree)
    assert result.returncode == 1
    assert "src/io/writer.cpp:2: io-ros:" in result.stdout
    assert "src/io/writer.cpp:3: io-ros:" in result.stdout
