// The rosbag 2.0 file format, read straight from a memory map: record and header-field parsing,
// the chunk scan (connections and message records in file order, without rosbag::View) and the
// structure check that every bag passes before rosbag::Bag may open it. Every length is
// bounds-checked: a corrupt record is a BagInputError ("corrupt bag: ... at byte N"), never a
// crash. The fuzz target fuzz/bag_input_fuzz.cpp exercises this through read_bag().
// Format: http://wiki.ros.org/Bags/Format/2.0
#pragma once

#include <ros/time.h>
#include <rosbag/constants.h>

#include <cstdint>
#include <cstring>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace accel_intrinsics {

// Every failure to read a usable run: missing file, corrupt or truncated bag, topic not in the
// bag (the message names it and lists the bag's topics), wrong message type. One line of text.
class BagInputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// A topic of the bag with its message type, e.g. {"/imu/data_raw", "sensor_msgs/Imu"}.
struct BagTopic {
  std::string name;
  std::string datatype;
  std::uint64_t messages = 0;
};

namespace bag_format {

// Exception texts on one line ("one-line reason"), without a trailing period.
std::string one_line(std::string text);

// Throws BagInputError unless `path` is a non-empty regular file that can be stat'ed.
void check_readable_file(const std::string& path);

// Walks every record that rosbag::Bag and rosbag::View will read (file header, chunks and their
// index records, connection and chunk info records) and throws BagInputError unless each lies
// where rosbag will look and inside the file (or inside its decompressed chunk). Bags that rosbag
// rejects by itself with a clear message (unindexed, cut short before the index) pass.
void check_structure(const std::string& path);

// Why rosbag could not open a bag when the file header tells (a file cut short before its
// index, not a bag at all); empty when that is not the explanation.
std::string truncation_hint(const std::string& path);

// A read-only memory map of a whole file.
class MappedFile {
 public:
  explicit MappedFile(const std::string& path);
  ~MappedFile();
  MappedFile(const MappedFile&) = delete;
  MappedFile& operator=(const MappedFile&) = delete;
  const std::uint8_t* data() const { return data_; }
  std::size_t size() const { return size_; }

 private:
  int fd_ = -1;
  const std::uint8_t* data_ = nullptr;
  std::size_t size_ = 0;
};

[[noreturn]] void corrupt(std::size_t offset, const std::string& what);

inline std::uint32_t read_u32(const std::uint8_t* p) {
  std::uint32_t v;
  std::memcpy(&v, p, 4);  // bags are little-endian, like every platform ROS 1 runs on
  return v;
}

// The header fields the scan and the structure check need.
struct RecordFields {
  int op = -1;
  std::uint32_t conn = 0;
  ros::Time time;
  std::string compression;
  std::uint64_t index_pos = 0;
  bool encrypted = false;
  std::string topic;
  // For the structure check: chunk sizes, index counts.
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

// One record: header fields and the data span.
struct Record {
  RecordFields fields;
  const std::uint8_t* data = nullptr;
  std::uint32_t data_len = 0;
  std::size_t end = 0;  // offset just past the record
};

// The record at `pos` of the `size` bytes at `base`; throws BagInputError when it does not fit.
Record read_record(const std::uint8_t* base, std::size_t size, std::size_t pos);

// A bag read without rosbag: its connections and message counts from the index section, then
// the chunks in file order (= write order = the recorder's receive order). open() says whether
// the bag qualifies (format 2.0, indexed, unencrypted, uncompressed chunks: what `rosbag record`
// writes by default); if not, or if anything in it looks odd, the caller uses rosbag, whose
// checks and messages then apply.
class ChunkScanner {
 public:
  explicit ChunkScanner(const std::string& path) : file_(path) {}

  bool open();

  // The bag's topics, sorted by name, with their message counts.
  std::vector<BagTopic> topics() const;

  // Connection ids of `topic`, added to `ids`, their messages to `messages`; false when one has
  // an MD5 sum other than `md5sum`.
  bool connections_of(const std::string& topic, const std::string& md5sum,
                      std::vector<std::uint32_t>* ids, std::uint64_t* messages) const;

  // Calls on_message(conn, bag_time, data, length, offset) for each message record, in file
  // order; offset is the record's position in the file for error messages.
  template <typename OnMessage>
  void scan(OnMessage&& on_message) const {
    const std::uint8_t* base = file_.data();
    std::size_t pos = first_record_;
    while (pos < index_pos_) {
      const Record chunk = read_record(base, index_pos_, pos);
      if (chunk.fields.op == rosbag::OP_CHUNK) {
        const std::size_t chunk_offset = static_cast<std::size_t>(chunk.data - base);
        std::size_t inner = 0;
        while (inner < chunk.data_len) {
          const Record r = read_record(chunk.data, chunk.data_len, inner);
          if (r.fields.op == rosbag::OP_MSG_DATA) {
            on_message(r.fields.conn, r.fields.time, r.data, r.data_len, chunk_offset + inner);
          } else if (r.fields.op != rosbag::OP_CONNECTION) {
            corrupt(chunk_offset + inner,
                    "unexpected record (op " + std::to_string(r.fields.op) + ") in a chunk");
          }
          inner = r.end;
        }
      }
      pos = chunk.end;
    }
  }

 private:
  struct Connection {
    std::string topic;
    std::string datatype;
    std::string md5sum;
    std::uint64_t messages = 0;
  };

  bool read_index();
  bool chunks_uncompressed() const;

  MappedFile file_;
  std::size_t first_record_ = 0;
  std::size_t index_pos_ = 0;
  std::map<std::uint32_t, Connection> connections_;
};

}  // namespace bag_format
}  // namespace accel_intrinsics
