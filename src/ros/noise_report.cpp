#include "accel_intrinsics/ros/noise_report.h"

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/Imu.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <memory>
#include <ostream>
#include <sstream>
#include <stdexcept>

#include "accel_intrinsics/core/noise/noise.h"
#include "accel_intrinsics/io/atomic_file.h"
#include "accel_intrinsics/io/noise_document.h"
#include "accel_intrinsics/ros/bag_format.h"
#include "accel_intrinsics/ros/bag_topics.h"
#include "accel_intrinsics/ros/offline_fit.h"
#include "accel_intrinsics/ros/scripts.h"

namespace accel_intrinsics {
namespace {

struct Failure {
  int status;
  std::string message;
};

bool is_file(const std::string& path) {
  struct stat info;
  return ::stat(path.c_str(), &info) == 0 && S_ISREG(info.st_mode);
}

void read_bag_samples(const NoiseReportArguments& args, std::vector<double>* stamps,
                      std::vector<Eigen::Vector3d>* outputs, std::string* topic) {
  rosbag::Bag bag;
  try {
    bag_format::check_readable_file(args.bag);
    bag.open(args.bag, rosbag::bagmode::Read);
    *topic = resolve_topic(args.imu_topic, list_topics(bag), "sensor_msgs/Imu");
  } catch (const std::exception& e) {
    throw Failure{1, as_one_line(e.what())};
  }
  try {
    rosbag::View view(bag, rosbag::TopicQuery(*topic));
    stamps->reserve(view.size());
    outputs->reserve(view.size());
    for (const rosbag::MessageInstance& m : view) {
      const sensor_msgs::Imu::ConstPtr imu = m.instantiate<sensor_msgs::Imu>();
      if (!imu) continue;
      stamps->push_back(imu->header.stamp.toSec());
      outputs->emplace_back(imu->linear_acceleration.x, imu->linear_acceleration.y,
                            imu->linear_acceleration.z);
    }
  } catch (const std::exception& e) {
    throw Failure{1, "cannot read " + args.bag + ": " + as_one_line(e.what())};
  }
}

int run(const NoiseReportArguments& args, std::ostream& out, std::ostream& err) {
  if (args.bag.empty() == args.csv.empty()) {
    throw Failure{2, "give exactly one of --bag FILE or --csv SAMPLES.csv"};
  }
  if (!args.csv.empty() && args.imu_topic_given)
    throw Failure{2, "--imu-topic applies to --bag only"};
  std::vector<double> stamps;
  std::vector<Eigen::Vector3d> outputs;
  std::string source;
  if (!args.csv.empty()) {
    try {
      read_samples_csv(args.csv, &stamps, &outputs);
    } catch (const std::runtime_error& e) {
      throw Failure{1, as_one_line(e.what())};
    }
    source = args.csv;
  } else {
    std::string topic;
    read_bag_samples(args, &stamps, &outputs, &topic);
    source = args.bag + " (" + topic + ")";
  }
  core::StaticRecordNoise noise;
  try {
    noise = core::analyze_static_record(stamps, outputs);
  } catch (const std::invalid_argument& e) {
    throw Failure{1, source + ": " + e.what()};
  }
  const std::string json = io::noise_json_text(noise, source);

  std::unique_ptr<io::AtomicFile> json_file, kalibr_file;
  if (!args.json_out.empty()) {
    json_file.reset(new io::AtomicFile(args.json_out));
    json_file->stream() << json;
    json_file->close();
  }
  if (!args.kalibr_out.empty()) {
    kalibr_file.reset(new io::AtomicFile(args.kalibr_out));
    kalibr_file->stream() << io::kalibr_imu_noise_yaml(noise, source,
                                                       "/" + std::string(names::kImuTopic));
    kalibr_file->close();
  }
  if (!args.plot_out.empty()) {
    // The script reads the JSON from a temporary file.
    char templ[] = "/tmp/noise_report_XXXXXX.json";
    const int fd = ::mkstemps(templ, 5);
    if (fd < 0) throw Failure{1, "cannot create a temporary file for the plot"};
    ::close(fd);
    const std::string json_path = templ;
    io::write_file_atomically(json_path, json);
    const std::string script = package_script("plot_allan");
    const std::string command = "/usr/bin/python3 '" + script + "' --json '" + json_path +
                                "' --out '" + args.plot_out + "' 2>&1";
    FILE* pipe = ::popen(command.c_str(), "r");
    std::string output;
    if (pipe) {
      char buffer[512];
      while (std::fgets(buffer, sizeof(buffer), pipe)) output += buffer;
    }
    const int status = pipe ? ::pclose(pipe) : -1;
    std::remove(json_path.c_str());
    if (status != 0) {
      throw Failure{1, "the plot failed (" + script + "): " + as_one_line(output)};
    }
  }
  if (json_file) json_file->commit();
  if (kalibr_file) kalibr_file->commit();

  out << "noise_report: " << source << ": " << noise.curve.samples << " samples, "
      << std::setprecision(6) << noise.rate_hz << " Hz, " << noise.duration_s << " s\n";
  out << "  N: white-noise density (m/s^2)/sqrt(Hz), continuous-time (per-sample std = N "
         "sqrt(rate)), at tau = 1 s\n  B: bias instability m/s^2 (Allan minimum / 0.664) at its "
         "tau\n  K: random walk (m/s^3)/sqrt(Hz), at tau = 3 s\n";
  const char* names[3] = {"u", "v", "w"};
  for (int a = 0; a < 3; ++a) {
    const core::NoiseParameters& p = noise.axes[a];
    out << "  " << names[a] << ": N " << std::setprecision(4) << p.white_density << " +- "
        << std::setprecision(2) << p.white_density_std << ", B " << std::setprecision(4)
        << p.bias_instability << " +- " << std::setprecision(2) << p.bias_instability_std << " at "
        << std::setprecision(4) << p.bias_instability_tau_s << " s"
        << (p.bias_instability_floor_seen ? ""
                                          : " (the longest tau: no floor seen, an upper bound)")
        << ", K " << p.random_walk << " +- " << std::setprecision(2) << p.random_walk_std << "\n";
  }
  out << std::flush;
  (void)err;
  return 0;
}

}  // namespace

void read_samples_csv(const std::string& path, std::vector<double>* stamps,
                      std::vector<Eigen::Vector3d>* outputs) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read '" + path + "'");
  std::string line;
  std::size_t number = 0;
  while (std::getline(in, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (line.empty()) continue;
    if (number == 1) {
      if (line.rfind("t,u,v,w", 0) != 0) {
        throw std::runtime_error(path + ": line 1 must be the header t,u,v,w (got '" + line + "')");
      }
      continue;
    }
    double v[4];
    const char* p = line.c_str();
    for (int i = 0; i < 4; ++i) {
      char* end = nullptr;
      v[i] = std::strtod(p, &end);
      if (end == p || (i < 3 && *end != ',') || (i == 3 && *end != '\0' && *end != ',')) {
        throw std::runtime_error(path + ": line " + std::to_string(number) +
                                 ": expected 4 numbers t,u,v,w (got '" + line + "')");
      }
      p = end + 1;
    }
    stamps->push_back(v[0]);
    outputs->emplace_back(v[1], v[2], v[3]);
  }
  if (number == 0) throw std::runtime_error(path + ": empty file (expected the header t,u,v,w)");
}

int run_noise_report(const NoiseReportArguments& args, std::ostream& out, std::ostream& err) {
  try {
    return run(args, out, err);
  } catch (const Failure& f) {
    err << kNoiseReportProgram << ": error: " << f.message << std::endl;
    return f.status;
  } catch (const std::exception& e) {
    err << kNoiseReportProgram << ": error: " << as_one_line(e.what()) << std::endl;
    return 1;
  }
}

}  // namespace accel_intrinsics
