"""launch/rig.launch refuses a real IMU topic with the simulated gimbal (docs/design.md section 15,
"Launch for hardware"): roslaunch, on a private master of its own, prints the refusal with the
fix, starts no stand node and ends by itself; dry_run:=true, the simulated accelerometer's topic
and a real driver are not refused (checked on the parsed launch, without running it). The
real-rig defaults of config/hardware.yaml reach the nodes, and an argument given overrides them.
"""
import os
import socket
import subprocess

import pytest

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.realpath(__file__))))
RIG = os.path.join(REPO, "launch", "rig.launch")
TEST_STAND = os.path.join(REPO, "launch", "test_stand.launch")


def _env(port=None):
    env = dict(os.environ)
    env["ROS_PACKAGE_PATH"] = REPO + os.pathsep + env.get("ROS_PACKAGE_PATH", "/usr/share")
    env["PATH"] = "/usr/bin:" + env.get("PATH", "")
    if port:
        env["ROS_MASTER_URI"] = "http://127.0.0.1:%d" % port
    return env


def _free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _roslaunch(*args, timeout=60):
    return subprocess.run(["roslaunch"] + list(args), env=_env(), universal_newlines=True,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, timeout=timeout)


def _nodes(*launch_args, launch=RIG):
    out = _roslaunch("--nodes", launch, *launch_args)
    assert out.returncode == 0, out.stdout
    return set(out.stdout.split())


def _params(*launch_args, launch=RIG):
    import yaml
    out = _roslaunch("--dump-params", launch, *launch_args)
    assert out.returncode == 0, out.stdout
    return yaml.safe_load(out.stdout)


def test_real_imu_with_the_simulated_gimbal_is_refused_and_nothing_runs(tmp_path):
    port = _free_port()
    env = _env(port)
    env["ROS_HOME"] = str(tmp_path)
    out = subprocess.run(["roslaunch", "-p", str(port), RIG, "imu_topic:=/xsens/imu/data_raw"],
                         env=env, universal_newlines=True, stdout=subprocess.PIPE,
                         stderr=subprocess.STDOUT, timeout=90)
    text = out.stdout
    assert "REFUSED: rig.launch: imu_topic:=/xsens/imu/data_raw is a real IMU" in text, text
    assert "driver:=grbl" in text and "dry_run:=true" in text, text  # the fixes
    # the refusal node exits 1 and, being required, shuts the launch down by itself
    assert "exit code 1" in text, text
    assert "gimbal_controller" not in text and "calibration-" not in text, text


@pytest.mark.parametrize("args,refused", [
    (["imu_topic:=/xsens/imu/data_raw"], True),
    (["imu_topic:=/xsens/imu/data_raw", "dry_run:=true"], False),
    (["imu_topic:=/xsens/imu/data_raw", "driver:=grbl", "port:=/dev/null"], False),
    (["imu_topic:=/xsens/imu/data_raw", "gimbal_driver:=smc100", "port:=/dev/null"], False),
    ([], False),                                          # the simulated accelerometer's topic
    (["ns:=rig1", "imu_topic:=/rig1/imu/data_raw"], False),
    (["ns:=rig1", "imu_topic:=/imu/data_raw"], True),    # another rig's
])
def test_which_launches_are_refused(args, refused):
    nodes = _nodes(*args)
    assert ("/rig_launch_refused" in nodes) == refused, nodes
    assert any(n.endswith("/calibration") for n in nodes) == (not refused), nodes


def test_hardware_defaults_and_the_arguments_over_them():
    p = _params("driver:=grbl", "port:=/dev/null")
    assert p["/gimbal_controller/initial_rest_s"] == 120.0
    assert p["/calibration/imu_timeout_s"] == 2.0
    assert p["/calibration/device_serial"] == "unnamed"
    p = _params("driver:=grbl", "port:=/dev/null", "initial_rest_s:=30", "imu_timeout_s:=0.5",
                "output_unit:=counts", "device_serial:=SN-7", "gravity:=9.80123",
                "budget:=/lab/budget.yaml", "archive:=sqlite:////lab/archive.db",
                "archive_rig:=bench2")
    assert p["/gimbal_controller/initial_rest_s"] == 30.0
    assert p["/gimbal_controller/driver"] == "grbl"
    assert p["/gimbal_controller/grbl/port"] == "/dev/null"
    assert p["/calibration/imu_timeout_s"] == 0.5
    assert p["/calibration/output_unit"] == "counts"
    assert p["/calibration/device_serial"] == "SN-7"
    assert p["/calibration/local_gravity"] == 9.80123
    assert p["/calibration/budget_file"] == "/lab/budget.yaml"
    assert p["/calibration/archive"] == "sqlite:////lab/archive.db"
    assert p["/calibration/archive_rig"] == "bench2"
    p = _params("driver:=grbl", "port:=/dev/null", "latitude_deg:=48.1", "height_m:=520")
    assert p["/calibration/latitude_deg"] == 48.1 and p["/calibration/height_m"] == 520.0


def test_test_stand_without_simulation_forwards_driver_and_port():
    p = _params("sim:=false", "driver:=smc100", "port:=/dev/ttyUSB7",
                "imu_topic:=/xsens/imu/data_raw", launch=TEST_STAND)
    assert p["/gimbal_controller/driver"] == "smc100"
    assert p["/gimbal_controller/smc100/port"] == "/dev/ttyUSB7"
    # the old name too
    p = _params("sim:=false", "gimbal_driver:=grbl", "port:=/dev/ttyACM3",
                "imu_topic:=/xsens/imu/data_raw", launch=TEST_STAND)
    assert p["/gimbal_controller/driver"] == "grbl"
    assert p["/gimbal_controller/grbl/port"] == "/dev/ttyACM3"
