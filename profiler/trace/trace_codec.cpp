#include "trace/trace_codec.hpp"

#include <algorithm>
#include <bit>
#include <cstring>

#include "error.hpp"

namespace hp::trace {

static_assert(std::endian::native == std::endian::little, "the trace format is little-endian");

namespace {

// Writes through a pointer into room reserved beforehand (the coding's bound per record is known).
void put_varint(uint8_t*& p, uint64_t v) {
  while (v >= 0x80) {
    *p++ = uint8_t(v | 0x80);
    v >>= 7;
  }
  *p++ = uint8_t(v);
}

uint32_t zigzag(int64_t d) { return uint32_t((uint64_t(d) << 1) ^ uint64_t(d >> 63)); }

}  // namespace

void SliceEncoder::encode(std::span<const TraceRecord> records, uint64_t first_workgroup, uint64_t end_workgroup,
                          uint64_t per_group, std::vector<uint8_t>& out) {
  const uint64_t groups = end_workgroup - first_workgroup;
  const uint64_t first_invocation = first_workgroup * per_group;
  // Records by workgroup (counting sort, stable; copied, so that each workgroup's records lie together in
  // the host's caches while they are coded), then each workgroup's by (seq, lane, position).
  const int shift = std::has_single_bit(per_group) ? std::countr_zero(per_group) : -1;
  const auto group_of = [&](uint32_t invocation) {
    const uint64_t i = invocation - first_invocation;
    return uint32_t(shift >= 0 ? i >> shift : i / per_group);
  };
  group_begin.assign(groups + 1, 0);
  gid.resize(records.size());
  for (size_t i = 0; i < records.size(); ++i) {
    const TraceRecord& r = records[i];
    // What the coding cannot hold is refused here rather than written as something else (a version-1
    // file stores such records as given, and its reader rejects them).
    if (r.invocation < first_invocation || r.invocation - first_invocation >= groups * per_group)
      throw InputError("trace writer: record " + std::to_string(i) + ": invocation " + std::to_string(r.invocation) +
                       " outside its slice's workgroups [" + std::to_string(first_workgroup) + ", " +
                       std::to_string(end_workgroup) + ")");
    if (r.info > 0xFFFF) throw InputError("trace writer: record " + std::to_string(i) + ": reserved info bits set");
    gid[i] = group_of(r.invocation);
    ++group_begin[gid[i] + 1];
  }
  for (uint64_t g = 0; g < groups; ++g) group_begin[g + 1] += group_begin[g];
  grouped.resize(records.size());
  {
    std::vector<uint32_t> at(group_begin.begin(), group_begin.end() - 1);
    for (size_t i = 0; i < records.size(); ++i) grouped[at[gid[i]]++] = records[i];
  }
  // Coded into scratch room, then appended. Its bound: at most 5 + 5 bytes a workgroup and a step,
  // 1 + 5 + 2 + 4 a record, and a slice has no more steps than records. Left uninitialised: zeroing the
  // bound would cost more than the coding.
  const size_t bound = 22 * records.size() + 10 * groups + 16;
  if (room_size < bound) {
    room = std::make_unique_for_overwrite<uint8_t[]>(bound);
    room_size = bound;
  }
  uint8_t* p = room.get();
  uint64_t next_g = 0;
  uint32_t prev_info = 0, prev_offset = 0;
  for (uint64_t g = 0; g < groups; ++g) {
    const uint32_t b = group_begin[g], e = group_begin[g + 1];
    if (b == e) continue;
    const uint64_t base = first_invocation + g * per_group;
    // Order by (seq, lane). A GPU capture numbers each invocation's records 0, 1, 2, ... so the keys are
    // distinct and dense: placed straight into a table of (largest seq + 1) x per_group slots and read back
    // in order (linear time). A key that repeats (the format allows it), or a table much larger than the
    // workgroup's records, takes a comparison sort instead; both give the same order.
    keys.clear();
    uint32_t max_seq = 0;
    for (uint32_t k = b; k < e; ++k) max_seq = std::max(max_seq, grouped[k].seq);
    const uint64_t range = (uint64_t(max_seq) + 1) * per_group;
    bool placed = range <= 8 * uint64_t(e - b) + 4096;
    if (placed) {
      slot.assign(range, kEmpty);
      for (uint32_t k = b; k < e && placed; ++k) {
        const TraceRecord& r = grouped[k];
        uint32_t& at = slot[uint64_t(r.seq) * per_group + (r.invocation - base)];
        placed = at == kEmpty;
        at = k;
      }
    }
    if (placed) {
      const uint32_t* at = slot.data();
      for (uint64_t seq = 0; seq <= max_seq; ++seq) {
        for (uint64_t lane = 0; lane < per_group; ++lane, ++at) {
          if (*at != kEmpty) keys.emplace_back(seq << 32 | lane, *at);
        }
      }
    } else {
      for (uint32_t k = b; k < e; ++k) {
        const TraceRecord& r = grouped[k];
        keys.emplace_back(uint64_t(r.seq) << 32 | (r.invocation - base), k);
      }
      std::sort(keys.begin(), keys.end());  // positions break ties: stable
    }
    put_varint(p, g - next_g);
    next_g = g + 1;
    uint64_t steps = 1;
    for (size_t k = 1; k < keys.size(); ++k) steps += (keys[k].first >> 32) != (keys[k - 1].first >> 32);
    put_varint(p, steps);
    uint64_t prev_seq = 0;
    bool first_step = true;
    for (size_t k = 0; k < keys.size();) {
      const uint64_t seq = keys[k].first >> 32;
      size_t j = k;
      while (j < keys.size() && (keys[j].first >> 32) == seq) ++j;
      put_varint(p, first_step ? seq : seq - prev_seq - 1);
      put_varint(p, j - k - 1);
      first_step = false;
      prev_seq = seq;
      int64_t prev_lane = -1;
      for (; k < j; ++k) {
        const TraceRecord& r = grouped[keys[k].second];
        const int64_t lane = int64_t(r.invocation - base);
        const uint64_t d = uint64_t(lane - prev_lane);
        prev_lane = lane;
        uint8_t control = uint8_t(std::min<uint64_t>(d, 7));
        const uint32_t info = r.info;
        if (info != prev_info) control |= 8;
        const uint32_t zz = zigzag(int64_t(r.offset) - int64_t(prev_offset));
        const uint32_t mode = zz == 0 ? 0 : zz < (1u << 8) ? 1 : zz < (1u << 16) ? 2 : zz < (1u << 24) ? 3 : 4;
        control |= uint8_t(mode << 4);
        *p++ = control;
        if (d >= 7) put_varint(p, d - 7);
        if (info != prev_info) {
          *p++ = uint8_t(info);
          *p++ = uint8_t(info >> 8);
          prev_info = info;
        }
        const uint32_t v = mode == 4 ? r.offset : zz;
        std::memcpy(p, &v, 4);  // little-endian; only the first `bytes` count
        p += mode == 4 ? 4u : mode;
        prev_offset = r.offset;
      }
    }
  }
  out.insert(out.end(), room.get(), p);
}

namespace {

// Bounds-checked reading of the stream; every failure names `where` and the byte.
struct Stream {
  const uint8_t* p;
  const uint8_t* begin;
  const uint8_t* end;
  const std::string& where;
  [[noreturn]] void fail(const std::string& why) const {
    throw InputError(where + ": compact records, byte " + std::to_string(p - begin) + ": " + why);
  }
  uint64_t varint() {
    uint64_t v = 0;
    for (int shift = 0; shift < 35; shift += 7) {
      if (p == end) fail("truncated");
      const uint8_t b = *p++;
      v |= uint64_t(b & 0x7F) << shift;
      if (!(b & 0x80)) return v;
    }
    fail("varint longer than 5 bytes");
  }
};

}  // namespace

void decode_slice(std::span<const uint8_t> in, uint64_t count, uint64_t first_workgroup, uint64_t end_workgroup,
                  uint64_t per_group, TraceRecord* out, const std::string& where, const DecodeCheck& check,
                  uint32_t* group_begin) {
  Stream s{in.data(), in.data(), in.data() + in.size(), where};
  const uint64_t groups = end_workgroup - first_workgroup;
  if (group_begin && count > 0xFFFFFFFFu) s.fail("more than 2^32 - 1 records in one slice");
  uint64_t next_g = 0, n_out = 0, checked = 0;
  uint32_t prev_info = 0, prev_offset = 0;
  constexpr uint64_t kCheckRun = 1 << 14;
  while (s.p != s.end) {
    const uint64_t g = next_g + s.varint();
    if (g >= groups) s.fail("workgroup " + std::to_string(first_workgroup + g) + " outside the slice");
    if (group_begin) {
      for (uint64_t e = next_g; e <= g; ++e) group_begin[e] = uint32_t(n_out);  // g and the empty ones before it
    }
    next_g = g + 1;
    const uint64_t base = (first_workgroup + g) * per_group;
    const uint64_t steps = s.varint();
    if (steps == 0) s.fail("a workgroup without steps");
    uint64_t seq = 0;
    for (uint64_t st = 0; st < steps; ++st) {
      const uint64_t delta = s.varint();
      seq = st == 0 ? delta : seq + delta + 1;
      if (seq > 0xFFFFFFFFu) s.fail("seq past 2^32 - 1");
      const uint64_t n = s.varint() + 1;
      if (n > count - n_out) s.fail("more records than the chunk's count of " + std::to_string(count));
      int64_t lane = -1;
      for (uint64_t k = 0; k < n; ++k) {
        // Fast path, 16 bytes or more left (every record but the last few of a slice): one unaligned
        // load for the offset and table lookups instead of a branch per field; the same checks.
        // A bad control byte takes the careful path, which names the error.
        if (s.end - s.p >= 16 && (s.p[0] >> 4) <= 4) {
          const uint8_t c = s.p[0];
          const uint32_t mode = c >> 4;
          const uint8_t* q = s.p + 1;
          uint64_t d = c & 7;
          if (d == 7) {
            s.p = q;
            d += s.varint();
            q = s.p;
          }
          lane += int64_t(d);
          if (uint64_t(lane) >= per_group) s.fail("lane " + std::to_string(lane) + " outside the workgroup");
          if (c & 8) {
            prev_info = uint32_t(q[0]) | uint32_t(q[1]) << 8;
            q += 2;
          }
          static constexpr uint32_t kMask[5] = {0, 0xFF, 0xFFFF, 0xFFFFFF, 0xFFFFFFFF};
          static constexpr uint8_t kBytes[5] = {0, 1, 2, 3, 4};
          uint32_t v;
          std::memcpy(&v, q, 4);
          v &= kMask[mode];
          q += kBytes[mode];
          const int64_t off = mode == 4 ? int64_t(v) : int64_t(prev_offset) + (int64_t(v >> 1) ^ -int64_t(v & 1));
          if (off < 0 || off > 0xFFFFFFFFll) {
            s.p = q;
            s.fail("offset outside 32 bits");
          }
          prev_offset = uint32_t(off);
          s.p = q;
          out[n_out++] = TraceRecord{uint32_t(base + uint64_t(lane)), uint32_t(seq), prev_info, prev_offset};
          continue;
        }
        if (s.p == s.end) s.fail("truncated");
        const uint8_t c = *s.p++;
        if (c & 0x80) s.fail("reserved control bit set");
        uint64_t d = c & 7;
        if (d == 7) d += s.varint();
        lane += int64_t(d);
        if (uint64_t(lane) >= per_group) s.fail("lane " + std::to_string(lane) + " outside the workgroup");
        if (c & 8) {
          if (s.end - s.p < 2) s.fail("truncated");
          prev_info = uint32_t(s.p[0]) | uint32_t(s.p[1]) << 8;
          s.p += 2;
        }
        const uint32_t mode = c >> 4;
        if (mode > 4) s.fail("unknown offset coding");
        const uint32_t bytes = mode == 4 ? 4 : mode;
        if (uint64_t(s.end - s.p) < bytes) s.fail("truncated");
        uint32_t v = 0;
        for (uint32_t b = 0; b < bytes; ++b) v |= uint32_t(s.p[b]) << (8 * b);
        s.p += bytes;
        if (mode == 4) {
          prev_offset = v;
        } else {
          const int64_t diff = int64_t(v >> 1) ^ -int64_t(v & 1);
          const int64_t off = int64_t(prev_offset) + diff;
          if (off < 0 || off > 0xFFFFFFFFll) s.fail("offset outside 32 bits");
          prev_offset = uint32_t(off);
        }
        out[n_out++] = TraceRecord{uint32_t(base + uint64_t(lane)), uint32_t(seq), prev_info, prev_offset};
      }
    }
    if (n_out - checked >= kCheckRun) {
      check(out + checked, checked, n_out - checked);
      checked = n_out;
    }
  }
  if (n_out != count)
    s.fail("holds " + std::to_string(n_out) + " records, the chunk declares " + std::to_string(count));
  if (group_begin) {
    for (uint64_t e = next_g; e <= groups; ++e) group_begin[e] = uint32_t(n_out);
  }
  if (n_out > checked) check(out + checked, checked, n_out - checked);
}

}  // namespace hp::trace
