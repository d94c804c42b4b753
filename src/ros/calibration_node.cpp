// Calibration node: dwell assembly, checkpoints, fit, result, services.
#include "accel_intrinsics/ros/calibration_node.h"

#include <diagnostic_msgs/DiagnosticStatus.h>
#include <diagnostic_msgs/KeyValue.h>
#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <stdexcept>

#include "accel_intrinsics/core/constants.h"
#include "accel_intrinsics/core/position_table.h"
#include "accel_intrinsics/ros/conversions.h"
#include "accel_intrinsics/ros/names.h"
#include "accel_intrinsics/ros/params.h"

namespace accel_intrinsics {

namespace {

diagnostic_msgs::KeyValue kv(const std::string& key, const std::string& value) {
  diagnostic_msgs::KeyValue out;
  out.key = key;
  out.value = value;
  return out;
}

const char* const kAccel[3] = {"u", "v", "w"};
const char* const kPhase[3] = {"x", "y", "z"};

}  // namespace

void ImmediateCallbackQueue::addCallback(const ros::CallbackInterfacePtr& callback, uint64_t) {
  // TryAgain only happens for callbacks that refuse concurrent calls; a subscription queue with
  // a single subscriber never does. Retry a few times to be safe, then leave it.
  for (int i = 0; i < 100; ++i) {
    if (callback->ready() && callback->call() != ros::CallbackInterface::TryAgain) return;
  }
}

void ImmediateCallbackQueue::removeByID(uint64_t) {}

CalibrationOptions CalibrationOptions::load(const ros::NodeHandle& pnh) {
  CalibrationOptions o;
  std::string model = core::model_name(o.fit.model);
  read_param(pnh, "model", &model);
  try {
    o.fit.model = core::parse_model(model);
  } catch (const std::invalid_argument&) {
    throw ParamError("parameter " + param_name(pnh, "model") + ": unknown model '" + model +
                     "' (joint or eq4)");
  }
  const bool have_g = read_param(pnh, "local_gravity", &o.fit.local_gravity);
  double latitude_deg = 0.0, height_m = 0.0;
  const bool have_lat = read_param(pnh, "latitude_deg", &latitude_deg);
  read_param(pnh, "height_m", &height_m);
  require(!(have_g && have_lat), pnh, "local_gravity",
          "give either local_gravity or latitude_deg (with height_m), not both");
  if (have_lat) {
    try {
      o.fit.local_gravity = core::normal_gravity(latitude_deg, height_m);
    } catch (const std::invalid_argument& e) {
      throw ParamError("parameter " + param_name(pnh, "latitude_deg") + ": " + e.what());
    }
  }
  require(
      std::isfinite(o.fit.local_gravity) && o.fit.local_gravity > 9.7 && o.fit.local_gravity < 9.9,
      pnh, "local_gravity",
      "must be in (9.7, 9.9) m/s^2 (got " + std::to_string(o.fit.local_gravity) + ")");
  read_param(pnh, "min_positions_per_phase", &o.fit.min_positions_per_phase);
  require(o.fit.min_positions_per_phase >= 3, pnh, "min_positions_per_phase", "must be >= 3");
  read_param(pnh, "settle_discard_s", &o.assembler.settle_discard_s);
  require(std::isfinite(o.assembler.settle_discard_s) && o.assembler.settle_discard_s >= 0.0, pnh,
          "settle_discard_s", "must be finite and >= 0 s");
  read_param(pnh, "reorder_window_s", &o.assembler.reorder_window_s);
  require(std::isfinite(o.assembler.reorder_window_s) && o.assembler.reorder_window_s >= 0.0 &&
              o.assembler.reorder_window_s <= 60.0,
          pnh, "reorder_window_s", "must be in [0, 60] s");
  read_param(pnh, "flush_period_s", &o.flush_period_s);
  require(std::isfinite(o.flush_period_s) && o.flush_period_s > 0.0 && o.flush_period_s <= 10.0,
          pnh, "flush_period_s", "must be in (0, 10] s");
  read_param(pnh, "status_period_s", &o.status_period_s);
  require(std::isfinite(o.status_period_s) && o.status_period_s > 0.0, pnh, "status_period_s",
          "must be > 0 s");
  read_param(pnh, "steps", &o.steps);
  read_param(pnh, "frame_id", &o.frame_id);
  read_param(pnh, "immediate_imu", &o.immediate_imu);
  read_param(pnh, "file_prefix", &o.file_prefix);
  require(o.file_prefix.find('/') == std::string::npos, pnh, "file_prefix", "must not contain '/'");
  read_param(pnh, "output_dir", &o.output_dir);
  if (!o.output_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(o.output_dir, ec);
    require(!ec && std::filesystem::is_directory(o.output_dir), pnh, "output_dir",
            "cannot create directory '" + o.output_dir + "'" + (ec ? ": " + ec.message() : ""));
  }
  return o;
}

CalibrationNode::CalibrationNode(ros::NodeHandle nh, ros::NodeHandle pnh,
                                 const CalibrationOptions& options)
    : nh_(nh), pnh_(pnh), options_(options), assembler_(options.assembler) {
  assembler_.set_dwell_callback([this](const core::DwellRecord& row) { on_dwell(row); });
  result_pub_ = nh_.advertise<IntrinsicResult>(names::kResultTopic, 1, true);
  status_pub_ =
      nh_.advertise<diagnostic_msgs::DiagnosticStatus>(names::kCalibrationStatusTopic, 1, true);
  get_srv_ =
      nh_.advertiseService(names::kGetIntrinsicsService, &CalibrationNode::on_get_intrinsics, this);
  reset_srv_ = nh_.advertiseService(names::kResetService, &CalibrationNode::on_reset, this);
  command_sub_ = nh_.subscribe(names::kGimbalCommandTopic, 1000, &CalibrationNode::on_command, this,
                               ros::TransportHints().tcpNoDelay());
  ros::SubscribeOptions imu_options = ros::SubscribeOptions::create<sensor_msgs::Imu>(
      names::kImuTopic, 20000, boost::bind(&CalibrationNode::on_imu, this, boost::placeholders::_1),
      ros::VoidConstPtr(), options_.immediate_imu ? &immediate_queue_ : nullptr);
  imu_sub_ = nh_.subscribe(imu_options);
  timer_ =
      nh_.createTimer(ros::Duration(options_.flush_period_s), &CalibrationNode::on_timer, this);
  ROS_INFO("calibration: model %s, local_gravity %.6f m/s^2, reorder window %.3f s, output %s",
           core::model_name(options_.fit.model), options_.fit.local_gravity,
           options_.assembler.reorder_window_s,
           options_.output_dir.empty() ? "(none)" : options_.output_dir.c_str());
}

CalibrationNode::~CalibrationNode() {
  imu_sub_.shutdown();
  command_sub_.shutdown();
  timer_.stop();
  std::lock_guard<std::recursive_mutex> lock(mutex_);
}

std::string CalibrationNode::csv_path() const {
  if (options_.output_dir.empty()) return "";
  return (std::filesystem::path(options_.output_dir) /
          (options_.file_prefix + "position_table.csv"))
      .string();
}

std::string CalibrationNode::yaml_path() const {
  if (options_.output_dir.empty()) return "";
  return (std::filesystem::path(options_.output_dir) / (options_.file_prefix + "intrinsics.yaml"))
      .string();
}

void CalibrationNode::handle_command(const GimbalCommand& msg) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  ++commands_received_;
  if (msg.phase > GimbalCommand::PHASE_Z || msg.state > GimbalCommand::DONE ||
      !std::isfinite(msg.angle) || msg.steps == 0 || msg.step >= msg.steps ||
      msg.header.stamp.isZero()) {
    ++rejected_commands_;
    ROS_WARN_THROTTLE(5.0,
                      "calibration: rejected a malformed gimbal command (phase %u state %u step "
                      "%u/%u angle %f stamp %.3f); %llu so far",
                      msg.phase, msg.state, msg.step, msg.steps, msg.angle,
                      msg.header.stamp.toSec(),
                      static_cast<unsigned long long>(rejected_commands_));
    return;
  }
  const core::GimbalEvent event = to_core(msg);
  const bool new_run = event.state == core::GimbalState::Moving && event.phase == core::Phase::X &&
                       event.step == 0 &&
                       (done_pending_ || assembler_.done() || has_result_ || !fit_error_.empty());
  if (new_run) {
    if (done_pending_) {
      // The previous run's DONE is still in the reorder window: finish it first.
      assembler_.flush();
      done_pending_ = false;
      run_fit(msg.header.stamp);
    }
    reset("a new run starts (MOVING to phase x step 0 after DONE)");
  }
  steps_seen_ = msg.steps;
  assembler_.add_command(event);
  if (event.state == core::GimbalState::Done) {
    done_pending_ = true;
    done_stamp_s_ = event.stamp_s;
    ROS_INFO("calibration: DONE received, fitting after the reorder window");
  }
  warn_on_new_drops();
}

void CalibrationNode::handle_imu(const sensor_msgs::Imu& msg) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  assembler_.add_sample(to_core(msg));
  const core::AssemblerCounters& c = assembler_.counters();
  if (c.dropped_non_finite != warned_.dropped_non_finite ||
      c.dropped_backwards != warned_.dropped_backwards || c.dropped_late != warned_.dropped_late) {
    warn_on_new_drops();
  }
}

void CalibrationNode::warn_on_new_drops() {
  const core::AssemblerCounters& c = assembler_.counters();
  if (c.dropped_non_finite > warned_.dropped_non_finite) {
    ROS_WARN_THROTTLE(5.0,
                      "calibration: dropped IMU samples with NaN or infinite values (%llu so far)",
                      static_cast<unsigned long long>(c.dropped_non_finite));
  }
  if (c.dropped_backwards > warned_.dropped_backwards) {
    ROS_WARN_THROTTLE(5.0,
                      "calibration: dropped IMU samples whose stamp went backwards (%llu so far)",
                      static_cast<unsigned long long>(c.dropped_backwards));
  }
  if (c.dropped_late > warned_.dropped_late) {
    ROS_WARN_THROTTLE(5.0,
                      "calibration: dropped messages that arrived after the reorder window "
                      "(%llu so far; raise reorder_window_s?)",
                      static_cast<unsigned long long>(c.dropped_late));
  }
  if (c.commands_out_of_order > warned_.commands_out_of_order) {
    ROS_WARN_THROTTLE(5.0, "calibration: gimbal command out of protocol order (%llu so far): %s",
                      static_cast<unsigned long long>(c.commands_out_of_order),
                      c.last_warning.c_str());
  }
  warned_ = c;
}

void CalibrationNode::update(const ros::Time& now) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  if (now.isZero()) return;
  const double window = options_.assembler.reorder_window_s;
  if (done_pending_ && now.toSec() >= done_stamp_s_ + window) {
    assembler_.flush();
    done_pending_ = false;
    warn_on_new_drops();
    run_fit(now);
  } else if (now.toSec() > window) {
    assembler_.flush_until(now.toSec() - window);
    warn_on_new_drops();
  }
  if (now < last_status_ || (now - last_status_).toSec() >= options_.status_period_s) {
    publish_status(now);
  }
}

void CalibrationNode::on_timer(const ros::TimerEvent&) { update(ros::Time::now()); }

void CalibrationNode::reset(const std::string& reason) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  const std::size_t dwells = assembler_.table().rows.size();
  assembler_.reset();
  assembler_.set_dwell_callback([this](const core::DwellRecord& row) { on_dwell(row); });
  done_pending_ = false;
  has_result_ = false;
  fit_error_.clear();
  result_ = IntrinsicResult();
  if (csv_.is_open()) csv_.close();
  warned_ = core::AssemblerCounters();
  rejected_commands_ = 0;
  ++runs_;
  ROS_INFO("calibration: reset (%s); discarded %zu dwells", reason.c_str(), dwells);
  publish_status(ros::Time::now());
}

void CalibrationNode::on_dwell(const core::DwellRecord& row) {
  if (!options_.output_dir.empty()) {
    if (!csv_.is_open()) {
      csv_.open(csv_path(), std::ios::out | std::ios::trunc);
      if (!csv_) {
        ROS_ERROR_THROTTLE(10.0, "calibration: cannot write %s", csv_path().c_str());
      } else {
        csv_ << core::kPositionTableHeader << '\n';
      }
    }
    if (csv_) core::write_position_row(csv_, row);  // flushed: the checkpoint of this dwell
  }
  ROS_INFO("calibration: dwell %s %u/%u: n = %llu, mean (%.5f, %.5f, %.5f) m/s^2",
           core::phase_name(row.phase), row.step + 1, steps_seen_,
           static_cast<unsigned long long>(row.n), row.mean(0), row.mean(1), row.mean(2));
}

std::array<int, 3> CalibrationNode::dwells_per_phase() const {
  std::array<int, 3> counts{{0, 0, 0}};
  for (const core::DwellRecord& r : assembler_.table().rows) ++counts[core::index(r.phase)];
  return counts;
}

std::string CalibrationNode::missing_message() const {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  const std::array<int, 3> counts = dwells_per_phase();
  const std::uint32_t n = steps_seen_ ? steps_seen_ : options_.steps;
  const int needed = n ? static_cast<int>(n) : options_.fit.min_positions_per_phase;
  std::ostringstream s;
  s << "no result yet: ";
  if (!fit_error_.empty()) s << "the fit failed (" << fit_error_ << "); ";
  // Which phases are missing dwells, and how many.
  bool first = true;
  for (int p = 0; p < 3; ++p) {
    if (counts[p] >= needed) continue;
    s << (first ? "missing " : ", ") << "phase " << kPhase[p] << " (" << counts[p] << " of "
      << (n ? std::to_string(n) : ">= " + std::to_string(needed)) << " dwells)";
    first = false;
  }
  if (first) s << "all phases have their dwells";
  if (commands_received_ == 0) s << "; no gimbal command received yet";
  core::Phase phase;
  std::uint32_t step = 0;
  std::uint64_t samples = 0;
  if (assembler_.current_dwell(&phase, &step, &samples)) {
    s << "; in dwell phase " << core::phase_name(phase) << " step " << step << " (" << samples
      << " samples)";
  }
  if (done_pending_) s << "; DONE received, fitting after the reorder window";
  const core::AssemblerCounters& c = assembler_.counters();
  s << "; samples used " << c.samples_used << ", dropped outside dwells "
    << c.dropped_outside_dwell;
  return s.str();
}

bool CalibrationNode::on_get_intrinsics(GetIntrinsics::Request&, GetIntrinsics::Response& res) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  if (has_result_) {
    res.success = true;
    res.result = result_;
    std::ostringstream s;
    s << result_.model << " fit of " << result_.positions[0] << "/" << result_.positions[1] << "/"
      << result_.positions[2] << " dwells (x/y/z), reduced chi2 " << result_.reduced_chi2
      << ", g = " << result_.local_gravity << " m/s^2";
    res.message = s.str();
  } else {
    res.success = false;
    res.message = missing_message();
  }
  return true;
}

bool CalibrationNode::on_reset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  std::lock_guard<std::recursive_mutex> lock(mutex_);
  const std::size_t dwells = assembler_.table().rows.size();
  reset("reset requested");
  res.success = true;
  res.message = "reset: discarded " + std::to_string(dwells) + " dwells";
  return true;
}

void CalibrationNode::run_fit(const ros::Time& now) {
  const core::PositionTable& table = assembler_.table();
  try {
    const core::FitResult fit = core::fit(table, options_.fit);
    result_ = to_msg(fit);
    result_.header.stamp = now;
    result_.header.frame_id = options_.frame_id;
    has_result_ = true;
    fit_error_.clear();
    result_pub_.publish(result_);
    ROS_INFO(
        "calibration: %s fit of %zu dwells: |u| %.6f |v| %.6f |w| %.6f, angles uv %.4f vw "
        "%.4f wu %.4f deg, reduced chi2 %.3f",
        result_.model.c_str(), table.rows.size(), result_.responsivity[0], result_.responsivity[1],
        result_.responsivity[2], result_.angles_deg[0], result_.angles_deg[1],
        result_.angles_deg[2], result_.reduced_chi2);
    write_result_yaml(fit, now);
  } catch (const std::exception& e) {
    has_result_ = false;
    fit_error_ = e.what();
    ROS_ERROR("calibration: no result after DONE: %s", missing_message().c_str());
  }
  publish_status(now);
}

void CalibrationNode::write_result_yaml(const core::FitResult& fit, const ros::Time& stamp) {
  if (options_.output_dir.empty()) return;
  const IntrinsicResult& r = result_;
  YAML::Emitter y;
  y << YAML::BeginMap;
  y << YAML::Key << "stamp" << YAML::Value << stamp.toSec();
  y << YAML::Key << "model" << YAML::Value << r.model;
  auto triple = [&y](const char* key, const char* const* names, const double* values) {
    y << YAML::Key << key << YAML::Value << YAML::BeginMap;
    for (int i = 0; i < 3; ++i) y << YAML::Key << names[i] << YAML::Value << values[i];
    y << YAML::EndMap;
  };
  const char* const kAngles[3] = {"uv", "vw", "wu"};
  y << YAML::Precision(12);
  triple("responsivity", kAccel, r.responsivity.data());
  triple("responsivity_std", kAccel, r.responsivity_std.data());
  triple("angles_deg", kAngles, r.angles_deg.data());
  triple("angles_std_deg", kAngles, r.angles_std_deg.data());
  y << YAML::Key << "vectors" << YAML::Value << YAML::BeginMap;
  for (int s = 0; s < 3; ++s) {
    y << YAML::Key << kAccel[s] << YAML::Value << YAML::Flow << YAML::BeginSeq << fit.S(s, 0)
      << fit.S(s, 1) << fit.S(s, 2) << YAML::EndSeq;
  }
  y << YAML::EndMap;
  triple("offset", kAccel, r.offset.data());
  triple("offset_std", kAccel, r.offset_std.data());
  y << YAML::Key << "offset_per_phase" << YAML::Value << YAML::BeginMap;
  for (int s = 0; s < 3; ++s) {
    y << YAML::Key << kAccel[s] << YAML::Value << YAML::Flow << YAML::BeginMap;
    for (int p = 0; p < 3; ++p)
      y << YAML::Key << kPhase[p] << YAML::Value << fit.offset_per_phase(s, p);
    y << YAML::EndMap;
  }
  y << YAML::EndMap;
  y << YAML::Key << "cross_sensitivity" << YAML::Value << YAML::BeginSeq;
  for (int i = 0; i < 3; ++i) {
    y << YAML::Flow << YAML::BeginSeq << fit.cross_sensitivity(i, 0) << fit.cross_sensitivity(i, 1)
      << fit.cross_sensitivity(i, 2) << YAML::EndSeq;
  }
  y << YAML::EndSeq;
  y << YAML::Key << "local_gravity" << YAML::Value << r.local_gravity;
  y << YAML::Key << "reduced_chi2" << YAML::Value << r.reduced_chi2;
  y << YAML::Key << "residual_rms" << YAML::Value << r.residual_rms;
  y << YAML::Key << "positions" << YAML::Value << YAML::Flow << YAML::BeginMap;
  for (int p = 0; p < 3; ++p) y << YAML::Key << kPhase[p] << YAML::Value << r.positions[p];
  y << YAML::EndMap;
  const core::AssemblerCounters& c = assembler_.counters();
  y << YAML::Key << "samples" << YAML::Value << YAML::BeginMap;
  y << YAML::Key << "used" << YAML::Value << c.samples_used;
  y << YAML::Key << "dropped_outside_dwell" << YAML::Value << c.dropped_outside_dwell;
  y << YAML::Key << "dropped_settle_discard" << YAML::Value << c.dropped_settle_discard;
  y << YAML::Key << "dropped_non_finite" << YAML::Value << c.dropped_non_finite;
  y << YAML::Key << "dropped_backwards" << YAML::Value << c.dropped_backwards;
  y << YAML::Key << "dropped_late" << YAML::Value << c.dropped_late;
  y << YAML::EndMap;
  y << YAML::EndMap;
  const std::string path = yaml_path();
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::out | std::ios::trunc);
    out << "# accel_intrinsics calibration result (keys as offline_fit's JSON, DESIGN.md)\n"
        << y.c_str() << '\n';
    if (!out) {
      ROS_ERROR("calibration: cannot write %s", tmp.c_str());
      return;
    }
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    ROS_ERROR("calibration: cannot rename %s to %s", tmp.c_str(), path.c_str());
    return;
  }
  ROS_INFO("calibration: wrote %s", path.c_str());
}

void CalibrationNode::publish_status(const ros::Time& now) {
  last_status_ = now;
  const core::AssemblerCounters& c = assembler_.counters();
  const std::array<int, 3> counts = dwells_per_phase();
  diagnostic_msgs::DiagnosticStatus msg;
  msg.name = nh_.resolveName("calibration");
  msg.hardware_id = "accel_intrinsics";
  std::string state = has_result_           ? "RESULT"
                      : !fit_error_.empty() ? "FAILED"
                      : done_pending_       ? "FITTING"
                      : commands_received_  ? "COLLECTING"
                                            : "WAITING";
  msg.level = fit_error_.empty() ? diagnostic_msgs::DiagnosticStatus::OK
                                 : diagnostic_msgs::DiagnosticStatus::ERROR;
  msg.message = has_result_ ? "result available" : missing_message();
  msg.values.push_back(kv("state", state));
  for (int p = 0; p < 3; ++p)
    msg.values.push_back(kv(std::string("dwells_") + kPhase[p], std::to_string(counts[p])));
  msg.values.push_back(kv("steps", std::to_string(steps_seen_ ? steps_seen_ : options_.steps)));
  msg.values.push_back(kv("samples_used", std::to_string(c.samples_used)));
  msg.values.push_back(kv("dropped_outside_dwell", std::to_string(c.dropped_outside_dwell)));
  msg.values.push_back(kv("dropped_settle_discard", std::to_string(c.dropped_settle_discard)));
  msg.values.push_back(kv("dropped_non_finite", std::to_string(c.dropped_non_finite)));
  msg.values.push_back(kv("dropped_backwards", std::to_string(c.dropped_backwards)));
  msg.values.push_back(kv("dropped_late", std::to_string(c.dropped_late)));
  msg.values.push_back(kv("commands", std::to_string(c.commands)));
  msg.values.push_back(kv("commands_out_of_order", std::to_string(c.commands_out_of_order)));
  msg.values.push_back(kv("commands_rejected", std::to_string(rejected_commands_)));
  msg.values.push_back(kv("last_warning", c.last_warning));
  msg.values.push_back(kv("stamp", std::to_string(now.toSec())));
  status_pub_.publish(msg);
}

}  // namespace accel_intrinsics
