// check_mount (include/accel_intrinsics/ros/check_mount.h).
#include "accel_intrinsics/ros/check_mount.h"

#include <exception>
#include <istream>
#include <ostream>
#include <sstream>
#include <stdexcept>

#include "accel_intrinsics/core/model/constants.h"

namespace accel_intrinsics {

std::vector<core::PoseMean> read_poses(std::istream& in) {
  std::vector<core::PoseMean> poses;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const std::size_t hash = line.find('#');
    if (hash != std::string::npos) line.erase(hash);
    std::istringstream fields(line);
    std::string phase;
    if (!(fields >> phase)) continue;  // blank
    core::PoseMean pose;
    double angle_deg = 0.0;
    if (!core::parse_phase(phase, &pose.phase) ||
        !(fields >> angle_deg >> pose.n >> pose.mean(0) >> pose.mean(1) >> pose.mean(2)))
      throw std::invalid_argument("line " + std::to_string(number) +
                                  ": expected PHASE ANGLE_DEG N MEAN_U MEAN_V MEAN_W, got \"" +
                                  line + "\"");
    pose.angle_rad = core::deg_to_rad(angle_deg);
    poses.push_back(pose);
  }
  return poses;
}

int run_check_mount(std::istream& in, const CheckMountArguments& args, std::ostream& out,
                    std::ostream& err) {
  core::MountCheck check;
  try {
    core::SetupOptions options;
    options.local_gravity = args.gravity;
    options.output_unit = args.output_unit;
    check = core::check_mount(read_poses(in), options);
  } catch (const std::exception& e) {
    err << "check_mount: " << e.what() << std::endl;
    return kMountCouldNotRun;
  }
  if (check.correct()) {
    out << "mount correct: every phase turns the DUT as docs/design.md section 1 has it"
        << std::endl;
    return kMountCorrect;
  }
  for (const core::SetupMistake& m : check.mistakes) out << m.text() << std::endl;
  return kMountMistake;
}

}  // namespace accel_intrinsics
