// Bag reading for offline_fit (bag_input.h).
#include "accel_intrinsics/ros/bag_input.h"

#include <ros/serialization.h>
#include <rosbag/exceptions.h>
#include <rosbag/view.h>
#include <sensor_msgs/Imu.h>
#include <fcntl.h>
#include <rosbag/constants.h>
#include <rosbag/stream.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <map>
#include <memory>
#include <ostream>
#include <sstream>
#include <unordered_map>

#include "accel_intrinsics/GimbalCommand.h"
#include "accel_intrinsics/core/protocol.h"
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

constexpr char kImuType[] = "sensor_msgs/Imu";
constexpr char kCommandType[] = "accel_intrinsics/GimbalCommand";

std::string strip_slash(const std::string& name) {
  return (!name.empty() && name[0] == '/') ? name.substr(1) : name;
}

bool ends_with(const std::string& text, const std::string& suffix) {
  return text.size() >= suffix.size() &&
         text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

std::string join(const std::vector<std::string>& items) {
  std::string out;
  for (const std::string& item : items) out += (out.empty() ? "" : ", ") + item;
  return out;
}

// Messages stay on one line: newlines in exception texts would break "one-line reason".
std::string one_line(std::string text) {
  std::replace(text.begin(), text.end(), '\n', ' ');
  while (!text.empty() && (text.back() == ' ' || text.back() == '.')) text.pop_back();
  return text;
}

void check_readable_file(const std::string& path) {
  struct stat info;
  if (::stat(path.c_str(), &info) != 0) {
    throw BagInputError("cannot open bag '" + path + "': " + std::strerror(errno));
  }
  if (S_ISDIR(info.st_mode)) throw BagInputError("cannot open bag '" + path + "': is a directory");
  if (info.st_size == 0) throw BagInputError("cannot open bag '" + path + "': the file is empty");
}

std::string truncation_hint(const std::string& path);
void check_structure(const std::string& path);

void open_bag(rosbag::Bag& bag, const std::string& path) {
  check_readable_file(path);
  // rosbag trusts the lengths, offsets and counts it reads (a corrupt length makes it allocate
  // gigabytes, a corrupt index offset makes it read outside its buffer): it only gets bags whose
  // structure check_structure() has walked.
  try {
    check_structure(path);
  } catch (const BagInputError& e) {
    const std::string hint = truncation_hint(path);  // a cut-off file says so first
    throw BagInputError("cannot read bag '" + path + "': " + (hint.empty() ? one_line(e.what()) : hint));
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
    throw BagInputError("cannot read bag '" + path + "' (corrupt or truncated?): " + one_line(e.what()));
  }
}

// The namespace around the default name when the resolved topic has it ("/stand2/imu/data_raw"
// -> "/stand2/", even when asked for as "stand2/imu/data_raw"), else around the request.
std::string namespace_of(const std::string& resolved, const std::string& default_name,
                         const std::string& requested) {
  return ends_with(resolved, "/" + default_name) ? topic_namespace(resolved, default_name)
                                                 : topic_namespace(resolved, requested);
}

class Progress {
 public:
  Progress(std::ostream* out, double interval_s, std::string label, std::uint64_t total)
      : out_(out), interval_s_(interval_s), label_(std::move(label)), total_(total),
        start_(Clock::now()), next_report_s_(interval_s) {}

  void update(std::uint64_t done) {
    if (out_ == nullptr || (done & 0x3ff) != 0) return;  // look at the clock every 1024 messages
    const double elapsed = seconds_since_start();
    if (elapsed < next_report_s_) return;
    next_report_s_ = elapsed + interval_s_;
    const double percent = total_ > 0 ? 100.0 * static_cast<double>(done) / static_cast<double>(total_) : 0.0;
    *out_ << label_ << ": " << std::fixed << std::setprecision(0) << percent << std::defaultfloat
          << "% (" << done << " of " << total_ << " messages, " << std::setprecision(1) << std::fixed
          << elapsed << std::defaultfloat << " s)" << std::endl;
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

// ---- Chunk scan ------------------------------------------------------------------------------
// rosbag::View parses every message's record header into a std::map and allocates the message;
// that is two thirds of the time for 1 M small messages. For the usual bag (format 2.0,
// uncompressed chunks, no encryption: what `rosbag record` writes by default) the records are read
// here straight from a memory map in file order, which is write order (the recorder's receive
// order, the order View yields as well when bag time grows with it). Anything else goes
// through View. Every length is bounds-checked: a corrupt record is an error, never a crash.
// Format: http://wiki.ros.org/Bags/Format/2.0

struct ChunkScanTargets {
  std::vector<std::uint32_t> imu;
  std::vector<std::uint32_t> command;
};

class MappedFile {
 public:
  explicit MappedFile(const std::string& path) {
    fd_ = ::open(path.c_str(), O_RDONLY);
    if (fd_ < 0) throw BagInputError("cannot open bag '" + path + "': " + std::strerror(errno));
    struct stat info;
    if (::fstat(fd_, &info) != 0) throw BagInputError("cannot stat bag '" + path + "'");
    size_ = static_cast<std::size_t>(info.st_size);
    if (size_ > 0) {
      void* p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd_, 0);
      if (p == MAP_FAILED) throw BagInputError("cannot map bag '" + path + "': " + std::strerror(errno));
      data_ = static_cast<const std::uint8_t*>(p);
      ::madvise(p, size_, MADV_SEQUENTIAL);
    }
  }
  ~MappedFile() {
    if (data_) ::munmap(const_cast<std::uint8_t*>(data_), size_);
    if (fd_ >= 0) ::close(fd_);
  }
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  const std::uint8_t* data() const { return data_; }
  std::size_t size() const { return size_; }

 private:
  int fd_ = -1;
  const std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
};

[[noreturn]] void corrupt(std::size_t offset, const std::string& what) {
  throw BagInputError("corrupt bag: " + what + " at byte " + std::to_string(offset));
}

std::uint32_t read_u32(const std::uint8_t* p) {
  std::uint32_t v;
  std::memcpy(&v, p, 4);  // bags are little-endian, like every platform ROS 1 runs on
  return v;
}

// The header fields the scan needs.
struct RecordFields {
  int op = -1;
  std::uint32_t conn = 0;
  ros::Time time;
  std::string compression;
  std::uint64_t index_pos = 0;
  bool encrypted = false;
  std::string topic;
  // For the structure check ahead of rosbag (check_structure): chunk sizes, index counts.
  std::uint32_t size = 0;
  std::uint32_t count = 0;
  std::uint32_t ver = 0;
  std::uint32_t conn_count = 0;
  std::uint32_t chunk_count = 0;
  std::uint64_t chunk_pos = 0;
  unsigned seen = 0;  // kHas* bits of the fields present
};

enum : unsigned {
  kHasConn = 1u << 0,
  kHasTime = 1u << 1,
  kHasSize = 1u << 2,
  kHasCount = 1u << 3,
  kHasVer = 1u << 4,
  kHasConnCount = 1u << 5,
  kHasChunkCount = 1u << 6,
  kHasChunkPos = 1u << 7,
  kHasIndexPos = 1u << 8,
  kHasTopic = 1u << 9,
  kHasCompression = 1u << 10,
  kHasStartTime = 1u << 11,
  kHasEndTime = 1u << 12,
};

bool field_is(const std::uint8_t* name, std::size_t name_len, const char* wanted) {
  const std::size_t n = std::strlen(wanted);
  return name_len == n && std::memcmp(name, wanted, n) == 0;
}

// Calls fn(name, name_len, value, value_len) for each "name=value" field of a record header (or
// of a connection record's data, which has the same layout).
template <typename Fn>
void for_each_field(const std::uint8_t* p, std::uint32_t len, std::size_t offset, Fn&& fn) {
  std::uint32_t i = 0;
  while (i < len) {
    if (len - i < 4) corrupt(offset + i, "truncated header field");
    const std::uint32_t field_len = read_u32(p + i);
    i += 4;
    if (field_len > len - i) corrupt(offset + i, "header field longer than its header");
    const std::uint8_t* field = p + i;
    const std::uint8_t* eq = static_cast<const std::uint8_t*>(std::memchr(field, '=', field_len));
    if (!eq) corrupt(offset + i, "header field without '='");
    const std::size_t name_len = static_cast<std::size_t>(eq - field);
    fn(field, name_len, eq + 1, field_len - name_len - 1, offset + i);
    i += field_len;
  }
}

RecordFields parse_fields(const std::uint8_t* p, std::uint32_t len, std::size_t offset) {
  RecordFields f;
  for_each_field(p, len, offset, [&f](const std::uint8_t* field, std::size_t name_len, const std::uint8_t* value,
                                      std::size_t value_len, std::size_t at) {
    auto u32 = [&](const char* name, unsigned bit, std::uint32_t* out) {
      if (value_len != 4) corrupt(at, std::string("bad ") + name + " field");
      *out = read_u32(value);
      f.seen |= bit;
    };
    auto u64 = [&](const char* name, unsigned bit, std::uint64_t* out) {
      if (value_len != 8) corrupt(at, std::string("bad ") + name + " field");
      std::memcpy(out, value, 8);
      f.seen |= bit;
    };
    if (field_is(field, name_len, "op")) {
      if (value_len != 1) corrupt(at, "bad op field");
      f.op = value[0];
    } else if (field_is(field, name_len, "conn")) {
      u32("conn", kHasConn, &f.conn);
    } else if (field_is(field, name_len, "time")) {
      if (value_len != 8) corrupt(at, "bad time field");
      f.time.sec = read_u32(value);
      f.time.nsec = read_u32(value + 4);
      f.seen |= kHasTime;
    } else if (field_is(field, name_len, "compression")) {
      f.compression.assign(reinterpret_cast<const char*>(value), value_len);
      f.seen |= kHasCompression;
    } else if (field_is(field, name_len, "index_pos")) {
      u64("index_pos", kHasIndexPos, &f.index_pos);
    } else if (field_is(field, name_len, "encryptor")) {
      f.encrypted = value_len > 0;
    } else if (field_is(field, name_len, "topic")) {
      f.topic.assign(reinterpret_cast<const char*>(value), value_len);
      f.seen |= kHasTopic;
    } else if (field_is(field, name_len, "size")) {
      u32("size", kHasSize, &f.size);
    } else if (field_is(field, name_len, "count")) {
      u32("count", kHasCount, &f.count);
    } else if (field_is(field, name_len, "ver")) {
      u32("ver", kHasVer, &f.ver);
    } else if (field_is(field, name_len, "conn_count")) {
      u32("conn_count", kHasConnCount, &f.conn_count);
    } else if (field_is(field, name_len, "chunk_count")) {
      u32("chunk_count", kHasChunkCount, &f.chunk_count);
    } else if (field_is(field, name_len, "chunk_pos")) {
      u64("chunk_pos", kHasChunkPos, &f.chunk_pos);
    } else if (field_is(field, name_len, "start_time")) {
      if (value_len != 8) corrupt(at, "bad start_time field");
      f.seen |= kHasStartTime;
    } else if (field_is(field, name_len, "end_time")) {
      if (value_len != 8) corrupt(at, "bad end_time field");
      f.seen |= kHasEndTime;
    }
  });
  return f;
}

// One record: header fields and the data span.
struct Record {
  RecordFields fields;
  const std::uint8_t* data = nullptr;
  std::uint32_t data_len = 0;
  std::size_t end = 0;  // offset just past the record
};

Record read_record(const std::uint8_t* base, std::size_t size, std::size_t pos) {
  Record r;
  if (size - pos < 4) corrupt(pos, "truncated record");
  const std::uint32_t header_len = read_u32(base + pos);
  if (header_len > size - pos - 4) corrupt(pos, "record header runs past the end");
  r.fields = parse_fields(base + pos + 4, header_len, pos + 4);
  std::size_t p = pos + 4 + header_len;
  if (size - p < 4) corrupt(p, "truncated record");
  r.data_len = read_u32(base + p);
  p += 4;
  if (r.data_len > size - p) corrupt(p, "record data runs past the end");
  r.data = base + p;
  r.end = p + r.data_len;
  return r;
}

constexpr char kVersionLine[] = "#ROSBAG V2.0\n";
constexpr std::size_t kVersionLength = sizeof(kVersionLine) - 1;

struct ScanConnection {
  std::string topic;
  std::string datatype;
  std::string md5sum;
  std::uint64_t messages = 0;
};

// A bag read without rosbag: its connections and message counts from the index section, then
// the chunks in file order. open() says whether this bag qualifies; if not (or if anything in it
// looks odd), the caller uses rosbag, whose checks and messages then apply.
class ChunkScanner {
 public:
  explicit ChunkScanner(const std::string& path) : file_(path) {}

  bool open() {
    try {
      return read_index() && chunks_uncompressed();
    } catch (const BagInputError&) {
      return false;
    }
  }

  std::vector<BagTopic> topics() const {
    std::map<std::string, BagTopic> by_name;
    for (const auto& entry : connections_) {
      const ScanConnection& c = entry.second;
      BagTopic& t = by_name[c.topic];
      t.name = c.topic;
      if (t.datatype.empty()) t.datatype = c.datatype;
      else if (t.datatype != c.datatype) t.datatype += "|" + c.datatype;
      t.messages += c.messages;
    }
    std::vector<BagTopic> out;
    for (auto& entry : by_name) out.push_back(entry.second);
    return out;
  }

  // Connection ids of `topic`; false when one has a different MD5 sum than `md5sum`.
  bool connections_of(const std::string& topic, const std::string& md5sum, std::vector<std::uint32_t>* ids,
                      std::uint64_t* messages) const {
    for (const auto& entry : connections_) {
      if (entry.second.topic != topic) continue;
      if (entry.second.md5sum != md5sum) return false;
      ids->push_back(entry.first);
      *messages += entry.second.messages;
    }
    return true;
  }

  template <typename OnImu, typename OnCommand>
  void scan(const ChunkScanTargets& targets, OnImu&& on_imu, OnCommand&& on_command) const {
    const std::uint8_t* base = file_.data();
    std::size_t pos = first_record_;
    detail::ImuAccelerationOnly imu;
    GimbalCommand command;
    while (pos < index_pos_) {
      const Record chunk = read_record(base, index_pos_, pos);
      if (chunk.fields.op == rosbag::OP_CHUNK) {
        const std::size_t chunk_offset = static_cast<std::size_t>(chunk.data - base);
        std::size_t inner = 0;
        while (inner < chunk.data_len) {
          const Record r = read_record(chunk.data, chunk.data_len, inner);
          if (r.fields.op == rosbag::OP_MSG_DATA) {
            const bool is_imu = contains(targets.imu, r.fields.conn);
            if (is_imu || contains(targets.command, r.fields.conn)) {
              try {
                ros::serialization::IStream stream(const_cast<std::uint8_t*>(r.data), r.data_len);
                if (is_imu) {
                  ros::serialization::deserialize(stream, imu);
                  on_imu(r.fields.time, imu);
                } else {
                  ros::serialization::deserialize(stream, command);
                  on_command(r.fields.time, command);
                }
              } catch (const ros::serialization::StreamOverrunException&) {
                corrupt(chunk_offset + inner, "message shorter than its type");
              }
            }
          } else if (r.fields.op != rosbag::OP_CONNECTION) {
            corrupt(chunk_offset + inner, "unexpected record (op " + std::to_string(r.fields.op) + ") in a chunk");
          }
          inner = r.end;
        }
      }
      pos = chunk.end;
    }
  }

 private:
  static bool contains(const std::vector<std::uint32_t>& ids, std::uint32_t id) {
    return std::find(ids.begin(), ids.end(), id) != ids.end();
  }

  // File header, then the index section: connection records and chunk info records.
  bool read_index() {
    const std::uint8_t* base = file_.data();
    const std::size_t size = file_.size();
    if (size < kVersionLength || std::memcmp(base, kVersionLine, kVersionLength) != 0) return false;
    const Record header = read_record(base, size, kVersionLength);
    if (header.fields.op != rosbag::OP_FILE_HEADER || header.fields.encrypted) return false;
    // index_pos = 0: the recorder never closed the bag (unindexed); rosbag says so.
    if (header.fields.index_pos == 0 || header.fields.index_pos >= size) return false;
    first_record_ = header.end;
    index_pos_ = static_cast<std::size_t>(header.fields.index_pos);
    std::size_t pos = index_pos_;
    while (pos < size) {
      const Record r = read_record(base, size, pos);
      if (r.fields.op == rosbag::OP_CONNECTION) {
        ScanConnection& c = connections_[r.fields.conn];
        c.topic = r.fields.topic;
        for_each_field(r.data, r.data_len, pos, [&c](const std::uint8_t* field, std::size_t name_len,
                                                     const std::uint8_t* value, std::size_t value_len, std::size_t) {
          if (field_is(field, name_len, "type")) c.datatype.assign(reinterpret_cast<const char*>(value), value_len);
          if (field_is(field, name_len, "md5sum")) c.md5sum.assign(reinterpret_cast<const char*>(value), value_len);
        });
      } else if (r.fields.op == rosbag::OP_CHUNK_INFO) {
        if (r.data_len % 8 != 0) return false;
        for (std::uint32_t i = 0; i < r.data_len; i += 8) {
          message_counts_[read_u32(r.data + i)] += read_u32(r.data + i + 4);
        }
      } else {
        return false;  // not a 2.0 index section as rosbag writes it
      }
      pos = r.end;
    }
    for (auto& entry : connections_) {
      if (entry.second.topic.empty() || entry.second.datatype.empty()) return false;
      entry.second.messages = message_counts_[entry.first];
    }
    return true;
  }

  bool chunks_uncompressed() const {
    std::size_t pos = first_record_;
    while (pos < index_pos_) {
      const Record r = read_record(file_.data(), index_pos_, pos);
      if (r.fields.op == rosbag::OP_CHUNK && r.fields.compression != rosbag::COMPRESSION_NONE) return false;
      pos = r.end;
    }
    return true;
  }

  MappedFile file_;
  std::size_t first_record_ = 0;
  std::size_t index_pos_ = 0;
  std::map<std::uint32_t, ScanConnection> connections_;
  std::map<std::uint32_t, std::uint64_t> message_counts_;
};

// ---- Structure check ahead of rosbag ------------------------------------------------------
// rosbag::Bag reads the file header, seeks to index_pos, reads conn_count connection records and
// chunk_count chunk info records, then at each chunk_pos the chunk header and the index records
// after the chunk; View then loads (decompresses) chunks and reads the message record at each
// indexed offset. None of that checks a length against the file or an offset against the chunk.
// This walks the same records first and throws BagInputError ("corrupt bag: ... at byte N")
// unless every one of them is where rosbag will look and lies inside the file (or inside its
// decompressed chunk). Compressed chunks are decompressed here with rosbag's own decompressors,
// so a compressed bag is decompressed twice on the rosbag path. Bags that rosbag rejects by itself
// with a clear message before reading past the file header (unindexed: index_pos 0; cut short
// before the index) are left to it. Only format 2.0 is accepted (1.2 predates ROS 1 Diamondback).

// A chunk may claim at most this many bytes uncompressed (rosbag allocates them up front).
constexpr std::uint64_t kMaxChunkBytes = std::uint64_t{1} << 30;
// ... and at most this ratio to its compressed size (plus 1 MiB): far beyond what bz2 or lz4 do
// on message data, far below what a corrupt size field claims.
constexpr std::uint64_t kMaxCompressionRatio = 4096;

void require(bool ok, std::size_t offset, const std::string& what) {
  if (!ok) corrupt(offset, what);
}

// The data of chunk record `chunk` (at file offset `offset`), decompressed when it is compressed.
const std::uint8_t* chunk_content(const Record& chunk, std::size_t offset, std::vector<std::uint8_t>* buffer,
                                  std::size_t* length) {
  const std::string& compression = chunk.fields.compression;
  require((chunk.fields.seen & kHasCompression) && (chunk.fields.seen & kHasSize), offset,
          "chunk header without compression or size");
  if (compression == rosbag::COMPRESSION_NONE) {
    require(chunk.fields.size == chunk.data_len, offset, "uncompressed chunk whose size differs from its length");
    *length = chunk.data_len;
    return chunk.data;
  }
  require(compression == rosbag::COMPRESSION_BZ2 || compression == rosbag::COMPRESSION_LZ4, offset,
          "unknown chunk compression '" + compression + "'");
  const std::uint64_t size = chunk.fields.size;
  require(size <= kMaxChunkBytes && size <= kMaxCompressionRatio * chunk.data_len + (1u << 20), offset,
          "chunk claims " + std::to_string(size) + " bytes uncompressed from " + std::to_string(chunk.data_len));
  // 0xff: bytes the decompressor did not write read as a record length past the end.
  buffer->assign(static_cast<std::size_t>(size), 0xff);
  try {
    std::unique_ptr<rosbag::Stream> stream;
    if (compression == rosbag::COMPRESSION_BZ2) stream.reset(new rosbag::BZ2Stream(nullptr));
    else stream.reset(new rosbag::LZ4Stream(nullptr));
    if (size > 0) {
      stream->decompress(buffer->data(), static_cast<unsigned int>(size), const_cast<std::uint8_t*>(chunk.data),
                         chunk.data_len);
    }
  } catch (const std::exception& e) {
    corrupt(offset, "chunk does not decompress (" + one_line(e.what()) + ")");
  }
  *length = buffer->size();
  return buffer->data();
}

void check_structure(const std::string& path) {
  MappedFile file(path);
  const std::uint8_t* base = file.data();
  const std::size_t size = file.size();
  if (size < kVersionLength || std::memcmp(base, kVersionLine, kVersionLength) != 0) {
    throw BagInputError("not a ROS bag (format 2.0): the file does not start with '#ROSBAG V2.0'");
  }
  const Record header = read_record(base, size, kVersionLength);
  require(header.fields.op == rosbag::OP_FILE_HEADER, kVersionLength, "first record is not a file header");
  if (header.fields.encrypted) {
    throw BagInputError("the bag is encrypted; decrypt a copy first ('rosbag decrypt')");
  }
  const std::uint64_t index_pos = header.fields.index_pos;
  if (index_pos == 0 || index_pos > size) return;  // unindexed or cut short: rosbag says so
  require((header.fields.seen & kHasConnCount) && (header.fields.seen & kHasChunkCount), kVersionLength,
          "file header without conn_count or chunk_count");
  require(index_pos >= header.end, kVersionLength, "index_pos inside the file header");

  // Chunks, each followed by its index records, up to index_pos. Per chunk: the offsets of its
  // message records with their connection, and how many index records follow it.
  std::map<std::size_t, std::uint32_t> index_records_after_chunk;
  std::unordered_map<std::uint32_t, std::uint32_t> messages_at;  // offset in chunk -> conn, last chunk
  std::vector<std::uint8_t> buffer;
  std::size_t last_chunk = 0;
  bool have_chunk = false;
  std::size_t pos = header.end;
  while (pos < index_pos) {
    const Record r = read_record(base, index_pos, pos);
    if (r.fields.op == rosbag::OP_CHUNK) {
      std::size_t length = 0;
      const std::uint8_t* content = chunk_content(r, pos, &buffer, &length);
      messages_at.clear();
      std::size_t inner = 0;
      while (inner < length) {
        const Record m = read_record(content, length, inner);
        if (m.fields.op == rosbag::OP_MSG_DATA) {
          require((m.fields.seen & kHasConn) && (m.fields.seen & kHasTime), pos,
                  "message record without conn or time in the chunk");
          messages_at[static_cast<std::uint32_t>(inner)] = m.fields.conn;
        } else {
          require(m.fields.op == rosbag::OP_CONNECTION, pos,
                  "unexpected record (op " + std::to_string(m.fields.op) + ") in the chunk");
        }
        inner = m.end;
      }
      last_chunk = pos;
      have_chunk = true;
      index_records_after_chunk[pos] = 0;
    } else if (r.fields.op == rosbag::OP_INDEX_DATA) {
      require(have_chunk, pos, "index record before any chunk");
      require((r.fields.seen & kHasVer) && r.fields.ver == 1 && (r.fields.seen & kHasConn) &&
                  (r.fields.seen & kHasCount),
              pos, "index record without version 1, conn or count");
      require(static_cast<std::uint64_t>(r.fields.count) * 12 == r.data_len, pos,
              "index record whose count does not match its length");
      for (std::uint32_t i = 0; i < r.fields.count; ++i) {
        const std::uint32_t offset = read_u32(r.data + 12 * i + 8);
        const auto found = messages_at.find(offset);
        require(found != messages_at.end() && found->second == r.fields.conn, pos,
                "index entry pointing at no message of its connection");
      }
      ++index_records_after_chunk[last_chunk];
    } else {
      corrupt(pos, "unexpected record (op " + std::to_string(r.fields.op) + ") before the index");
    }
    pos = r.end;
  }

  // The index section: conn_count connection records, then chunk_count chunk info records.
  pos = static_cast<std::size_t>(index_pos);
  for (std::uint32_t i = 0; i < header.fields.conn_count; ++i) {
    require(pos < size, pos, "fewer connection records than the file header's conn_count");
    const Record r = read_record(base, size, pos);
    require(r.fields.op == rosbag::OP_CONNECTION && (r.fields.seen & kHasConn) && (r.fields.seen & kHasTopic), pos,
            "expected a connection record with conn and topic");
    for_each_field(r.data, r.data_len, pos, [](const std::uint8_t*, std::size_t, const std::uint8_t*, std::size_t,
                                               std::size_t) {});
    pos = r.end;
  }
  for (std::uint32_t i = 0; i < header.fields.chunk_count; ++i) {
    require(pos < size, pos, "fewer chunk info records than the file header's chunk_count");
    const Record r = read_record(base, size, pos);
    const unsigned needed = kHasVer | kHasChunkPos | kHasStartTime | kHasEndTime | kHasCount;
    require(r.fields.op == rosbag::OP_CHUNK_INFO && (r.fields.seen & needed) == needed && r.fields.ver == 1, pos,
            "expected a chunk info record (version 1, chunk_pos, start_time, end_time, count)");
    require(static_cast<std::uint64_t>(r.fields.count) * 8 == r.data_len, pos,
            "chunk info whose count does not match its length");
    const auto chunk = index_records_after_chunk.find(static_cast<std::size_t>(r.fields.chunk_pos));
    require(chunk != index_records_after_chunk.end(), pos, "chunk info pointing at no chunk");
    require(chunk->second == r.fields.count, pos, "chunk info whose connection count differs from the chunk's index");
    pos = r.end;
  }
}

// Why rosbag could not open a bag, when the file header says so: a file cut short before its
// index (a copy interrupted, a disk filled up). Empty when that is not the explanation.
std::string truncation_hint(const std::string& path) {
  try {
    MappedFile file(path);
    if (file.size() < kVersionLength || std::memcmp(file.data(), kVersionLine, kVersionLength) != 0) {
      return "not a ROS bag (format 2.0): the file does not start with '#ROSBAG V2.0'";
    }
    const Record header = read_record(file.data(), file.size(), kVersionLength);
    if (header.fields.index_pos > file.size()) {
      return "the file is truncated (" + std::to_string(file.size()) + " bytes, but its index starts at byte " +
             std::to_string(header.fields.index_pos) + "); 'rosbag reindex' on a copy may recover the messages";
    }
  } catch (const BagInputError&) {
    return "the file is truncated or corrupt within its header record";
  }
  return "";
}

}  // namespace

std::vector<BagTopic> list_topics(rosbag::Bag& bag) {
  std::map<std::string, BagTopic> by_name;
  rosbag::View view(bag);
  for (const rosbag::ConnectionInfo* connection : view.getConnections()) {
    BagTopic& topic = by_name[connection->topic];
    topic.name = connection->topic;
    if (topic.datatype.empty()) topic.datatype = connection->datatype;
    else if (topic.datatype != connection->datatype) topic.datatype += "|" + connection->datatype;
  }
  for (auto& entry : by_name) {
    rosbag::View count(bag, rosbag::TopicQuery(entry.first));
    entry.second.messages = count.size();
  }
  std::vector<BagTopic> topics;
  for (auto& entry : by_name) topics.push_back(entry.second);
  return topics;
}

std::string describe_topics(const std::vector<BagTopic>& topics) {
  if (topics.empty()) return "(none: the bag has no messages)";
  std::vector<std::string> items;
  for (const BagTopic& t : topics) {
    items.push_back(t.name + " (" + t.datatype + ", " + std::to_string(t.messages) + " msgs)");
  }
  return join(items);
}

std::string resolve_topic(const std::string& requested, const std::vector<BagTopic>& topics,
                          const std::string& expected_datatype,
                          const std::string& preferred_namespace) {
  if (requested.empty() || requested == "/") throw BagInputError("empty topic name requested");
  const std::string wanted = strip_slash(requested);
  const bool absolute = requested[0] == '/';

  std::vector<const BagTopic*> candidates;
  for (const BagTopic& t : topics) {
    if (strip_slash(t.name) == wanted) candidates.push_back(&t);
  }
  if (candidates.empty() && !absolute) {
    for (const BagTopic& t : topics) {
      if (ends_with(t.name, "/" + wanted)) candidates.push_back(&t);
    }
    if (candidates.size() > 1 && !preferred_namespace.empty()) {
      std::vector<const BagTopic*> preferred;
      for (const BagTopic* t : candidates) {
        if (t->name == preferred_namespace + wanted) preferred.push_back(t);
      }
      if (preferred.size() == 1) candidates = preferred;
    }
  }
  if (candidates.empty()) {
    throw BagInputError("topic '" + requested + "' not found in the bag; its topics are: " +
                        describe_topics(topics));
  }
  if (candidates.size() > 1) {
    std::vector<std::string> names;
    for (const BagTopic* t : candidates) names.push_back(t->name);
    throw BagInputError("topic '" + requested + "' is ambiguous in the bag: " + join(names) +
                        "; pass the full name");
  }
  const BagTopic& found = *candidates.front();
  if (!expected_datatype.empty() && found.datatype != expected_datatype) {
    throw BagInputError("topic '" + found.name + "' has type " + found.datatype + ", expected " +
                        expected_datatype);
  }
  return found.name;
}

std::string topic_namespace(const std::string& resolved, const std::string& requested) {
  const std::string wanted = "/" + strip_slash(requested);
  const std::string full = resolved.empty() || resolved[0] == '/' ? resolved : "/" + resolved;
  if (ends_with(full, wanted)) return full.substr(0, full.size() - wanted.size()) + "/";
  return "/";
}

BagInputStats feed_bag(const std::string& path, const BagInputOptions& options,
                       core::DwellAssembler& assembler) {
  BagInputStats stats;
  stats.path = path;
  check_readable_file(path);
  // The chunk scan when the bag qualifies, else rosbag (which also produces the diagnostics of
  // unindexed, truncated or otherwise unreadable bags).
  std::unique_ptr<ChunkScanner> scanner;
  if (options.allow_chunk_scan) {
    scanner.reset(new ChunkScanner(path));
    if (!scanner->open()) scanner.reset();
  }
  rosbag::Bag bag;
  if (!scanner) open_bag(bag, path);

  try {
    const std::vector<BagTopic> topics = scanner ? scanner->topics() : list_topics(bag);
    // Resolve the IMU first; its namespace disambiguates the command topic, and vice versa.
    std::string imu_ns;
    try {
      stats.imu_topic = resolve_topic(options.imu_topic, topics, kImuType);
    } catch (const BagInputError& imu_error) {
      // Several namespaced IMU topics: retry in the namespace of the command topic when that one
      // is unambiguous; otherwise report the IMU topic's own problem.
      std::string command;
      try {
        command = resolve_topic(options.command_topic, topics, kCommandType);
      } catch (const BagInputError&) {
        throw imu_error;
      }
      stats.imu_topic =
          resolve_topic(options.imu_topic, topics, kImuType,
                        namespace_of(command, names::kGimbalCommandTopic, options.command_topic));
    }
    imu_ns = namespace_of(stats.imu_topic, names::kImuTopic, options.imu_topic);
    stats.command_topic = resolve_topic(options.command_topic, topics, kCommandType, imu_ns);

    ChunkScanTargets targets;
    std::uint64_t total = 0;
    if (scanner &&
        !(scanner->connections_of(stats.imu_topic, ros::message_traits::MD5Sum<sensor_msgs::Imu>::value(),
                                  &targets.imu, &total) &&
          scanner->connections_of(stats.command_topic, ros::message_traits::MD5Sum<GimbalCommand>::value(),
                                  &targets.command, &total))) {
      scanner.reset();  // another version of a message type: rosbag's instantiate() reports it
      open_bag(bag, path);
    }
    std::unique_ptr<rosbag::View> view;
    if (!scanner) {
      view.reset(new rosbag::View(bag, rosbag::TopicQuery(std::vector<std::string>{stats.imu_topic, stats.command_topic})));
      total = view->size();
    }
    Progress progress(options.progress_stream, options.progress_interval_s, options.progress_label, total);

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
      sample.stamp_s = imu.stamp.toSec();
      sample.outputs = Eigen::Vector3d(imu.x, imu.y, imu.z);
      assembler.add_sample(sample);
      if (options.raw_samples) options.raw_samples->push_back(sample);
      ++stats.imu_messages;
      progress.update(++done);
    };
    auto on_command = [&](const ros::Time& bag_time, const GimbalCommand& command) {
      on_time(bag_time);
      ++stats.command_messages;
      progress.update(++done);
      // The calibration node's acceptance test (CalibrationNode::handle_command), so that both
      // see the same commands.
      if (command.phase > GimbalCommand::PHASE_Z || command.state > GimbalCommand::DONE ||
          !std::isfinite(command.angle) || !core::step_in_protocol(command.step, command.steps) ||
          command.header.stamp.isZero()) {
        ++stats.invalid_commands;
        return;
      }
      const core::GimbalEvent event = to_core(command);
      stats.steps_announced[core::index(event.phase)] = event.steps;
      if (event.state == core::GimbalState::Done) stats.done_seen = true;
      assembler.add_command(event);
      if (options.raw_commands) options.raw_commands->push_back(event);
    };

    if (scanner) {
      stats.reader = "chunk scan";
      scanner->scan(targets, on_imu, on_command);
    } else {
      stats.reader = "rosbag::View";
      for (const rosbag::MessageInstance& m : *view) {
        if (m.getTopic() == stats.imu_topic) {
          const auto imu = m.instantiate<detail::ImuAccelerationOnly>();
          if (!imu) throw BagInputError("message on '" + stats.imu_topic + "' is not a sensor_msgs/Imu");
          on_imu(m.getTime(), *imu);
        } else {
          const auto command = m.instantiate<GimbalCommand>();
          if (!command) throw BagInputError("message on '" + stats.command_topic + "' is not a GimbalCommand");
          on_command(m.getTime(), *command);
        }
      }
    }
    assembler.flush();
    progress.finish(done);
    stats.read_wall_s = progress.seconds_since_start();
  } catch (const BagInputError&) {
    throw;
  } catch (const rosbag::BagException& e) {
    throw BagInputError("cannot read bag '" + path + "' (corrupt or truncated?): " + one_line(e.what()));
  } catch (const ros::Exception& e) {
    throw BagInputError("cannot read bag '" + path + "' (corrupt message data?): " + one_line(e.what()));
  } catch (const std::exception& e) {
    throw BagInputError("cannot read bag '" + path + "': " + one_line(e.what()));
  }

  stats.counters = assembler.counters();
  stats.open_dwell = assembler.current_dwell(&stats.open_dwell_phase, &stats.open_dwell_step,
                                             &stats.open_dwell_samples);
  return stats;
}

BagRun read_bag(const std::string& path, const BagInputOptions& options) {
  core::DwellAssembler assembler(options.assembler);
  BagRun run;
  run.stats = feed_bag(path, options, assembler);
  run.table = assembler.table();
  return run;
}

}  // namespace accel_intrinsics
