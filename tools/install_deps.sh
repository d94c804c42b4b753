#!/usr/bin/env bash
# Installs every Debian 12 package the package needs to build, run and test (as root).
source "$(dirname "${BASH_SOURCE[0]}")/common.sh"
PACKAGES=(
  build-essential cmake ros-base-dev catkin rosbash python3-rostest python3-roslaunch
  librosbag-dev python3-rosbag libtf2-ros-dev libtf2-eigen-dev libsensor-msgs-dev
  python3-sensor-msgs libstd-msgs-dev libstd-srvs-dev python3-std-srvs ros-std-srvs
  libgeometry-msgs-dev python3-geometry-msgs libtf2-msgs-dev libdiagnostic-msgs-dev
  python3-diagnostic-msgs ros-message-generation libmessage-filters-dev
  libdiagnostic-updater-dev libeigen3-dev libceres-dev libyaml-cpp-dev libboost-math-dev
  nlohmann-json3-dev libcli11-dev libbenchmark-dev libgtest-dev googletest
  python3-rospy python3-rosgraph python3-matplotlib python3-numpy python3-yaml catkin-lint graphviz
  libnodeletlib-dev libnodeletlib-tools pluginlib-dev
  poppler-utils mkdocs clang-format
  python3-sqlalchemy python3-alembic python3-psycopg2 python3-pytest postgresql
  python3-tornado chromium chromium-driver python3-selenium
)
missing=()
for p in "${PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "[install_deps] installing ${#missing[@]} packages: ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi
echo "[install_deps] all dependencies present"
