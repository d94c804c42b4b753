#!/usr/bin/env python3
"""The package's layers, checked on its #include lines (docs/architecture.md, "Layers").

Rules (each violation is printed as `file:line: rule: what`):
  up          a core folder includes only from folders below it:
              model < dwells < noise < fit < analysis < run (simulation may use model, dwells,
              noise and fit); applies to src/core/<A>/ and include/accel_intrinsics/core/<A>/.
  simulation  core/simulation is included only by src/core/simulation, its headers, test/,
              bench/, fuzz/ and the simulated drivers (SIMULATED_DRIVERS below).
  core-ros    the core includes no ros, io, drivers or emulators header (ours or ROS's).
  io-ros      io includes no ros header (ours or ROS's).

An include is resolved to a file of the tree: "accel_intrinsics/..." under include/, anything
else relative to the including file (internal headers such as src/core/fit/fit_internal.h).
Includes that resolve to no file of the tree (system and third-party headers) are checked only
for ROS (<ros/...>, message packages listed in ROS_PREFIXES).

Usage: check_layers.py [ROOT]   (default: the repository this script is in). Exit status 0 when
the tree is clean, 1 with the list of violations.
"""
import os
import re
import sys

ORDER = ["model", "dwells", "noise", "fit", "analysis", "run"]
# What each core folder may include besides itself.
ALLOWED = {folder: set(ORDER[:i]) for i, folder in enumerate(ORDER)}
ALLOWED["simulation"] = {"model", "dwells", "noise", "fit"}

# Files of src/drivers (and their headers) that implement the simulated gimbal and accelerometer:
# the only shipped code besides the core's simulation folder allowed to use the simulator.
SIMULATED_DRIVERS = {
    "src/drivers/gimbal_driver.cpp",
    "src/drivers/accelerometer_source.cpp",
    "include/accel_intrinsics/drivers/accelerometer_source.h",
}

# Trees where the simulator may be used freely.
SIMULATION_USERS = ("src/core/simulation/", "include/accel_intrinsics/core/simulation/", "test/",
                    "bench/", "fuzz/")

# ROS headers that the core and io must not include (by the first path component).
ROS_PREFIXES = ("ros/", "rosbag/", "roscpp/", "std_msgs/", "sensor_msgs/", "geometry_msgs/",
                "diagnostic_msgs/", "diagnostic_updater/", "std_srvs/", "tf2/", "tf2_ros/",
                "nodelet/", "pluginlib/", "dynamic_reconfigure/", "accel_intrinsics/ros/")

INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]')
SOURCE_EXT = (".h", ".hpp", ".cpp", ".cc")
SCANNED = ("src", "include", "test", "bench", "fuzz")


def core_folder(rel):
    """The core folder of a repository-relative path, or None."""
    for prefix in ("src/core/", "include/accel_intrinsics/core/"):
        if rel.startswith(prefix):
            rest = rel[len(prefix):]
            return rest.split("/", 1)[0] if "/" in rest else ""
    return None


def part_of(rel, name):
    return rel.startswith("src/%s/" % name) or rel.startswith("include/accel_intrinsics/%s/" % name)


def resolve(root, rel, target):
    """The repository-relative path an include names, or None when it is not in the tree."""
    if target.startswith("accel_intrinsics/"):
        candidate = os.path.join("include", target)
    else:
        candidate = os.path.normpath(os.path.join(os.path.dirname(rel), target))
    if os.path.isfile(os.path.join(root, candidate)):
        return candidate.replace(os.sep, "/")
    return None


def check_file(root, rel):
    errors = []
    own = core_folder(rel)
    in_core = own is not None
    in_io = part_of(rel, "io")
    with open(os.path.join(root, rel), encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, 1):
            m = INCLUDE.match(line)
            if not m:
                continue
            target = m.group(2)
            where = "%s:%d" % (rel, number)
            resolved = resolve(root, rel, target)
            name = resolved or target
            is_ros = target.startswith(ROS_PREFIXES) or (resolved and part_of(resolved, "ros"))
            if in_core:
                if is_ros or (resolved and any(part_of(resolved, p)
                                               for p in ("io", "drivers", "emulators"))):
                    errors.append("%s: core-ros: the core includes %s (the core is ROS-free and "
                                  "below io and drivers)" % (where, name))
                    continue
            if in_io and is_ros:
                errors.append("%s: io-ros: io includes %s (io is ROS-free)" % (where, name))
                continue
            if resolved is None:
                continue
            theirs = core_folder(resolved)
            if theirs == "simulation" and not (rel.startswith(SIMULATION_USERS)
                                               or rel in SIMULATED_DRIVERS):
                errors.append("%s: simulation: %s includes the simulator %s (only tests, bench, "
                              "fuzz and the simulated drivers may)" % (where, rel, name))
                continue
            if in_core and theirs is not None and theirs != own and own in ALLOWED:
                if theirs not in ALLOWED[own]:
                    errors.append("%s: up: core/%s includes %s from core/%s (a folder includes "
                                  "only from folders below it: %s)"
                                  % (where, own, name, theirs, " < ".join(ORDER)))
            elif in_core and own not in ALLOWED and theirs is not None and theirs != own:
                errors.append("%s: up: %s is in no known core folder (%s)"
                              % (where, rel, ", ".join(sorted(ALLOWED))))
    return errors


def check_tree(root):
    errors = []
    for top in SCANNED:
        for dirpath, dirnames, filenames in os.walk(os.path.join(root, top)):
            dirnames.sort()
            for filename in sorted(filenames):
                if filename.endswith(SOURCE_EXT):
                    rel = os.path.relpath(os.path.join(dirpath, filename), root)
                    errors += check_file(root, rel.replace(os.sep, "/"))
    return errors


def main(argv):
    root = argv[1] if len(argv) > 1 else os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    errors = check_tree(root)
    for e in errors:
        print(e)
    if errors:
        print("check_layers: %d violation(s)" % len(errors))
        return 1
    print("check_layers: the layers hold")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
