// The compact coding of a slice's records (trace file format version 2, chunk 'RECV'; the layout is in
// trace_file.hpp and docs/formats.md).
//
// A slice's records are coded in the order the replay issues them: by workgroup, then by seq, then by
// invocation (stably: records of one invocation with the same seq keep their order). In that order the
// records of one wave step follow each other, so most fields are small differences from the record
// before: the lane is usually the next one, the info word usually the previous record's, and the
// offset usually the one a neighbouring lane read (a coherent step reads the same BVH node) or one
// close to it. Per record: one control byte, then only what differs.
//
//   stream     := { workgroup }                        workgroups with records, ascending
//   workgroup  := varint(g - next_g) [u32 body bytes] body
//                                                      g relative to the slice's first workgroup;
//                                                      next_g: the previous g + 1 (0 at first);
//                                                      body bytes: coding 2 only, the size of `body`
//   body       := varint(steps) { step }
//   step       := varint(seq delta) varint(n - 1) n * record
//                                                      seq delta: the first step's seq, then
//                                                      seq - previous seq - 1 (seqs strictly increase)
//   record     := control [varint(lane delta - 7)] [u16 info] [offset bytes]
//   control    bits 0-2  lane delta d: lane = previous lane of the step + d (previous lane: -1 at the
//                        step's start; d = 0 repeats a lane); 7: the delta is 7 + a varint that follows
//              bit 3     the info word follows (u16; else it is the previous record's, 0 at first)
//              bits 4-6  offset: 0 the previous record's (0 at first), 1/2/3 a zigzag difference from
//                        it in 1/2/3 bytes, 4 the offset itself in 4 bytes (always where the difference
//                        is 2^31 or more either way)
//              bit 7     0
//   varint: LEB128 (7 bits a byte, low first), at most 5 bytes; multi-byte fields little-endian.
//
// Codings: 1 carries "the previous record" across workgroups; 2 (written by default) starts each
// workgroup afresh (previous info and offset 0) and states its body's size, so that a reader can find
// every workgroup without decoding the ones before it and decode workgroups on several threads, or
// straight into the replay's wave steps (cachesim's coded feed). It costs about 7 bytes a workgroup.
//
// Decoding gives the records in that canonical order: the same multiset of records, each invocation's
// records in the same order, which is all that a replay's results depend on.
#pragma once

#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "trace_format.hpp"

namespace hp::trace {

inline constexpr uint32_t kCodingDeltaVarint = 1;  // the state runs on across workgroups
inline constexpr uint32_t kCodingSizedGroups = 2;  // each workgroup stands alone, its size up front

// Scratch kept between slices by an encoder (no allocation per slice once warm).
struct SliceEncoder {
  struct Run {
    uint32_t first, count, group;  // records [first, first + count) of workgroup `group`
  };
  struct Segment {
    const TraceRecord* first;
    uint32_t count;
  };
  static constexpr size_t kMaxParts = HP_TRACE_MAX_REGIONS;  // a capture's regions
  std::vector<Run> runs;
  std::vector<Segment> segments;
  std::vector<TraceRecord> gathered;
  std::vector<uint32_t> group_begin, max_seq, run_begin, run_order, cursor;
  // A workgroup's records by (seq, lane), slot seq * per_group + lane: occupied (0 between workgroups),
  // the record's info word and offset; and each seq's occupied lanes as bits.
  std::vector<uint8_t> occupied;
  std::vector<uint32_t> info_table, offset_table;
  std::vector<uint64_t> row_lanes;
  static constexpr uint32_t kEmpty = 0xFFFFFFFFu;
  // Whether a step of at most 64 lanes is coded with AVX-512 where the host has it (on by default; the
  // same bytes either way, which the tests check by turning it off).
  void use_simd(bool on) { simd_ = on; }
  static bool simd_available();
  std::unique_ptr<uint8_t[]> room;  // the coding's room, of room_size bytes
  size_t room_size = 0;
  std::vector<std::pair<uint64_t, uint32_t>> keys;
  // Appends the coding of `records` (of workgroups [first_workgroup, end_workgroup) of a dispatch of
  // `per_group` invocations per workgroup) to `out`. Throws InputError on a record the coding cannot
  // hold: an invocation outside those workgroups, or info bits 16-31 set.
  void encode(std::span<const TraceRecord> records, uint64_t first_workgroup, uint64_t end_workgroup,
              uint64_t per_group, std::vector<uint8_t>& out, uint32_t coding = kCodingSizedGroups);
  // The same coding of the records of `parts` put together in order (the bytes encode() gives for them),
  // read once, straight from the parts, where they are in run order: in each part, every workgroup's
  // records are one run, and the runs are in increasing workgroup order (a capture's trace buffer regions,
  // each filled by one lavapipe thread running whole workgroups in turn). Returns false, leaving `out` as
  // it was, where they are not (or there are more than kMaxParts parts): encode() on the records put
  // together then codes them. Throws as encode() does.
  bool encode_parts(std::span<const std::span<const TraceRecord>> parts, uint64_t first_workgroup,
                    uint64_t end_workgroup, uint64_t per_group, std::vector<uint8_t>& out,
                    uint32_t coding = kCodingSizedGroups);

 private:
  void reserve_room(uint64_t records, uint64_t groups);
  size_t code_group(size_t at, uint64_t g, std::span<const Segment> segs, uint64_t n, uint32_t max_seq,
                    uint64_t lane_base, uint64_t per_group, uint32_t coding);
  bool simd_ = true;
  uint64_t next_g_ = 0;  // the workgroup after the last one coded (relative to the slice)
  uint32_t state_prev_info_ = 0, state_prev_offset_ = 0;  // the coding's previous record (coding 1: across workgroups)
};

// Decodes a slice of `count` records into `out` (room for count) in canonical order. `check` is called
// on each run of about 16 K decoded records while they are still in the host's caches (records
// out[first, first + n)), so the caller validates them there. Throws InputError "`where`: ..." on any
// inconsistency: a truncated or overlong stream, a workgroup outside [first_workgroup, end_workgroup), a
// lane outside its workgroup, seqs that do not increase, a record count other than `count`, a reserved
// control bit, a workgroup's body of another size than coding 2 states. `group_begin`, if set (room for
// end_workgroup - first_workgroup + 1), gets where each workgroup's records start in `out` (the last entry:
// count), so that a consumer need not scan them.
using DecodeCheck = std::function<void(const TraceRecord* records, uint64_t first, uint64_t n)>;
void decode_slice(std::span<const uint8_t> in, uint64_t count, uint64_t first_workgroup, uint64_t end_workgroup,
                  uint64_t per_group, TraceRecord* out, const std::string& where, const DecodeCheck& check,
                  uint32_t* group_begin = nullptr, uint32_t coding = kCodingSizedGroups);

// Where each workgroup's body lies in a coding-2 slice: bodies[g] = [begin, end) byte offsets in `in` of
// workgroup first_workgroup + g's body (begin == end: the workgroup has no records). Reads the headers
// only (a hop per workgroup). False where they do not describe the bytes (a workgroup out of order or
// outside the slice, a body past the end): decode_slice then names the defect.
bool index_workgroups(std::span<const uint8_t> in, uint64_t first_workgroup, uint64_t end_workgroup,
                      std::vector<std::pair<uint64_t, uint64_t>>& bodies);

// Decoding one record where at least kRecordReadBytes bytes can be read from its first byte on (the
// longest record is 12 bytes; the rest is what a 4-byte load of its offset may read past it): the shared
// inner step of decode_slice and of the replay's coded feed.
inline constexpr size_t kRecordReadBytes = 16;
struct CodedState {
  uint32_t info = 0, offset = 0;  // the previous record's
};
// Reads a varint of at most 5 bytes at p into v; returns the byte after it (null: longer than 5 bytes).
inline const uint8_t* read_varint(const uint8_t* p, uint64_t& v) {
  v = 0;
  for (int shift = 0; shift < 35; shift += 7) {
    const uint8_t b = *p++;
    v |= uint64_t(b & 0x7F) << shift;
    if (!(b & 0x80)) return p;
  }
  return nullptr;
}
// Decodes the record at p: its lane delta to `delta`, its info word and offset into `s`. Returns the byte
// after it, or null for a reserved control bit, an unknown offset coding, a varint longer than 5 bytes or an
// offset outside 32 bits (the careful path of decode_slice names which).
[[gnu::always_inline]] inline const uint8_t* decode_record(const uint8_t* p, CodedState& s, uint64_t& delta) {
  const uint8_t c = p[0];
  const uint32_t mode = c >> 4;
  if (mode > 4) return nullptr;  // bit 7 set, or an unknown offset coding
  const uint8_t* q = p + 1;
  delta = c & 7;
  if (delta == 7) {
    uint64_t more;
    q = read_varint(q, more);
    if (!q) return nullptr;
    delta += more;
  }
  if (c & 8) {
    s.info = uint32_t(q[0]) | uint32_t(q[1]) << 8;
    q += 2;
  }
  static constexpr uint32_t kMask[5] = {0, 0xFF, 0xFFFF, 0xFFFFFF, 0xFFFFFFFF};
  uint32_t v;
  std::memcpy(&v, q, 4);
  v &= kMask[mode];
  q += mode;
  const int64_t off = mode == 4 ? int64_t(v) : int64_t(s.offset) + (int64_t(v >> 1) ^ -int64_t(v & 1));
  if (off < 0 || off > 0xFFFFFFFFll) return nullptr;
  s.offset = uint32_t(off);
  return q;
}

}  // namespace hp::trace
