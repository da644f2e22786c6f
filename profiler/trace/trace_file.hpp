// Memory-trace files: what an instrumented frame wrote, for the cache simulator to replay.
//
// Binary format, little-endian, every field naturally aligned. Version 2 (written by default) differs
// from version 1 only in how a slice's records are stored ('RECV' instead of 'RECS'); readers take both.
//
//   FileHeader   32 bytes: magic "HPTRACE\0", u32 version (1 or 2), u32 flags (0), u32 image_width,
//                u32 image_height, u64 reserved (0)
//   then chunks, each a 16-byte ChunkHeader {u32 tag, u32 reserved, u64 payload_bytes} and its payload:
//   'BUFS'  exactly once, before any pass: u32 count, then per buffer
//           u32 id, u32 kind, u64 base_address, u64 size_bytes, u32 texel_bytes, u32 width, u32 height,
//           u32 row_pitch_bytes, u32 tile_width, u32 tile_height, u32 name_bytes, u32 reserved (0), name (no NUL),
//           padded with zeros to 8 bytes
//   'PASS'  u32 pass index (0, 1, ... in order), u32 workgroup_size[3], u32 workgroup_count[3],
//           u32 name_bytes, name, padded to 8 bytes
//   'RECS'  u32 pass index, u32 reserved, u64 first_workgroup, u64 end_workgroup, u64 count,
//           count * 16-byte hp::gpu::TraceRecord (any order). One chunk per streamed slice: the
//           workgroup range says which workgroups the slice dispatched, records need not be sorted.
//   'RECV'  (version 2 only) the same slice coded compactly: u32 pass index, u32 coding (1 or 2), u64
//           first_workgroup, u64 end_workgroup, u64 count, u64 coded_bytes, then coded_bytes bytes of
//           the coding in trace_codec.hpp (about 3 bytes a record instead of 16), padded to 8 bytes.
//   'END '  u64 total records, u32 pass count, u32 reserved. A file without it is reported as
//           truncated: the writer writes it last and renames the file into place only then.
//
// Buffers of kind image_* are addressed in records by logical offset (see trace_record.h) and mapped
// to bytes by their declared layout: image_linear rows of row_pitch_bytes, or image_tiled blocks of
// tile_width x tile_height texels stored contiguously, blocks in row-major order.
#pragma once

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "atomic_file.hpp"
#include "trace/trace_codec.hpp"
#include "trace_format.hpp"

namespace hp::trace {

inline constexpr char kTraceMagic[8] = {'H', 'P', 'T', 'R', 'A', 'C', 'E', '\0'};
inline constexpr uint32_t kTraceVersion = 2;     // what TraceWriter writes by default (compact records)
inline constexpr uint32_t kTraceVersionRaw = 1;  // 16 bytes a record; still written on request

// A whole trace in memory: fine for tests, tools and moderate frames; streaming code uses the
// writer's per-slice chunks and the reader's per-pass reads.
struct Trace {
  TraceHeader header;
  std::vector<PassInfo> passes;
  std::vector<std::vector<TraceRecord>> records;  // records[pass]
};

// Streams a trace file: header and buffer table at construction, then passes and record slices.
// Writes through an AtomicFile, renamed to PATH in finish(), so a crashed capture never leaves a file that
// looks complete; destroying an unfinished writer removes the temporary file. `version` 2 codes each slice
// compactly (SliceEncoder: records reordered by workgroup, seq and invocation; `coding` 2, or the older 1),
// 1 stores them as given.
class TraceWriter final : public TraceSink {
 public:
  TraceWriter(std::filesystem::path path, const TraceHeader& header, uint32_t version = kTraceVersion,
              uint32_t coding = kCodingSizedGroups);
  ~TraceWriter() override;
  TraceWriter(const TraceWriter&) = delete;
  TraceWriter& operator=(const TraceWriter&) = delete;

  uint32_t begin_pass(const PassInfo& pass) override;
  void write_records(uint32_t pass, std::span<const TraceRecord> records, uint64_t first_workgroup,
                     uint64_t end_workgroup) override;
  /// Codes the parts where they lie when they are in run order (SliceEncoder::encode_parts), a single part
  /// in any order; a raw (version 1) file stores them one after the other. False for several parts not in
  /// run order.
  bool write_record_parts(uint32_t pass, std::span<const std::span<const TraceRecord>> parts, uint64_t first_workgroup,
                          uint64_t end_workgroup) override;
  /// Codes the slice on the calling thread (beside other slices being coded on other threads), leaving the
  /// file write to the returned step. Version 1 files are written in order only (null).
  Commit stage_record_parts(uint32_t pass, std::span<const std::span<const TraceRecord>> parts,
                            uint64_t first_workgroup, uint64_t end_workgroup) override;
  void finish();
  /// Bytes written to the file so far (headers and records): what the capture has cost on disk.
  uint64_t bytes_written() const { return bytes_written_; }

 private:
  void put(const void* data, size_t bytes);
  void put_chunk_header(uint32_t tag, uint64_t payload_bytes);
  void put_coded(uint32_t pass, uint64_t first_workgroup, uint64_t end_workgroup, uint64_t records,
                 std::span<const uint8_t> coded);
  // Codes the records of `parts` put together into `out` with `encoder`: where they lie if they are in run
  // order, else (several parts) gathered into `gathered` first; false, nothing coded, where that is needed
  // and `gathered` is null.
  bool code_parts(SliceEncoder& encoder, std::vector<TraceRecord>* gathered, uint32_t pass,
                  std::span<const std::span<const TraceRecord>> parts, uint64_t first_workgroup, uint64_t end_workgroup,
                  std::vector<uint8_t>& out) const;
  AtomicFile out_;
  std::FILE* file_ = nullptr;
  uint32_t passes_ = 0;
  uint64_t total_records_ = 0;
  uint64_t bytes_written_ = 0;
  uint32_t version_;
  uint32_t coding_;
  std::vector<uint64_t> per_group_;  // by pass: invocations per workgroup (the coding needs them)
  SliceEncoder encoder_;
  std::vector<uint8_t> coded_;
  // Encoders for stage_record_parts, one per thread coding at once, kept between slices.
  struct Staging {
    SliceEncoder encoder;
    std::vector<TraceRecord> gathered;
  };
  std::mutex staging_mutex_;
  std::vector<std::unique_ptr<Staging>> staging_;
};

// A coding-2 slice as stored (TraceReader::read_slices_coded): its bytes, with kRecordReadBytes more
// readable past their end, and where each workgroup's body lies in them (index_workgroups; begin == end:
// none). Its records are not checked yet: the consumer decodes and checks them.
struct CodedSlice {
  std::span<const uint8_t> bytes;
  std::span<const std::pair<uint64_t, uint64_t>> bodies;  // by workgroup - first_workgroup
  uint64_t count = 0;                                     // records the chunk declares
};

// Reads a trace file's directory (header, buffers, passes, where each pass's record chunks lie) at
// open, and a pass's records on demand. Every defect is an hp::InputError of one line naming the file.
class TraceReader {
 public:
  explicit TraceReader(std::filesystem::path path);
  ~TraceReader();
  TraceReader(const TraceReader&) = delete;
  TraceReader& operator=(const TraceReader&) = delete;

  const TraceHeader& header() const { return header_; }
  const std::vector<PassInfo>& passes() const { return passes_; }
  uint32_t version() const { return version_; }
  uint64_t record_count(uint32_t pass) const;
  // All records of a pass, validated: reserved bits zero, known buffer id, invocation inside its
  // slice's workgroups, offset + size inside the buffer.
  std::vector<TraceRecord> read_pass(uint32_t pass) const;
  // The same records one slice at a time, in workgroup order, each validated before `consume` sees it;
  // a second thread reads and validates the next slice while `consume` runs: memory bounded by two
  // of the largest slice. Returns the largest slice's record count.
  using SliceFn =
      std::function<void(std::span<const TraceRecord> records, uint64_t first_workgroup, uint64_t end_workgroup)>;
  uint64_t read_slices(uint32_t pass, const SliceFn& consume) const;
  // The same, also handing over where each workgroup's records start when the slice comes in workgroup
  // order, as a version-2 slice decodes: group_begin[g] .. group_begin[g + 1] are workgroup
  // first_workgroup + g's records (null for a version-1 slice, whose records come in the GPU's order).
  using IndexedSliceFn = std::function<void(std::span<const TraceRecord> records, uint64_t first_workgroup,
                                            uint64_t end_workgroup, const uint32_t* group_begin)>;
  uint64_t read_slices_indexed(uint32_t pass, const IndexedSliceFn& consume) const;
  // The same, but a slice of coding 2 comes as its coding (`coded` set, `records` empty, `group_begin`
  // null) for a consumer that decodes and checks it itself: cachesim's coded feed. Other slices come as
  // read_slices_indexed gives them (`coded` null). Memory: two of the largest coded slice's bytes (and
  // two of the largest other slice's records).
  using CodedSliceFn =
      std::function<void(std::span<const TraceRecord> records, const CodedSlice* coded, uint64_t first_workgroup,
                         uint64_t end_workgroup, const uint32_t* group_begin)>;
  uint64_t read_slices_coded(uint32_t pass, const CodedSliceFn& consume) const;

 private:
  struct Chunk {
    uint32_t pass;
    uint64_t file_offset;  // of the first record, or of the coded bytes
    uint64_t count;
    uint64_t first_workgroup, end_workgroup;
    uint64_t coded_bytes = 0;  // 'RECV' chunks: the coding's size (0: 16-byte records)
    uint32_t coding = 0;       // 'RECV' chunks: kCodingDeltaVarint or kCodingSizedGroups
  };
  // c.count records to `out`, validated; `group_begin` (room for the chunk's workgroups + 1), if set, gets
  // where each workgroup's records start, for a 'RECV' chunk.
  void read_chunk(const Chunk& c, TraceRecord* out, uint32_t* group_begin = nullptr) const;
  // read_slices_indexed and read_slices_coded: `coded` says whether coding-2 slices come coded.
  uint64_t read_slices_impl(uint32_t pass, bool coded, const CodedSliceFn& consume) const;
  [[noreturn]] void fail(const std::string& what) const;
  // Parts of the constructor's directory read; `at` names the chunk in errors.
  void read_buffer_table(const std::vector<char>& payload, const std::string& at);
  void read_pass(const std::vector<char>& payload, const std::string& at);
  void check_slices_disjoint() const;
  std::filesystem::path path_;
  std::FILE* file_ = nullptr;
  TraceHeader header_;
  std::vector<PassInfo> passes_;
  std::vector<Chunk> chunks_;
  uint32_t version_ = 0;
  mutable std::vector<uint8_t> coded_;  // read_chunk's scratch for a 'RECV' chunk's bytes
};

void write_trace(const std::filesystem::path& path, const Trace& trace, uint32_t version = kTraceVersion,
                 uint32_t coding = kCodingSizedGroups);
Trace read_trace(const std::filesystem::path& path);

// Checks one pass's records against the header and dispatch (and, when given, the slice of workgroups
// [first_workgroup, end_workgroup) they came from); throws InputError naming `where` and the record's
// index (records[i] is record first_index + i of its chunk).
void validate_records(const std::string& where, const TraceHeader& header, const PassInfo& pass,
                      std::span<const TraceRecord> records, uint64_t first_workgroup = 0,
                      uint64_t end_workgroup = UINT64_MAX, uint64_t first_index = 0);

}  // namespace hp::trace
