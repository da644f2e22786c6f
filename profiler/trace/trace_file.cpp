#include "trace/trace_file.hpp"

#include <algorithm>
#include <bit>
#include <cstring>
#include <exception>
#include <new>
#include <stdexcept>
#include <system_error>
#include <thread>
#include <utility>

#include <sys/mman.h>

#include "error.hpp"
#include "output_path.hpp"

namespace hp::trace {

static_assert(std::endian::native == std::endian::little, "the trace format is little-endian");

namespace {

bool printable_ascii(const std::string& s) {
  return std::all_of(s.begin(), s.end(), [](char c) { return c >= 0x20 && c <= 0x7E; });
}

constexpr uint32_t tag(char a, char b, char c, char d) {
  return uint32_t(uint8_t(a)) | uint32_t(uint8_t(b)) << 8 | uint32_t(uint8_t(c)) << 16 | uint32_t(uint8_t(d)) << 24;
}
constexpr uint32_t kTagBuffers = tag('B', 'U', 'F', 'S');
constexpr uint32_t kTagPass = tag('P', 'A', 'S', 'S');
constexpr uint32_t kTagRecords = tag('R', 'E', 'C', 'S');
constexpr uint32_t kTagCoded = tag('R', 'E', 'C', 'V');
constexpr uint32_t kTagEnd = tag('E', 'N', 'D', ' ');

struct FileHeader {
  char magic[8];
  uint32_t version;
  uint32_t flags;
  uint32_t image_width;
  uint32_t image_height;
  uint64_t reserved;
};
static_assert(sizeof(FileHeader) == 32);

struct ChunkHeader {
  uint32_t tag;
  uint32_t reserved;
  uint64_t payload_bytes;
};
static_assert(sizeof(ChunkHeader) == 16);

struct BufferEntry {
  uint32_t id, kind;
  uint64_t base_address, size_bytes;
  uint32_t texel_bytes, width, height, row_pitch_bytes, tile_width, tile_height, name_bytes;
  // The alignment padding, named so that it is written as zeros: left implicit, it carried whatever the
  // stack held, and two captures of one frame differed in those bytes. Readers ignore it.
  uint32_t reserved;
};
static_assert(sizeof(BufferEntry) == 56);

struct PassEntry {
  uint32_t index;
  uint32_t workgroup_size[3];
  uint32_t workgroup_count[3];
  uint32_t name_bytes;
};
static_assert(sizeof(PassEntry) == 32);

struct RecordsEntry {
  uint32_t pass, reserved;
  uint64_t first_workgroup, end_workgroup, count;
};
static_assert(sizeof(RecordsEntry) == 32);

struct CodedEntry {
  uint32_t pass, coding;
  uint64_t first_workgroup, end_workgroup, count, coded_bytes;
};
static_assert(sizeof(CodedEntry) == 40);

struct EndEntry {
  uint64_t total_records;
  uint32_t passes, reserved;
};
static_assert(sizeof(EndEntry) == 16);

size_t pad8(size_t n) { return (8 - n % 8) % 8; }

// Reads bytes out of an in-memory payload, failing (via the reader) when a field runs past its end.
struct Cursor {
  const std::vector<char>& data;
  size_t pos = 0;
  bool get(void* out, size_t bytes) {
    if (pos + bytes > data.size()) return false;
    std::memcpy(out, data.data() + pos, bytes);
    pos += bytes;
    return true;
  }
};

}  // namespace

// ------------------------------------------------------------------------------------------------ writer

// A constructor that throws runs no destructor of its own: this closes the FILE unless disarmed at the end
// of the constructor.
namespace {
struct CloseOnThrow {
  std::FILE*& file;
  bool armed = true;
  ~CloseOnThrow() {
    if (armed && file) {
      std::fclose(file);
      file = nullptr;
    }
  }
};
}  // namespace

TraceWriter::TraceWriter(std::filesystem::path path, const TraceHeader& header, uint32_t version, uint32_t coding)
    : out_(std::move(path)), version_(version), coding_(coding) {
  if (version != kTraceVersion && version != kTraceVersionRaw)
    throw InputError(out_.path().string() + ": trace format version " + std::to_string(version) +
                     " cannot be written (1 or 2)");
  if (coding != kCodingDeltaVarint && coding != kCodingSizedGroups)
    throw InputError(out_.path().string() + ": record coding " + std::to_string(coding) +
                     " cannot be written (1 or 2)");
  file_ = std::fopen(out_.temp_path().c_str(), "wb");
  if (!file_) throw InputError(out_.path().string() + ": cannot create trace file: " + std::strerror(errno));
  CloseOnThrow guard{file_};  // and out_'s destructor removes the temporary
  FileHeader fh{};
  std::memcpy(fh.magic, kTraceMagic, 8);
  fh.version = version_;
  fh.image_width = header.image_width;
  fh.image_height = header.image_height;
  put(&fh, sizeof fh);

  std::vector<char> payload;
  auto append = [&](const void* p, size_t n) {
    payload.insert(payload.end(), static_cast<const char*>(p), static_cast<const char*>(p) + n);
  };
  uint32_t count = uint32_t(header.buffers.size());
  append(&count, 4);
  for (const BufferInfo& b : header.buffers) {
    BufferEntry e{b.id,     uint32_t(b.kind),  b.base_address, b.size_bytes,  b.texel_bytes,           b.width,
                  b.height, b.row_pitch_bytes, b.tile_width,   b.tile_height, uint32_t(b.name.size()), 0};
    append(&e, sizeof e);
    append(b.name.data(), b.name.size());
    payload.resize(payload.size() + pad8(b.name.size()), 0);
  }
  put_chunk_header(kTagBuffers, payload.size());
  put(payload.data(), payload.size());
  guard.armed = false;
}

TraceWriter::~TraceWriter() {
  // Unfinished: out_ removes the temporary, so nothing that looks like a trace is left.
  if (file_) std::fclose(file_);
}

void TraceWriter::put(const void* data, size_t bytes) {
  if (bytes && std::fwrite(data, 1, bytes, file_) != bytes)
    throw InputError(out_.path().string() + ": write failed: " + std::strerror(errno));
  bytes_written_ += bytes;
}

void TraceWriter::put_chunk_header(uint32_t t, uint64_t payload_bytes) {
  ChunkHeader ch{t, 0, payload_bytes};
  put(&ch, sizeof ch);
}

uint32_t TraceWriter::begin_pass(const PassInfo& pass) {
  PassEntry e{passes_, {}, {}, uint32_t(pass.name.size())};
  for (int i = 0; i < 3; ++i) {
    e.workgroup_size[i] = pass.dispatch.workgroup_size[i];
    e.workgroup_count[i] = pass.dispatch.workgroup_count[i];
  }
  size_t pad = pad8(sizeof e + pass.name.size());
  put_chunk_header(kTagPass, sizeof e + pass.name.size() + pad);
  put(&e, sizeof e);
  put(pass.name.data(), pass.name.size());
  const uint64_t zero = 0;
  put(&zero, pad);
  per_group_.push_back(pass.dispatch.invocations_per_workgroup());
  return passes_++;
}

void TraceWriter::write_records(uint32_t pass, std::span<const TraceRecord> records, uint64_t first_workgroup,
                                uint64_t end_workgroup) {
  const std::span<const TraceRecord> one[] = {records};
  write_record_parts(pass, one, first_workgroup, end_workgroup);
}

bool TraceWriter::code_parts(SliceEncoder& encoder, std::vector<TraceRecord>* gathered, uint32_t pass,
                             std::span<const std::span<const TraceRecord>> parts, uint64_t first_workgroup,
                             uint64_t end_workgroup, std::vector<uint8_t>& out) const {
  const uint64_t per_group = per_group_.at(pass);
  if (encoder.encode_parts(parts, first_workgroup, end_workgroup, per_group, out, coding_)) return true;
  if (parts.size() == 1) {
    encoder.encode(parts[0], first_workgroup, end_workgroup, per_group, out, coding_);
    return true;
  }
  if (!gathered) return false;
  gathered->clear();
  for (const auto& part : parts) gathered->insert(gathered->end(), part.begin(), part.end());
  encoder.encode(*gathered, first_workgroup, end_workgroup, per_group, out, coding_);
  return true;
}

bool TraceWriter::write_record_parts(uint32_t pass, std::span<const std::span<const TraceRecord>> parts,
                                     uint64_t first_workgroup, uint64_t end_workgroup) {
  uint64_t count = 0;
  for (const auto& part : parts) count += part.size();
  if (version_ == kTraceVersionRaw) {
    RecordsEntry e{pass, 0, first_workgroup, end_workgroup, count};
    put_chunk_header(kTagRecords, sizeof e + count * sizeof(TraceRecord));
    put(&e, sizeof e);
    for (const auto& part : parts) put(part.data(), part.size_bytes());
    total_records_ += count;
    return true;
  }
  coded_.clear();
  if (!code_parts(encoder_, nullptr, pass, parts, first_workgroup, end_workgroup, coded_)) {
    return false;  // the caller puts them together, in place
  }
  put_coded(pass, first_workgroup, end_workgroup, count, coded_);
  return true;
}

TraceSink::Commit TraceWriter::stage_record_parts(uint32_t pass, std::span<const std::span<const TraceRecord>> parts,
                                                  uint64_t first_workgroup, uint64_t end_workgroup) {
  if (version_ == kTraceVersionRaw) return nullptr;
  std::unique_ptr<Staging> staging;
  {
    const std::lock_guard lock(staging_mutex_);
    if (!staging_.empty()) {
      staging = std::move(staging_.back());
      staging_.pop_back();
    }
  }
  if (!staging) staging = std::make_unique<Staging>();
  uint64_t count = 0;
  for (const auto& part : parts) count += part.size();
  std::vector<uint8_t> coded;
  std::exception_ptr error;
  try {
    code_parts(staging->encoder, &staging->gathered, pass, parts, first_workgroup, end_workgroup, coded);
  } catch (...) {
    error = std::current_exception();
  }
  {
    const std::lock_guard lock(staging_mutex_);
    staging_.push_back(std::move(staging));
  }
  if (error) std::rethrow_exception(error);
  return [this, pass, first_workgroup, end_workgroup, count, coded = std::move(coded)] {
    put_coded(pass, first_workgroup, end_workgroup, count, coded);
  };
}

// The 'RECV' chunk of a coded slice.
void TraceWriter::put_coded(uint32_t pass, uint64_t first_workgroup, uint64_t end_workgroup, uint64_t records,
                            std::span<const uint8_t> coded) {
  CodedEntry e{pass, coding_, first_workgroup, end_workgroup, records, coded.size()};
  const size_t pad = pad8(coded.size());
  put_chunk_header(kTagCoded, sizeof e + coded.size() + pad);
  put(&e, sizeof e);
  put(coded.data(), coded.size());
  const uint64_t zero = 0;
  put(&zero, pad);
  total_records_ += records;
}

void TraceWriter::finish() {
  EndEntry e{total_records_, passes_, 0};
  put_chunk_header(kTagEnd, sizeof e);
  put(&e, sizeof e);
  if (std::fclose(file_) != 0) {
    file_ = nullptr;
    throw InputError(out_.path().string() + ": close failed: " + std::strerror(errno));
  }
  file_ = nullptr;
  out_.commit();
}

// ------------------------------------------------------------------------------------------------ reader

// Buffer and pass names come from the file: keep the message one line whatever bytes they hold.
static std::string one_line(std::string s) {
  for (char& ch : s)
    if (ch == '\n' || ch == '\r') ch = ' ';
  return s;
}

void TraceReader::fail(const std::string& what) const { throw InputError(one_line(path_.string() + ": " + what)); }

void TraceReader::read_buffer_table(const std::vector<char>& payload, const std::string& at) {
  Cursor c{payload};
  uint32_t count = 0;
  if (!c.get(&count, 4)) fail("malformed BUFS" + at);
  for (uint32_t i = 0; i < count; ++i) {
    BufferEntry e{};
    if (!c.get(&e, sizeof e)) fail("malformed BUFS" + at + ": entry " + std::to_string(i));
    BufferInfo b;
    // Bound the name by the chunk before allocating it (a corrupt length once asked for 4 GiB).
    if (e.name_bytes > payload.size() - c.pos)
      fail("malformed BUFS" + at + ": name of entry " + std::to_string(i) + " runs past the chunk");
    b.name.resize(e.name_bytes);
    if (!c.get(b.name.data(), e.name_bytes)) fail("malformed BUFS" + at + ": name of entry " + std::to_string(i));
    // The writer's names are printable ASCII; anything else is corruption (and cannot go into JSON).
    if (!printable_ascii(b.name))
      fail("malformed BUFS" + at + ": name of entry " + std::to_string(i) + " is not printable ASCII");
    c.pos += pad8(e.name_bytes);
    if (e.kind > uint32_t(BufferKind::image_tiled) || e.id > HP_TRACE_BUFFER_MASK)
      fail("BUFS" + at + ": entry " + std::to_string(i) + " has an invalid kind or id");
    b.id = e.id;
    b.kind = BufferKind(e.kind);
    b.base_address = e.base_address;
    b.size_bytes = e.size_bytes;
    b.texel_bytes = e.texel_bytes;
    b.width = e.width;
    b.height = e.height;
    b.row_pitch_bytes = e.row_pitch_bytes;
    b.tile_width = e.tile_width;
    b.tile_height = e.tile_height;
    if (b.kind != BufferKind::buffer &&
        (b.texel_bytes == 0 || b.width == 0 || b.height == 0 ||
         (b.kind == BufferKind::image_linear && b.row_pitch_bytes < uint64_t(b.width) * b.texel_bytes) ||
         (b.kind == BufferKind::image_tiled && (b.tile_width == 0 || b.tile_height == 0))))
      fail("BUFS" + at + ": image '" + b.name + "' has an impossible layout");
    if (header_.find_buffer(b.id)) fail("BUFS" + at + ": duplicate buffer id " + std::to_string(b.id));
    header_.buffers.push_back(std::move(b));
  }
}

void TraceReader::read_pass(const std::vector<char>& payload, const std::string& at) {
  Cursor c{payload};
  PassEntry e{};
  if (!c.get(&e, sizeof e)) fail("malformed PASS" + at);
  if (e.index != passes_.size()) fail("PASS" + at + " out of order");
  PassInfo p;
  if (e.name_bytes > payload.size() - c.pos) fail("malformed PASS" + at + ": name runs past the chunk");
  p.name.resize(e.name_bytes);
  if (!c.get(p.name.data(), e.name_bytes)) fail("malformed PASS" + at);
  if (!printable_ascii(p.name)) fail("malformed PASS" + at + ": the name is not printable ASCII");
  for (int i = 0; i < 3; ++i) {
    p.dispatch.workgroup_size[i] = e.workgroup_size[i];
    p.dispatch.workgroup_count[i] = e.workgroup_count[i];
    if (e.workgroup_size[i] == 0) fail("PASS '" + p.name + "': workgroup size 0");
  }
  unsigned __int128 invocations = 1;  // six 32-bit factors: 128 bits hold any product of four, then clamp
  for (int i = 0; i < 3 && invocations <= 0xFFFFFFFFull; ++i)
    invocations *= (unsigned __int128)e.workgroup_size[i] * e.workgroup_count[i];
  if (invocations > 0xFFFFFFFFull) fail("PASS '" + p.name + "': 2^32 invocations or more");
  passes_.push_back(std::move(p));
}

// A workgroup belongs to at most one slice: sliced replay (read_slices) relies on it.
void TraceReader::check_slices_disjoint() const {
  std::vector<const Chunk*> order;
  for (const Chunk& c : chunks_)
    if (c.first_workgroup < c.end_workgroup) order.push_back(&c);
  std::sort(order.begin(), order.end(), [](const Chunk* a, const Chunk* b) {
    return a->pass != b->pass ? a->pass < b->pass : a->first_workgroup < b->first_workgroup;
  });
  for (size_t i = 1; i < order.size(); ++i)
    if (order[i]->pass == order[i - 1]->pass && order[i]->first_workgroup < order[i - 1]->end_workgroup)
      fail("RECS slices of pass " + std::to_string(order[i]->pass) + " overlap at workgroup " +
           std::to_string(order[i]->first_workgroup));
}

TraceReader::TraceReader(std::filesystem::path path) : path_(std::move(path)) {
  std::error_code dir_ec;
  if (std::filesystem::is_directory(path_, dir_ec)) fail("is a directory, not a trace file");
  file_ = std::fopen(path_.c_str(), "rb");
  if (!file_) fail(std::string("cannot open trace file: ") + std::strerror(errno));
  // Every fail() below throws out of the constructor: without this each rejected file leaked its FILE and
  // descriptor (fuzzer find: a tool reading many bad traces runs out of descriptors).
  CloseOnThrow guard{file_};
  std::fseek(file_, 0, SEEK_END);
  const uint64_t file_size = uint64_t(std::ftell(file_));
  std::fseek(file_, 0, SEEK_SET);

  FileHeader fh{};
  if (std::fread(&fh, sizeof fh, 1, file_) != 1) fail("truncated: shorter than the 32-byte header");
  if (std::memcmp(fh.magic, kTraceMagic, 8) != 0) fail("bad magic: not a hybridprof trace file");
  if (fh.version != kTraceVersion && fh.version != kTraceVersionRaw)
    fail("unsupported version " + std::to_string(fh.version) + " (this build reads versions 1 and 2)");
  version_ = fh.version;
  header_.image_width = fh.image_width;
  header_.image_height = fh.image_height;

  uint64_t pos = sizeof fh;
  bool have_buffers = false, have_end = false;
  uint64_t total = 0;
  while (pos < file_size && !have_end) {
    ChunkHeader ch{};
    if (file_size - pos < sizeof ch || std::fread(&ch, sizeof ch, 1, file_) != 1)
      fail("truncated: chunk header at byte " + std::to_string(pos));
    pos += sizeof ch;
    if (ch.payload_bytes > file_size - pos)
      fail("truncated: chunk at byte " + std::to_string(pos - sizeof ch) + " declares " +
           std::to_string(ch.payload_bytes) + " bytes, " + std::to_string(file_size - pos) + " remain");
    const std::string at = " chunk at byte " + std::to_string(pos - sizeof ch);
    // Either records chunk, once its own fields are checked: its workgroup range lies in its pass's dispatch.
    const auto add_chunk = [&](const char* name, const Chunk& c) {
      const uint64_t groups = passes_[c.pass].dispatch.workgroups();
      if (c.first_workgroup > c.end_workgroup || c.end_workgroup > groups)
        fail(name + at + ": workgroups [" + std::to_string(c.first_workgroup) + ", " + std::to_string(c.end_workgroup) +
             ") outside the dispatch of " + std::to_string(groups));
      chunks_.push_back(c);
      total += c.count;
    };
    if (ch.tag == kTagRecords) {
      RecordsEntry e{};
      if (ch.payload_bytes < sizeof e || std::fread(&e, sizeof e, 1, file_) != 1) fail("malformed RECS" + at);
      if (e.pass >= passes_.size()) fail("RECS" + at + " names pass " + std::to_string(e.pass) + " before its PASS");
      // Compare by division: count * 16 wraps for counts >= 2^60, which made a tiny chunk claim 2^60 records.
      if ((ch.payload_bytes - sizeof e) % sizeof(TraceRecord) != 0 ||
          e.count != (ch.payload_bytes - sizeof e) / sizeof(TraceRecord))
        fail("malformed RECS" + at + ": record count does not match the chunk size");
      add_chunk("RECS", {e.pass, pos + sizeof e, e.count, e.first_workgroup, e.end_workgroup});
    } else if (ch.tag == kTagCoded && version_ >= 2) {
      CodedEntry e{};
      if (ch.payload_bytes < sizeof e || std::fread(&e, sizeof e, 1, file_) != 1) fail("malformed RECV" + at);
      if (e.pass >= passes_.size()) fail("RECV" + at + " names pass " + std::to_string(e.pass) + " before its PASS");
      if (e.coding != kCodingDeltaVarint && e.coding != kCodingSizedGroups)
        fail("RECV" + at + ": unknown coding " + std::to_string(e.coding));
      // A record takes at least one byte: a count beyond the bytes is corruption, not an allocation to make.
      if (e.coded_bytes > ch.payload_bytes - sizeof e || e.count > e.coded_bytes ||
          ch.payload_bytes - sizeof e - e.coded_bytes != pad8(e.coded_bytes))
        fail("malformed RECV" + at + ": record count or coded size does not match the chunk size");
      add_chunk("RECV", {e.pass, pos + sizeof e, e.count, e.first_workgroup, e.end_workgroup, e.coded_bytes, e.coding});
    } else {
      std::vector<char> payload(ch.payload_bytes);
      if (!payload.empty() && std::fread(payload.data(), 1, payload.size(), file_) != payload.size())
        fail("truncated" + at);
      Cursor c{payload};
      if (ch.tag == kTagBuffers) {
        if (have_buffers) fail("second BUFS" + at);
        have_buffers = true;
        read_buffer_table(payload, at);
      } else if (ch.tag == kTagPass) {
        read_pass(payload, at);
      } else if (ch.tag == kTagEnd) {
        EndEntry e{};
        if (!c.get(&e, sizeof e)) fail("malformed END" + at);
        if (e.total_records != total || e.passes != passes_.size())
          fail("END" + at + " counts " + std::to_string(e.total_records) + " records in " + std::to_string(e.passes) +
               " passes, the file holds " + std::to_string(total) + " in " + std::to_string(passes_.size()));
        have_end = true;
        if (pos + ch.payload_bytes != file_size)
          fail(std::to_string(file_size - pos - ch.payload_bytes) + " bytes after the END chunk");
      } else {
        fail("unknown chunk tag" + at);
      }
    }
    pos += ch.payload_bytes;
    std::fseek(file_, long(pos), SEEK_SET);
  }
  if (!have_buffers) fail("truncated: no buffer table");
  if (!have_end) fail("truncated: no END chunk (the writer did not finish)");
  check_slices_disjoint();
  guard.armed = false;
}

TraceReader::~TraceReader() {
  if (file_) std::fclose(file_);
}

uint64_t TraceReader::record_count(uint32_t pass) const {
  uint64_t n = 0;
  for (const Chunk& c : chunks_)
    if (c.pass == pass) n += c.count;
  return n;
}

void TraceReader::read_chunk(const Chunk& c, TraceRecord* out, uint32_t* group_begin) const {
  std::fseek(file_, long(c.file_offset), SEEK_SET);
  if (c.coded_bytes > 0) {
    // The coded slice is small (about 3 bytes a record): read whole, decoded into `out`, each run of
    // decoded records validated while it is in the host's caches.
    if (coded_.size() < c.coded_bytes) coded_.resize(c.coded_bytes);
    if (std::fread(coded_.data(), 1, c.coded_bytes, file_) != c.coded_bytes)
      fail("truncated records of pass " + std::to_string(c.pass));
    const std::string where = path_.string() + ": pass '" + passes_[c.pass].name + "'";
    const PassInfo& pass = passes_[c.pass];
    decode_slice(
        std::span<const uint8_t>(coded_.data(), c.coded_bytes), c.count, c.first_workgroup, c.end_workgroup,
        pass.dispatch.invocations_per_workgroup(), out, where,
        [&](const TraceRecord* r, uint64_t first, uint64_t n) {
          validate_records(where, header_, pass, std::span<const TraceRecord>(r, n), c.first_workgroup, c.end_workgroup,
                           first);
        },
        group_begin, c.coding);
    return;
  }
  // Block by block, each validated while it is still in the host's caches (one pass over memory, not two).
  constexpr uint64_t kBlock = 1 << 15;  // records (512 KiB)
  const std::string where = path_.string() + ": pass '" + passes_[c.pass].name + "'";
  for (uint64_t at = 0; at < c.count; at += kBlock) {
    const uint64_t n = std::min(kBlock, c.count - at);
    if (std::fread(out + at, sizeof(TraceRecord), n, file_) != n)
      fail("truncated records of pass " + std::to_string(c.pass));
    validate_records(where, header_, passes_[c.pass], std::span<const TraceRecord>(out + at, n), c.first_workgroup,
                     c.end_workgroup, at);
  }
}

std::vector<TraceRecord> TraceReader::read_pass(uint32_t pass) const {
  if (pass >= passes_.size()) fail("no pass " + std::to_string(pass));
  std::vector<TraceRecord> out(record_count(pass));
  size_t at = 0;
  for (const Chunk& c : chunks_) {
    if (c.pass != pass) continue;
    read_chunk(c, out.data() + at);
    at += c.count;
  }
  return out;
}

namespace {

// A slice buffer in anonymous memory the kernel may back with 2 MiB pages. Filled from the file once per
// slice and reused: with 4 KiB pages, the first touch of a 64 MiB buffer is 16 K page faults, which on
// the VMs this runs on cost more than reading the slice (a page fault there is several microseconds).
// Grows, never shrinks; not initialized (every record is read into it before use).
class RecordBuffer {
 public:
  RecordBuffer() = default;
  RecordBuffer(const RecordBuffer&) = delete;
  RecordBuffer& operator=(const RecordBuffer&) = delete;
  ~RecordBuffer() { release(); }
  TraceRecord* reserve(uint64_t count) {
    if (count > capacity_) {
      release();
      constexpr uint64_t kHuge = 2u << 20;
      const uint64_t bytes = (count * sizeof(TraceRecord) + kHuge - 1) / kHuge * kHuge;
      void* p = ::mmap(nullptr, size_t(bytes), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
      if (p == MAP_FAILED) throw std::bad_alloc();
      ::madvise(p, size_t(bytes), MADV_HUGEPAGE);  // advice only: 4 KiB pages where refused
      data_ = static_cast<TraceRecord*>(p);
      bytes_ = bytes;
      capacity_ = bytes / sizeof(TraceRecord);
    }
    return data_;
  }

 private:
  void release() {
    if (data_) ::munmap(data_, size_t(bytes_));
    data_ = nullptr;
    bytes_ = capacity_ = 0;
  }
  TraceRecord* data_ = nullptr;
  uint64_t bytes_ = 0, capacity_ = 0;
};

}  // namespace

uint64_t TraceReader::read_slices(uint32_t pass, const SliceFn& consume) const {
  return read_slices_indexed(pass, [&](std::span<const TraceRecord> records, uint64_t first, uint64_t end,
                                       const uint32_t*) { consume(records, first, end); });
}

uint64_t TraceReader::read_slices_indexed(uint32_t pass, const IndexedSliceFn& consume) const {
  return read_slices_impl(pass, false,
                          [&](std::span<const TraceRecord> records, const CodedSlice*, uint64_t first, uint64_t end,
                              const uint32_t* group_begin) { consume(records, first, end, group_begin); });
}

uint64_t TraceReader::read_slices_coded(uint32_t pass, const CodedSliceFn& consume) const {
  return read_slices_impl(pass, true, consume);
}

uint64_t TraceReader::read_slices_impl(uint32_t pass, bool coded, const CodedSliceFn& consume) const {
  if (pass >= passes_.size()) fail("no pass " + std::to_string(pass));
  std::vector<const Chunk*> order;
  for (const Chunk& c : chunks_)
    if (c.pass == pass) order.push_back(&c);
  // Chunks never overlap (checked at open); a writer may still have appended them out of order.
  std::stable_sort(order.begin(), order.end(),
                   [](const Chunk* a, const Chunk* b) { return a->first_workgroup < b->first_workgroup; });
  const auto comes_coded = [&](const Chunk& c) { return coded && c.coding == kCodingSizedGroups; };
  uint64_t largest = 0, largest_decoded = 0, largest_coded = 0;
  for (const Chunk* c : order) {
    largest = std::max<uint64_t>(largest, c->count);
    if (comes_coded(*c))
      largest_coded = std::max<uint64_t>(largest_coded, c->coded_bytes);
    else
      largest_decoded = std::max<uint64_t>(largest_decoded, c->count);
  }
  // Two buffers, reused for every slice: a thread reads and validates the next slice while `consume`
  // works on the current one. (Mapping the slice from the page cache instead of reading it was measured
  // 2-5x slower on the VM, whose page-table updates are expensive: reading 512 KiB blocks is the
  // cheapest way in.)
  RecordBuffer buffers[2];
  std::vector<uint32_t> group_begin[2];  // per buffer, for a 'RECV' slice: where each workgroup's records start
  // Per buffer, for a slice that comes coded: its bytes (and kRecordReadBytes more) and its workgroups' bodies.
  std::vector<uint8_t> coded_bytes[2];
  std::vector<std::pair<uint64_t, uint64_t>> bodies[2];
  bool is_coded[2] = {false, false};
  // Sized once for the largest slice: growing with the slices (which get larger past a frame's sky rows)
  // mapped fresh memory at each step, and the kernel's zeroing of it cost about 8% of a replay.
  if (largest_decoded > 0) {
    buffers[0].reserve(largest_decoded);
    if (order.size() > 1) buffers[1].reserve(largest_decoded);
  }
  if (largest_coded > 0) {
    coded_bytes[0].resize(largest_coded + kRecordReadBytes);
    if (order.size() > 1) coded_bytes[1].resize(largest_coded + kRecordReadBytes);
  }
  std::exception_ptr read_error;
  auto read_into = [&](size_t k, size_t slot) {
    try {
      const Chunk& c = *order[k];
      is_coded[slot] = false;
      if (comes_coded(c)) {
        std::vector<uint8_t>& bytes = coded_bytes[slot];
        std::fseek(file_, long(c.file_offset), SEEK_SET);
        if (std::fread(bytes.data(), 1, c.coded_bytes, file_) != c.coded_bytes)
          fail("truncated records of pass " + std::to_string(c.pass));
        std::memset(bytes.data() + c.coded_bytes, 0, kRecordReadBytes);
        // Headers that do not index the bytes: the careful decode below names the defect.
        is_coded[slot] = index_workgroups(std::span<const uint8_t>(bytes.data(), c.coded_bytes), c.first_workgroup,
                                          c.end_workgroup, bodies[slot]);
        if (is_coded[slot]) return;
      }
      std::vector<uint32_t>& index = group_begin[slot];
      index.resize(c.coded_bytes > 0 ? c.end_workgroup - c.first_workgroup + 1 : 0);
      read_chunk(c, buffers[slot].reserve(c.count), index.empty() ? nullptr : index.data());
    } catch (...) {
      read_error = std::current_exception();
    }
  };
  if (!order.empty()) read_into(0, 0);
  for (size_t k = 0; k < order.size(); ++k) {
    if (read_error) std::rethrow_exception(read_error);
    std::thread next;
    if (k + 1 < order.size()) next = std::thread(read_into, k + 1, (k + 1) % 2);
    try {
      const size_t slot = k % 2;
      const Chunk& c = *order[k];
      if (is_coded[slot]) {
        const CodedSlice slice{std::span<const uint8_t>(coded_bytes[slot].data(), c.coded_bytes), bodies[slot],
                               c.count};
        consume({}, &slice, c.first_workgroup, c.end_workgroup, nullptr);
      } else {
        const std::vector<uint32_t>& index = group_begin[slot];
        consume(std::span<const TraceRecord>(buffers[slot].reserve(0), c.count), nullptr, c.first_workgroup,
                c.end_workgroup, index.empty() ? nullptr : index.data());
      }
    } catch (...) {
      if (next.joinable()) next.join();
      throw;
    }
    if (next.joinable()) next.join();
  }
  return largest;
}

void validate_records(const std::string& where, const TraceHeader& header, const PassInfo& pass,
                      std::span<const TraceRecord> records, uint64_t first_workgroup, uint64_t end_workgroup,
                      uint64_t first_index) {
  const BufferInfo* by_id[256] = {};
  for (const BufferInfo& b : header.buffers)
    if (b.id < 256) by_id[b.id] = &b;
  const uint64_t invocations = pass.dispatch.invocations();
  const uint64_t per_group = pass.dispatch.invocations_per_workgroup();
  const uint64_t slice_first = std::min(first_workgroup, pass.dispatch.workgroups()) * per_group;
  const uint64_t slice_end = std::min(end_workgroup, pass.dispatch.workgroups()) * per_group;
  const bool sliced = first_workgroup != 0 || end_workgroup < pass.dispatch.workgroups();
  for (size_t i = 0; i < records.size(); ++i) {
    const TraceRecord& r = records[i];
    auto bad = [&](const std::string& why) {
      throw InputError(one_line(where + ": record " + std::to_string(first_index + i) + ": " + why));
    };
    if (r.info & HP_TRACE_RESERVED_MASK) bad("reserved info bits set");
    if (gpu::trace_kind(r.info) > HP_TRACE_ATOMIC) bad("unknown access kind");
    const BufferInfo* b = by_id[gpu::trace_buffer(r.info)];
    if (!b) bad("unknown buffer id " + std::to_string(gpu::trace_buffer(r.info)));
    if (r.invocation >= invocations)
      bad("invocation " + std::to_string(r.invocation) + " outside the dispatch of " + std::to_string(invocations));
    if (sliced && (r.invocation < slice_first || r.invocation >= slice_end))
      bad("invocation " + std::to_string(r.invocation) + " outside its slice's workgroups [" +
          std::to_string(first_workgroup) + ", " + std::to_string(end_workgroup) + ")");
    if (uint64_t(r.offset) + gpu::trace_size(r.info) > b->size_bytes)
      bad("offset " + std::to_string(r.offset) + " past the end of buffer '" + b->name + "'");
  }
}

void write_trace(const std::filesystem::path& path, const Trace& trace, uint32_t version, uint32_t coding) {
  TraceWriter w(path, trace.header, version, coding);
  for (size_t p = 0; p < trace.passes.size(); ++p) {
    uint32_t index = w.begin_pass(trace.passes[p]);
    if (p < trace.records.size()) w.write_records(index, trace.records[p], 0, trace.passes[p].dispatch.workgroups());
  }
  w.finish();
}

Trace read_trace(const std::filesystem::path& path) {
  TraceReader r(path);
  Trace t;
  t.header = r.header();
  t.passes = r.passes();
  for (uint32_t p = 0; p < t.passes.size(); ++p) t.records.push_back(r.read_pass(p));
  return t;
}

}  // namespace hp::trace
