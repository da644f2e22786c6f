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
//   workgroup  := varint(g - next_g) varint(steps)     g relative to the slice's first workgroup;
//                                                      next_g: the previous g + 1 (0 at first)
//                 { step }
//   step       := varint(seq delta) varint(n - 1) n * record
//                                                      seq delta: the first step's seq, then
//                                                      seq - previous seq - 1 (seqs strictly increase)
//   record     := control [varint(lane delta - 7)] [u16 info] [offset bytes]
//   control    bits 0-2  lane delta d: lane = previous lane of the step + d (previous lane: -1 at the
//                        step's start; d = 0 repeats a lane); 7: the delta is 7 + a varint that follows
//              bit 3     the info word follows (u16; else it is the previous record's, 0 at first)
//              bits 4-6  offset: 0 the previous record's (0 at first), 1/2/3 a zigzag difference from
//                        it in 1/2/3 bytes, 4 the offset itself in 4 bytes
//              bit 7     0
//   varint: LEB128 (7 bits a byte, low first), at most 5 bytes; multi-byte fields little-endian.
//
// Decoding gives the records in that canonical order: the same multiset of records, each invocation's
// records in the same order, which is all that a replay's results depend on.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "trace_format.hpp"

namespace hp::trace {

// Scratch kept between slices by an encoder (no allocation per slice once warm).
struct SliceEncoder {
  std::vector<uint32_t> group_begin, max_seq, sorted_begin, slot, row_count;
  std::vector<uint64_t> table_begin, row_begin;
  std::vector<uint8_t> placed;
  static constexpr uint32_t kEmpty = 0xFFFFFFFFu;
  std::unique_ptr<uint8_t[]> room;  // the coding's room, of room_size bytes
  size_t room_size = 0;
  std::vector<std::pair<uint64_t, uint32_t>> keys;
  // Appends the coding of `records` (of workgroups [first_workgroup, end_workgroup) of a dispatch of
  // `per_group` invocations per workgroup) to `out`. Throws InputError on a record the coding cannot
  // hold: an invocation outside those workgroups, or info bits 16-31 set.
  void encode(std::span<const TraceRecord> records, uint64_t first_workgroup, uint64_t end_workgroup,
              uint64_t per_group, std::vector<uint8_t>& out);
};

// Decodes a slice of `count` records into `out` (room for count) in canonical order. `check` is called
// on each run of about 16 K decoded records while they are still in the host's caches (records
// out[first, first + n)), so the caller validates them there. Throws InputError "`where`: ..." on any
// inconsistency: a truncated or overlong stream, a workgroup outside [first_workgroup, end_workgroup), a
// lane outside its workgroup, seqs that do not increase, a record count other than `count`, a reserved
// control bit. `group_begin`, if set (room for end_workgroup - first_workgroup + 1), gets where each
// workgroup's records start in `out` (the last entry: count), so that a consumer need not scan them.
using DecodeCheck = std::function<void(const TraceRecord* records, uint64_t first, uint64_t n)>;
void decode_slice(std::span<const uint8_t> in, uint64_t count, uint64_t first_workgroup, uint64_t end_workgroup,
                  uint64_t per_group, TraceRecord* out, const std::string& where, const DecodeCheck& check,
                  uint32_t* group_begin = nullptr);

}  // namespace hp::trace
