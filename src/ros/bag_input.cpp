// The feed loop of bag reading (bag_input.h): messages of the run's topics to the assembler.
#include "accel_intrinsics/ros/bag_input.h"

#include <ros/serialization.h>
#include <rosbag/exceptions.h>
#include <rosbag/view.h>
#include <sensor_msgs/Imu.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <memory>
#include <ostream>

#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/core/model/protocol.h"
#include "accel_intrinsics/ros/conversions.h"

namespace accel_intrinsics {
namespace detail {

// The fields of a sensor_msgs/Imu that the dwell assembly needs: header stamp and
// linear_acceleration. Deserializes the wire format of sensor_msgs/Imu (same MD5 sum), skipping
// the frame_id, orientation, angular velocity and covariances instead of allocating and copying
// them. bag_input_test checks it against the full sensor_msgs::Imu on the same bytes.
struct ImuAccelerationOnly {
  ros::Time stamp;
  double x = 0.0;
  double y = 0.0;
  double z = 0.0;
};

}  // namespace detail
}  // namespace accel_intrinsics

namespace ros {
namespace message_traits {
template <>
struct MD5Sum<accel_intrinsics::detail::ImuAccelerationOnly> {
  static const char* value() { return MD5Sum<sensor_msgs::Imu>::value(); }
  static const char* value(const accel_intrinsics::detail::ImuAccelerationOnly&) { return value(); }
};
template <>
struct DataType<accel_intrinsics::detail::ImuAccelerationOnly> {
  static const char* value() { return DataType<sensor_msgs::Imu>::value(); }
  static const char* value(const accel_intrinsics::detail::ImuAccelerationOnly&) { return value(); }
};
template <>
struct Definition<accel_intrinsics::detail::ImuAccelerationOnly> {
  static const char* value() { return Definition<sensor_msgs::Imu>::value(); }
  static const char* value(const accel_intrinsics::detail::ImuAccelerationOnly&) { return value(); }
};
}  // namespace message_traits

namespace serialization {
template <>
struct Serializer<accel_intrinsics::detail::ImuAccelerationOnly> {
  // Wire layout of sensor_msgs/Imu: Header (uint32 seq, time stamp, string frame_id),
  // Quaternion orientation (4 float64), float64[9] orientation_covariance, Vector3
  // angular_velocity (3), float64[9] angular_velocity_covariance, Vector3 linear_acceleration (3),
  // float64[9] linear_acceleration_covariance. advance() throws StreamOverrunException on a
  // short buffer, like the generated deserializer.
  template <typename Stream>
  static void read(Stream& stream, accel_intrinsics::detail::ImuAccelerationOnly& m) {
    std::uint32_t seq = 0;
    stream.next(seq);
    stream.next(m.stamp.sec);
    stream.next(m.stamp.nsec);
    std::uint32_t frame_id_length = 0;
    stream.next(frame_id_length);
    stream.advance(frame_id_length);
    stream.advance((4 + 9 + 3 + 9) * sizeof(double));
    stream.next(m.x);
    stream.next(m.y);
    stream.next(m.z);
    stream.advance(9 * sizeof(double));
  }
};
}  // namespace serialization
}  // namespace ros

namespace accel_intrinsics {

namespace {

using bag_format::check_readable_file;
using bag_format::check_structure;
using bag_format::one_line;
using bag_format::truncation_hint;

void open_bag(rosbag::Bag& bag, const std::string& path) {
  check_readable_file(path);
  // rosbag trusts the lengths, offsets and counts it reads (a corrupt length makes it allocate
  // gigabytes, a corrupt index offset makes it read outside its buffer): it only gets bags whose
  // structure check_structure() has walked.
  try {
    check_structure(path);
  } catch (const BagInputError& e) {
    const std::string hint = truncation_hint(path);  // a cut-off file says so first
    throw BagInputError("cannot read bag '" + path +
                        "': " + (hint.empty() ? one_line(e.what()) : hint));
  }
  try {
    bag.open(path, rosbag::bagmode::Read);
  } catch (const rosbag::BagUnindexedException&) {
    throw BagInputError("cannot read bag '" + path +
                        "': it is unindexed (truncated, or the recorder did not close it); "
                        "try 'rosbag reindex' on a copy");
  } catch (const std::exception& e) {
    const std::string hint = truncation_hint(path);
    if (!hint.empty()) throw BagInputError("cannot read bag '" + path + "': " + hint);
    throw BagInputError("cannot read bag '" + path +
                        "' (corrupt or truncated?): " + one_line(e.what()));
  }
}

class Progress {
 public:
  Progress(std::ostream* out, double interval_s, std::string label, std::uint64_t total)
      : out_(out),
        interval_s_(interval_s),
        label_(std::move(label)),
        total_(total),
        start_(Clock::now()),
        next_report_s_(interval_s) {}

  void update(std::uint64_t done) {
    if (out_ == nullptr || (done & 0x3ff) != 0) return;  // look at the clock every 1024 messages
    const double elapsed = seconds_since_start();
    if (elapsed < next_report_s_) return;
    next_report_s_ = elapsed + interval_s_;
    const double percent =
        total_ > 0 ? 100.0 * static_cast<double>(done) / static_cast<double>(total_) : 0.0;
    *out_ << label_ << ": " << std::fixed << std::setprecision(0) << percent << std::defaultfloat
          << "% (" << done << " of " << total_ << " messages, " << std::setprecision(1)
          << std::fixed << elapsed << std::defaultfloat << " s)" << std::endl;
    reported_ = true;
  }

  void finish(std::uint64_t done) {
    if (out_ == nullptr || !reported_) return;
    *out_ << label_ << ": 100% (" << done << " messages, " << std::setprecision(1) << std::fixed
          << seconds_since_start() << std::defaultfloat << " s)" << std::endl;
  }

  double seconds_since_start() const {
    return std::chrono::duration<double>(Clock::now() - start_).count();
  }

 private:
  using Clock = std::chrono::steady_clock;
  std::ostream* out_;
  double interval_s_;
  std::string label_;
  std::uint64_t total_;
  Clock::time_point start_;
  double next_report_s_;
  bool reported_ = false;
};

}  // namespace

BagInputStats feed_bag(const std::string& path, const BagInputOptions& options,
                       core::DwellAssembler& assembler) {
  BagInputStats stats;
  stats.path = path;
  check_readable_file(path);
  // The chunk scan when the bag qualifies, else rosbag (which also produces the diagnostics of
  // unindexed, truncated or otherwise unreadable bags).
  std::unique_ptr<bag_format::ChunkScanner> scanner;
  if (options.allow_chunk_scan) {
    scanner.reset(new bag_format::ChunkScanner(path));
    if (!scanner->open()) scanner.reset();
  }
  rosbag::Bag bag;
  if (!scanner) open_bag(bag, path);

  try {
    const std::vector<BagTopic> topics = scanner ? scanner->topics() : list_topics(bag);
    const RunTopics run_topics =
        resolve_run_topics(options.imu_topic, options.command_topic, topics, options.imu_by_type,
                           options.channel_topics, options.command_topic_optional);
    stats.channel_topics = run_topics.channels;
    stats.topic_note = run_topics.note;
    stats.imu_topic = run_topics.imu;
    stats.command_topic = run_topics.command;

    // Connection ids of the run's topics in the chunk scan.
    std::vector<std::uint32_t> imu_connections;
    std::vector<std::uint32_t> command_connections;
    core::PerChannel<std::vector<std::uint32_t>> channel_connections;
    std::uint64_t total = 0;
    const std::vector<ChannelMessage>& bindings = channel_messages();
    auto channel_connections_found = [&] {
      for (std::size_t c = 0; c < core::kChannelCount; ++c) {
        if (!stats.channel_topics[c].empty() &&
            !scanner->connections_of(stats.channel_topics[c], bindings[c].md5sum,
                                     &channel_connections[c], &total))
          return false;
      }
      return true;
    };
    if (scanner && !(scanner->connections_of(stats.imu_topic,
                                             ros::message_traits::MD5Sum<sensor_msgs::Imu>::value(),
                                             &imu_connections, &total) &&
                     (stats.command_topic.empty() ||
                      scanner->connections_of(stats.command_topic,
                                              ros::message_traits::MD5Sum<GimbalCommand>::value(),
                                              &command_connections, &total)) &&
                     channel_connections_found())) {
      scanner.reset();  // another version of a message type: rosbag's instantiate() reports it
      open_bag(bag, path);
    }
    std::unique_ptr<rosbag::View> view;
    if (!scanner) {
      std::vector<std::string> query{stats.imu_topic};
      if (!stats.command_topic.empty()) query.push_back(stats.command_topic);
      for (const std::string& topic : stats.channel_topics)
        if (!topic.empty()) query.push_back(topic);
      view.reset(new rosbag::View(bag, rosbag::TopicQuery(query)));
      total = view->size();
    }
    Progress progress(options.progress_stream, options.progress_interval_s, options.progress_label,
                      total);

    // The same handling for both readers.
    std::uint64_t done = 0;
    bool first = true;
    auto on_time = [&](const ros::Time& bag_time) {
      const double t = bag_time.toSec();
      if (first) {
        stats.bag_start_s = t;
        first = false;
      }
      stats.bag_end_s = t;
    };
    auto on_imu = [&](const ros::Time& bag_time, const detail::ImuAccelerationOnly& imu) {
      on_time(bag_time);
      core::ImuSample sample;
      sample.stamp_s = imu.stamp.toSec() + options.imu_time_offset_s;
      sample.outputs = Eigen::Vector3d(imu.x, imu.y, imu.z);
      assembler.add_sample(sample);
      if (options.clock_check) options.clock_check->add_sample(sample);
      if (options.raw_samples) options.raw_samples->push_back(sample);
      ++stats.imu_messages;
      progress.update(++done);
    };
    auto on_channel = [&](const ros::Time& bag_time, core::ChannelSample reading) {
      on_time(bag_time);
      // On the IMU's clock, like its samples.
      reading.stamp_s += options.imu_time_offset_s;
      assembler.add_channel_sample(reading);
      ++stats.channel_messages[core::channel_index(reading.channel)];
      progress.update(++done);
    };
    // The channel whose topic `topic` is, kChannelCount for none.
    auto channel_of_topic = [&](const std::string& topic) {
      std::size_t c = 0;
      while (c < core::kChannelCount && stats.channel_topics[c] != topic) ++c;
      return c;
    };
    auto on_command = [&](const ros::Time& bag_time, const GimbalCommand& command) {
      on_time(bag_time);
      ++stats.command_messages;
      progress.update(++done);
      // The calibration node's acceptance test (CalibrationNode::handle_command), so that both
      // see the same commands.
      if (!is_well_formed(command)) {
        ++stats.invalid_commands;
        return;
      }
      const core::GimbalEvent event = to_core(command);
      stats.steps_announced[core::index(event.phase)] = event.steps;
      if (event.state == core::GimbalState::Done) stats.done_seen = true;
      assembler.add_command(event);
      if (options.clock_check) options.clock_check->add_command(event);
      if (options.raw_commands) options.raw_commands->push_back(event);
    };

    if (scanner) {
      stats.reader = "chunk scan";
      detail::ImuAccelerationOnly imu;
      GimbalCommand command;
      auto contains = [](const std::vector<std::uint32_t>& ids, std::uint32_t id) {
        return std::find(ids.begin(), ids.end(), id) != ids.end();
      };
      scanner->scan([&](std::uint32_t conn, const ros::Time& bag_time, const std::uint8_t* data,
                        std::uint32_t length, std::size_t offset) {
        const bool is_imu = contains(imu_connections, conn);
        std::size_t channel = 0;
        while (!is_imu && channel < core::kChannelCount &&
               !contains(channel_connections[channel], conn))
          ++channel;
        const bool is_channel = !is_imu && channel < core::kChannelCount;
        if (!is_imu && !is_channel && !contains(command_connections, conn)) return;
        try {
          ros::serialization::IStream stream(const_cast<std::uint8_t*>(data), length);
          if (is_imu) {
            ros::serialization::deserialize(stream, imu);
            on_imu(bag_time, imu);
          } else if (is_channel) {
            on_channel(bag_time,
                       bindings[channel].deserialize(const_cast<std::uint8_t*>(data), length));
          } else {
            ros::serialization::deserialize(stream, command);
            on_command(bag_time, command);
          }
        } catch (const ros::serialization::StreamOverrunException&) {
          bag_format::corrupt(offset, "message shorter than its type");
        }
      });
    } else {
      stats.reader = "rosbag::View";
      for (const rosbag::MessageInstance& m : *view) {
        if (m.getTopic() == stats.imu_topic) {
          const auto imu = m.instantiate<detail::ImuAccelerationOnly>();
          if (!imu)
            throw BagInputError("message on '" + stats.imu_topic + "' is not a sensor_msgs/Imu");
          on_imu(m.getTime(), *imu);
        } else if (const std::size_t c = channel_of_topic(m.getTopic()); c < core::kChannelCount) {
          const auto reading = bindings[c].instantiate(m);
          if (!reading)
            throw BagInputError("message on '" + m.getTopic() + "' is not a " +
                                bindings[c].datatype);
          on_channel(m.getTime(), *reading);
        } else {
          const auto command = m.instantiate<GimbalCommand>();
          if (!command)
            throw BagInputError("message on '" + stats.command_topic + "' is not a GimbalCommand");
          on_command(m.getTime(), *command);
        }
      }
    }
    if (options.flush_at_end) assembler.flush();
    progress.finish(done);
    stats.read_wall_s = progress.seconds_since_start();
  } catch (const BagInputError&) {
    throw;
  } catch (const rosbag::BagException& e) {
    throw BagInputError("cannot read bag '" + path +
                        "' (corrupt or truncated?): " + one_line(e.what()));
  } catch (const ros::Exception& e) {
    throw BagInputError("cannot read bag '" + path +
                        "' (corrupt message data?): " + one_line(e.what()));
  } catch (const std::exception& e) {
    throw BagInputError("cannot read bag '" + path + "': " + one_line(e.what()));
  }

  stats.counters = assembler.counters();
  stats.open_dwell = assembler.current_dwell(&stats.open_dwell_phase, &stats.open_dwell_step,
                                             &stats.open_dwell_samples);
  return stats;
}

namespace {
void observe_long_rest(const BagInputOptions& options, core::DwellAssembler& assembler) {
  core::LongRestRecorder* rest = options.long_rest;
  if (!rest) return;
  assembler.set_release_observers([rest](const core::GimbalEvent& e) { rest->add_command(e); },
                                  [rest](const core::ImuSample& s) { rest->add_sample(s); });
}
}  // namespace

BagRun read_bag(const std::string& path, const BagInputOptions& options) {
  core::DwellAssembler assembler(options.assembler);
  observe_long_rest(options, assembler);
  BagRun run;
  run.stats = feed_bag(path, options, assembler);
  run.table = assembler.table();
  return run;
}

std::vector<std::string> expand_bag_paths(const std::vector<std::string>& paths) {
  namespace fs = std::filesystem;
  std::vector<std::string> bags;
  for (const std::string& p : paths) {
    std::error_code ec;
    if (!fs::is_directory(p, ec)) {
      bags.push_back(p);  // feed_bag names a missing or unreadable file
      continue;
    }
    std::vector<std::string> found;
    for (const fs::directory_entry& e : fs::directory_iterator(p, ec)) {
      if (e.is_regular_file(ec) && e.path().extension() == ".bag")
        found.push_back(e.path().string());
    }
    if (ec) throw BagInputError("cannot list directory '" + p + "': " + ec.message());
    if (found.empty()) throw BagInputError("directory '" + p + "' holds no *.bag files");
    std::sort(found.begin(), found.end());
    bags.insert(bags.end(), found.begin(), found.end());
  }
  if (bags.empty()) throw BagInputError("no bag given");
  return bags;
}

BagRun read_bags(const std::vector<std::string>& paths, const BagInputOptions& options) {
  std::vector<std::string> bags = expand_bag_paths(paths);
  if (bags.size() == 1) return read_bag(bags.front(), options);
  // In the order of their first message (split bags' names do not sort numerically).
  std::vector<std::pair<double, std::string>> ordered;
  for (const std::string& path : bags) {
    check_readable_file(path);
    rosbag::Bag bag;
    open_bag(bag, path);
    rosbag::View view(bag);
    ordered.emplace_back(view.size() > 0 ? view.getBeginTime().toSec() : 0.0, path);
  }
  std::stable_sort(ordered.begin(), ordered.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });

  core::DwellAssembler assembler(options.assembler);
  observe_long_rest(options, assembler);
  BagInputOptions each = options;
  each.flush_at_end = false;
  BagRun run;
  BagInputStats& total = run.stats;
  for (std::size_t i = 0; i < ordered.size(); ++i) {
    const BagInputStats st = feed_bag(ordered[i].second, each, assembler);
    if (i == 0) {
      total = st;
      total.path = ordered[i].second;
    } else {
      if (st.imu_topic != total.imu_topic || st.command_topic != total.command_topic) {
        throw BagInputError("bag '" + ordered[i].second + "' holds the run on " + st.imu_topic +
                            " and " + st.command_topic + ", bag '" + total.path + "' on " +
                            total.imu_topic + " and " + total.command_topic);
      }
      total.path += ", " + ordered[i].second;
      total.imu_messages += st.imu_messages;
      for (std::size_t c = 0; c < core::kChannelCount; ++c) {
        total.channel_messages[c] += st.channel_messages[c];
        if (total.channel_topics[c].empty()) total.channel_topics[c] = st.channel_topics[c];
      }
      total.command_messages += st.command_messages;
      total.invalid_commands += st.invalid_commands;
      total.bag_start_s = std::min(total.bag_start_s, st.bag_start_s);
      total.bag_end_s = std::max(total.bag_end_s, st.bag_end_s);
      total.read_wall_s += st.read_wall_s;
      total.done_seen = total.done_seen || st.done_seen;
      for (int p = 0; p < 3; ++p) {
        if (st.steps_announced[p] > 0) total.steps_announced[p] = st.steps_announced[p];
      }
      if (total.reader != st.reader) total.reader = "chunk scan and rosbag::View";
    }
  }
  assembler.flush();
  total.files = static_cast<std::uint32_t>(ordered.size());
  total.counters = assembler.counters();
  total.open_dwell = assembler.current_dwell(&total.open_dwell_phase, &total.open_dwell_step,
                                             &total.open_dwell_samples);
  run.table = assembler.table();
  return run;
}

}  // namespace accel_intrinsics
