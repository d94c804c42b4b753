// The rosbag 2.0 format: records, the chunk scan and the structure check (bag_format.h).
#include "accel_intrinsics/ros/bag_format.h"

#include <fcntl.h>
#include <rosbag/stream.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <memory>
#include <unordered_map>

namespace accel_intrinsics {
namespace bag_format {

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

MappedFile::MappedFile(const std::string& path) {
  fd_ = ::open(path.c_str(), O_RDONLY);
  if (fd_ < 0) throw BagInputError("cannot open bag '" + path + "': " + std::strerror(errno));
  struct stat info;
  if (::fstat(fd_, &info) != 0) throw BagInputError("cannot stat bag '" + path + "'");
  size_ = static_cast<std::size_t>(info.st_size);
  if (size_ > 0) {
    void* p = ::mmap(nullptr, size_, PROT_READ, MAP_PRIVATE, fd_, 0);
    if (p == MAP_FAILED)
      throw BagInputError("cannot map bag '" + path + "': " + std::strerror(errno));
    data_ = static_cast<const std::uint8_t*>(p);
    ::madvise(p, size_, MADV_SEQUENTIAL);
  }
}

MappedFile::~MappedFile() {
  if (data_) ::munmap(const_cast<std::uint8_t*>(data_), size_);
  if (fd_ >= 0) ::close(fd_);
}

void corrupt(std::size_t offset, const std::string& what) {
  throw BagInputError("corrupt bag: " + what + " at byte " + std::to_string(offset));
}

namespace {

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
  for_each_field(p, len, offset,
                 [&f](const std::uint8_t* field, std::size_t name_len, const std::uint8_t* value,
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

constexpr char kVersionLine[] = "#ROSBAG V2.0\n";
constexpr std::size_t kVersionLength = sizeof(kVersionLine) - 1;

}  // namespace

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

bool ChunkScanner::open() {
  try {
    return read_index() && chunks_uncompressed();
  } catch (const BagInputError&) {
    return false;
  }
}

std::vector<BagTopic> ChunkScanner::topics() const {
  std::map<std::string, BagTopic> by_name;
  for (const auto& entry : connections_) {
    const Connection& c = entry.second;
    BagTopic& t = by_name[c.topic];
    t.name = c.topic;
    if (t.datatype.empty())
      t.datatype = c.datatype;
    else if (t.datatype != c.datatype)
      t.datatype += "|" + c.datatype;
    t.messages += c.messages;
  }
  std::vector<BagTopic> out;
  for (auto& entry : by_name) out.push_back(entry.second);
  return out;
}

bool ChunkScanner::connections_of(const std::string& topic, const std::string& md5sum,
                                  std::vector<std::uint32_t>* ids, std::uint64_t* messages) const {
  for (const auto& entry : connections_) {
    if (entry.second.topic != topic) continue;
    if (entry.second.md5sum != md5sum) return false;
    ids->push_back(entry.first);
    *messages += entry.second.messages;
  }
  return true;
}

// File header, then the index section: connection records and chunk info records.
bool ChunkScanner::read_index() {
  const std::uint8_t* base = file_.data();
  const std::size_t size = file_.size();
  if (size < kVersionLength || std::memcmp(base, kVersionLine, kVersionLength) != 0) return false;
  const Record header = read_record(base, size, kVersionLength);
  if (header.fields.op != rosbag::OP_FILE_HEADER || header.fields.encrypted) return false;
  // index_pos = 0: the recorder never closed the bag (unindexed); rosbag says so.
  if (header.fields.index_pos == 0 || header.fields.index_pos >= size) return false;
  first_record_ = header.end;
  index_pos_ = static_cast<std::size_t>(header.fields.index_pos);
  std::map<std::uint32_t, std::uint64_t> message_counts;
  std::size_t pos = index_pos_;
  while (pos < size) {
    const Record r = read_record(base, size, pos);
    if (r.fields.op == rosbag::OP_CONNECTION) {
      Connection& c = connections_[r.fields.conn];
      c.topic = r.fields.topic;
      for_each_field(r.data, r.data_len, pos,
                     [&c](const std::uint8_t* field, std::size_t name_len,
                          const std::uint8_t* value, std::size_t value_len, std::size_t) {
                       if (field_is(field, name_len, "type"))
                         c.datatype.assign(reinterpret_cast<const char*>(value), value_len);
                       if (field_is(field, name_len, "md5sum"))
                         c.md5sum.assign(reinterpret_cast<const char*>(value), value_len);
                     });
    } else if (r.fields.op == rosbag::OP_CHUNK_INFO) {
      if (r.data_len % 8 != 0) return false;
      for (std::uint32_t i = 0; i < r.data_len; i += 8) {
        message_counts[read_u32(r.data + i)] += read_u32(r.data + i + 4);
      }
    } else {
      return false;  // not a 2.0 index section as rosbag writes it
    }
    pos = r.end;
  }
  for (auto& entry : connections_) {
    if (entry.second.topic.empty() || entry.second.datatype.empty()) return false;
    entry.second.messages = message_counts[entry.first];
  }
  return true;
}

bool ChunkScanner::chunks_uncompressed() const {
  std::size_t pos = first_record_;
  while (pos < index_pos_) {
    const Record r = read_record(file_.data(), index_pos_, pos);
    if (r.fields.op == rosbag::OP_CHUNK && r.fields.compression != rosbag::COMPRESSION_NONE)
      return false;
    pos = r.end;
  }
  return true;
}

namespace {

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
const std::uint8_t* chunk_content(const Record& chunk, std::size_t offset,
                                  std::vector<std::uint8_t>* buffer, std::size_t* length) {
  const std::string& compression = chunk.fields.compression;
  require((chunk.fields.seen & kHasCompression) && (chunk.fields.seen & kHasSize), offset,
          "chunk header without compression or size");
  if (compression == rosbag::COMPRESSION_NONE) {
    require(chunk.fields.size == chunk.data_len, offset,
            "uncompressed chunk whose size differs from its length");
    *length = chunk.data_len;
    return chunk.data;
  }
  require(compression == rosbag::COMPRESSION_BZ2 || compression == rosbag::COMPRESSION_LZ4, offset,
          "unknown chunk compression '" + compression + "'");
  const std::uint64_t size = chunk.fields.size;
  require(size <= kMaxChunkBytes && size <= kMaxCompressionRatio * chunk.data_len + (1u << 20),
          offset,
          "chunk claims " + std::to_string(size) + " bytes uncompressed from " +
              std::to_string(chunk.data_len));
  // 0xff: bytes the decompressor did not write read as a record length past the end.
  buffer->assign(static_cast<std::size_t>(size), 0xff);
  try {
    std::unique_ptr<rosbag::Stream> stream;
    if (compression == rosbag::COMPRESSION_BZ2)
      stream.reset(new rosbag::BZ2Stream(nullptr));
    else
      stream.reset(new rosbag::LZ4Stream(nullptr));
    if (size > 0) {
      stream->decompress(buffer->data(), static_cast<unsigned int>(size),
                         const_cast<std::uint8_t*>(chunk.data), chunk.data_len);
    }
  } catch (const std::exception& e) {
    corrupt(offset, "chunk does not decompress (" + one_line(e.what()) + ")");
  }
  *length = buffer->size();
  return buffer->data();
}

}  // namespace

void check_structure(const std::string& path) {
  MappedFile file(path);
  const std::uint8_t* base = file.data();
  const std::size_t size = file.size();
  if (size < kVersionLength || std::memcmp(base, kVersionLine, kVersionLength) != 0) {
    throw BagInputError("not a ROS bag (format 2.0): the file does not start with '#ROSBAG V2.0'");
  }
  const Record header = read_record(base, size, kVersionLength);
  require(header.fields.op == rosbag::OP_FILE_HEADER, kVersionLength,
          "first record is not a file header");
  if (header.fields.encrypted) {
    throw BagInputError("the bag is encrypted; decrypt a copy first ('rosbag decrypt')");
  }
  const std::uint64_t index_pos = header.fields.index_pos;
  if (index_pos == 0 || index_pos > size) return;  // unindexed or cut short: rosbag says so
  require((header.fields.seen & kHasConnCount) && (header.fields.seen & kHasChunkCount),
          kVersionLength, "file header without conn_count or chunk_count");
  require(index_pos >= header.end, kVersionLength, "index_pos inside the file header");

  // Chunks, each followed by its index records, up to index_pos. Per chunk: the offsets of its
  // message records with their connection, and how many index records follow it.
  std::map<std::size_t, std::uint32_t> index_records_after_chunk;
  std::unordered_map<std::uint32_t, std::uint32_t>
      messages_at;  // offset in chunk -> conn, last chunk
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
    require(r.fields.op == rosbag::OP_CONNECTION && (r.fields.seen & kHasConn) &&
                (r.fields.seen & kHasTopic),
            pos, "expected a connection record with conn and topic");
    for_each_field(
        r.data, r.data_len, pos,
        [](const std::uint8_t*, std::size_t, const std::uint8_t*, std::size_t, std::size_t) {});
    pos = r.end;
  }
  for (std::uint32_t i = 0; i < header.fields.chunk_count; ++i) {
    require(pos < size, pos, "fewer chunk info records than the file header's chunk_count");
    const Record r = read_record(base, size, pos);
    const unsigned needed = kHasVer | kHasChunkPos | kHasStartTime | kHasEndTime | kHasCount;
    require(r.fields.op == rosbag::OP_CHUNK_INFO && (r.fields.seen & needed) == needed &&
                r.fields.ver == 1,
            pos,
            "expected a chunk info record (version 1, chunk_pos, start_time, end_time, count)");
    require(static_cast<std::uint64_t>(r.fields.count) * 8 == r.data_len, pos,
            "chunk info whose count does not match its length");
    const auto chunk = index_records_after_chunk.find(static_cast<std::size_t>(r.fields.chunk_pos));
    require(chunk != index_records_after_chunk.end(), pos, "chunk info pointing at no chunk");
    require(chunk->second == r.fields.count, pos,
            "chunk info whose connection count differs from the chunk's index");
    pos = r.end;
  }
}

// Why rosbag could not open a bag, when the file header says so: a file cut short before its
// index (a copy interrupted, a disk filled up). Empty when that is not the explanation.
std::string truncation_hint(const std::string& path) {
  try {
    MappedFile file(path);
    if (file.size() < kVersionLength ||
        std::memcmp(file.data(), kVersionLine, kVersionLength) != 0) {
      return "not a ROS bag (format 2.0): the file does not start with '#ROSBAG V2.0'";
    }
    const Record header = read_record(file.data(), file.size(), kVersionLength);
    if (header.fields.index_pos > file.size()) {
      return "the file is truncated (" + std::to_string(file.size()) +
             " bytes, but its index starts at byte " + std::to_string(header.fields.index_pos) +
             "); 'rosbag reindex' on a copy may recover the messages";
    }
  } catch (const BagInputError&) {
    return "the file is truncated or corrupt within its header record";
  }
  return "";
}

}  // namespace bag_format
}  // namespace accel_intrinsics
