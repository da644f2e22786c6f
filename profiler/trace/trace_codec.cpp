#include "trace/trace_codec.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <stdexcept>

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

uint64_t zigzag(int64_t d) { return (uint64_t(d) << 1) ^ uint64_t(d >> 63); }

// What a workgroup's records are coded against (the coding's "previous record").
struct CodeState {
  uint32_t prev_info = 0, prev_offset = 0;
  int64_t prev_lane = -1;
};

// One record of the current step, at p.
[[gnu::always_inline]] inline void put_record(uint8_t*& p, CodeState& s, const TraceRecord& r, int64_t lane) {
  const uint64_t d = uint64_t(lane - s.prev_lane);
  s.prev_lane = lane;
  uint8_t control = uint8_t(std::min<uint64_t>(d, 7));
  const uint32_t info = r.info;
  if (info != s.prev_info) control |= 8;
  // A difference of 2^31 or more either way has a 33-bit zigzag: such an offset is stored as itself (mode 4).
  const uint64_t zz = zigzag(int64_t(r.offset) - int64_t(s.prev_offset));
  const uint32_t mode = std::min(uint32_t(std::bit_width(zz) + 7) >> 3, 4u);  // zz's bytes, 0..4 (4: the offset itself)
  control |= uint8_t(mode << 4);
  *p++ = control;
  if (d >= 7) put_varint(p, d - 7);
  if (info != s.prev_info) {
    *p++ = uint8_t(info);
    *p++ = uint8_t(info >> 8);
    s.prev_info = info;
  }
  const uint32_t v = mode == 4 ? r.offset : uint32_t(zz);
  std::memcpy(p, &v, 4);  // little-endian; only the first `mode` count
  p += mode == 4 ? 4u : mode;
  s.prev_offset = r.offset;
}

// The refusals of SliceEncoder::encode, for record `index` of the slice (in the order given).
[[noreturn]] void refuse_invocation(uint64_t index, uint32_t invocation, uint64_t first_workgroup,
                                    uint64_t end_workgroup) {
  throw InputError("trace writer: record " + std::to_string(index) + ": invocation " + std::to_string(invocation) +
                   " outside its slice's workgroups [" + std::to_string(first_workgroup) + ", " +
                   std::to_string(end_workgroup) + ")");
}
[[noreturn]] void refuse_info(uint64_t index) {
  throw InputError("trace writer: record " + std::to_string(index) + ": reserved info bits set");
}

// What both entry points of SliceEncoder refuse before coding a slice of `records` records.
void check_slice(const char* caller, uint32_t coding, uint64_t records) {
  if (coding != kCodingDeltaVarint && coding != kCodingSizedGroups)
    throw std::logic_error(std::string("SliceEncoder::") + caller + ": unknown coding " + std::to_string(coding));
  if (records > 0xFFFFFFFFu) throw InputError("trace writer: a slice of 2^32 records or more");
}

}  // namespace

// Codes workgroup g (relative to the slice), whose `n` records are the runs `segs` in record order (their
// seqs at most max_seq; the invocations of lanes lane_base ..), at room + at; returns where it ends.
size_t SliceEncoder::code_group(size_t at, uint64_t g, std::span<const Segment> segs, uint64_t n, uint32_t max_seq,
                                uint64_t lane_base, uint64_t per_group, uint32_t coding) {
  // A workgroup in several runs is gathered first, so that one index names each of its records.
  const TraceRecord* records = segs[0].first;
  if (segs.size() > 1) {
    gathered.clear();
    for (const Segment& s : segs) gathered.insert(gathered.end(), s.first, s.first + s.count);
    records = gathered.data();
  }
  uint8_t* p = room.get() + at;
  put_varint(p, g - next_g_);
  next_g_ = g + 1;
  uint8_t* body_bytes = nullptr;  // coding 2: where the body's size goes once it is known
  if (coding == kCodingSizedGroups) {
    body_bytes = p;
    p += 4;
    state_prev_info_ = state_prev_offset_ = 0;
  }
  CodeState s{state_prev_info_, state_prev_offset_, -1};
  uint64_t prev_seq = 0;
  bool first_step = true;
  const auto put_step_header = [&](uint64_t seq, uint64_t count) {
    put_varint(p, first_step ? seq : seq - prev_seq - 1);
    put_varint(p, count - 1);
    first_step = false;
    prev_seq = seq;
    s.prev_lane = -1;
  };
  // The workgroup's records in (seq, lane, position) order. A GPU capture numbers each invocation's records
  // 0, 1, 2, ... so the keys are distinct and dense: a table of (largest seq + 1) x per_group slots, each
  // record's index placed into its slot (in record order), read back in order (linear time, and the table
  // small enough to stay in the host's caches while the workgroup is coded). A key that repeats (the format
  // allows it), or a table much larger than the workgroup's records, takes a comparison sort of the
  // workgroup's keys instead; both give the same order.
  const uint64_t seqs = uint64_t(max_seq) + 1;
  bool placed = seqs * per_group <= 8 * n + 4096;
  if (placed) {
    slot.assign(seqs * per_group, kEmpty);
    row_count.assign(seqs, 0);  // records per seq: a step's size, without scanning its row
    uint32_t* const table = slot.data();
    uint32_t* const in_row = row_count.data();
    for (uint32_t i = 0; i < n; ++i) {
      const TraceRecord& r = records[i];
      uint32_t& where = table[uint64_t(r.seq) * per_group + (r.invocation - lane_base)];
      if (where != kEmpty) {
        placed = false;  // a repeated key: this workgroup is sorted instead
        break;
      }
      where = i;
      ++in_row[r.seq];
    }
  }
  if (placed) {
    const uint32_t* row = slot.data();
    const uint32_t* count = row_count.data();
    uint64_t steps = 0;
    for (uint64_t seq = 0; seq < seqs; ++seq) steps += count[seq] != 0;
    put_varint(p, steps);
    for (uint64_t seq = 0; seq < seqs; ++seq, row += per_group) {
      if (count[seq] == 0) continue;
      put_step_header(seq, count[seq]);
      for (uint64_t lane = 0, left = count[seq]; left > 0; ++lane) {
        if (row[lane] == kEmpty) continue;
        put_record(p, s, records[row[lane]], int64_t(lane));
        --left;
      }
    }
  } else {
    // Keys (seq << 32 | lane, position), sorted (positions break ties: stable).
    keys.clear();
    for (uint32_t i = 0; i < n; ++i)
      keys.emplace_back(uint64_t(records[i].seq) << 32 | (records[i].invocation - lane_base), i);
    std::sort(keys.begin(), keys.end());
    const auto* k0 = keys.data();
    const auto* k1 = keys.data() + keys.size();
    uint64_t steps = 1;
    for (const auto* k = k0 + 1; k < k1; ++k) steps += (k->first >> 32) != ((k - 1)->first >> 32);
    put_varint(p, steps);
    for (const auto* k = k0; k < k1;) {
      const uint64_t seq = k->first >> 32;
      const auto* j = k;
      while (j < k1 && (j->first >> 32) == seq) ++j;
      put_step_header(seq, uint64_t(j - k));
      for (; k < j; ++k) put_record(p, s, records[k->second], int64_t(k->first & 0xFFFFFFFFu));
    }
  }
  state_prev_info_ = s.prev_info;
  state_prev_offset_ = s.prev_offset;
  if (body_bytes) {
    const uint64_t size = uint64_t(p - body_bytes - 4);
    if (size > 0xFFFFFFFFu) throw InputError("trace writer: a workgroup's records code to 4 GiB or more");
    const uint32_t v = uint32_t(size);
    std::memcpy(body_bytes, &v, 4);
  }
  return size_t(p - room.get());
}

// The coding's room for `records` records of `groups` workgroups: at most 5 + 4 + 5 bytes a workgroup, 5 + 5
// a step, 1 + 5 + 2 + 4 a record, and a slice has no more steps than records. Left uninitialised: zeroing the
// bound would cost more than the coding.
void SliceEncoder::reserve_room(uint64_t records, uint64_t groups) {
  const size_t bound = 22 * records + 14 * groups + 16;
  if (room_size < bound) {
    room = std::make_unique_for_overwrite<uint8_t[]>(bound);
    room_size = bound;
  }
  next_g_ = 0;
  state_prev_info_ = state_prev_offset_ = 0;
}

void SliceEncoder::encode(std::span<const TraceRecord> records, uint64_t first_workgroup, uint64_t end_workgroup,
                          uint64_t per_group, std::vector<uint8_t>& out, uint32_t coding) {
  check_slice("encode", coding, records.size());
  const uint64_t groups = end_workgroup - first_workgroup;
  const uint64_t first_invocation = first_workgroup * per_group;
  const int shift = std::has_single_bit(per_group) ? std::countr_zero(per_group) : -1;
  const auto group_of = [&](uint32_t invocation) {
    const uint64_t i = invocation - first_invocation;
    return uint32_t(shift >= 0 ? i >> shift : i / per_group);
  };
  // Per workgroup: its record count and largest seq, and the runs of consecutive records of one workgroup
  // (one pass over the records, which also refuses what the coding cannot hold rather than writing it as
  // something else; a version-1 file stores such records as given, and its reader rejects them).
  group_begin.assign(groups + 1, 0);
  max_seq.assign(groups, 0);
  runs.clear();
  // Plain pointers into the scratch arrays here and below: through the members the compiler reloads each
  // array's address at every store.
  uint32_t* const counts = group_begin.data() + 1;
  uint32_t* const seq_max = max_seq.data();
  uint32_t run_group = kEmpty;
  for (size_t i = 0; i < records.size(); ++i) {
    const TraceRecord& r = records[i];
    if (r.invocation < first_invocation || r.invocation - first_invocation >= groups * per_group)
      refuse_invocation(i, r.invocation, first_workgroup, end_workgroup);
    if (r.info > 0xFFFF) refuse_info(i);
    const uint32_t g = group_of(r.invocation);
    ++counts[g];
    seq_max[g] = std::max(seq_max[g], r.seq);
    if (g != run_group) {
      runs.push_back({uint32_t(i), 0, g});
      run_group = g;
    }
    ++runs.back().count;
  }
  for (uint64_t g = 0; g < groups; ++g) group_begin[g + 1] += group_begin[g];
  // The runs by workgroup, in record order within each: workgroup g's are run_order[run_begin[g] ..
  // run_begin[g + 1]).
  run_begin.assign(groups + 1, 0);
  for (const Run& r : runs) ++run_begin[r.group + 1];
  for (uint64_t g = 0; g < groups; ++g) run_begin[g + 1] += run_begin[g];
  run_order.resize(runs.size());
  {
    std::vector<uint32_t>& cursor = row_count;  // scratch here; row_count is reset before each use below
    cursor.assign(run_begin.begin(), run_begin.end() - 1);
    for (size_t k = 0; k < runs.size(); ++k) run_order[cursor[runs[k].group]++] = uint32_t(k);
  }
  reserve_room(records.size(), groups);
  size_t at = 0;
  for (uint64_t g = 0; g < groups; ++g) {
    if (group_begin[g] == group_begin[g + 1]) continue;
    segments.clear();
    for (uint32_t k = run_begin[g]; k < run_begin[g + 1]; ++k) {
      const Run& run = runs[run_order[k]];
      segments.push_back({records.data() + run.first, run.count});
    }
    at = code_group(at, g, segments, group_begin[g + 1] - group_begin[g], max_seq[g], first_invocation + g * per_group,
                    per_group, coding);
  }
  out.insert(out.end(), room.get(), room.get() + at);
}

bool SliceEncoder::encode_parts(std::span<const std::span<const TraceRecord>> parts, uint64_t first_workgroup,
                                uint64_t end_workgroup, uint64_t per_group, std::vector<uint8_t>& out,
                                uint32_t coding) {
  uint64_t total = 0;
  for (const auto& part : parts) total += part.size();
  check_slice("encode_parts", coding, total);
  if (parts.size() > kMaxParts) return false;
  const uint64_t groups = end_workgroup - first_workgroup;
  const uint64_t first_invocation = first_workgroup * per_group;
  const int shift = std::has_single_bit(per_group) ? std::countr_zero(per_group) : -1;
  // Each part's next run: records [at, end) of workgroup `group`, their largest seq; `before`: the records
  // of the parts before it (for the refusals' record index), `last`: the group of its previous run.
  struct Head {
    const TraceRecord* begin;
    uint64_t at, end, size, before;
    uint64_t group, last;
    uint32_t seq_max;
  };
  std::array<Head, kMaxParts> heads;
  constexpr uint64_t kNone = ~uint64_t(0);
  // Reads part h's next run; false where it is not after the part's previous one (the parts are then
  // not in run order, and the caller gathers them).
  const auto next_run = [&](Head& h) {
    h.at = h.end;
    if (h.at == h.size) {
      h.group = kNone;
      return true;
    }
    const TraceRecord* r = h.begin + h.at;
    const auto group_of = [&](uint64_t index, const TraceRecord& x) {
      if (x.invocation < first_invocation || x.invocation - first_invocation >= groups * per_group)
        refuse_invocation(h.before + index, x.invocation, first_workgroup, end_workgroup);
      if (x.info > 0xFFFF) refuse_info(h.before + index);
      const uint64_t i = x.invocation - first_invocation;
      return shift >= 0 ? i >> shift : i / per_group;
    };
    const uint64_t g = group_of(h.at, *r);
    if (h.last != kNone && g <= h.last) return false;
    // The run ends at the first record of another workgroup: its invocation outside [lo, hi).
    const uint64_t lo = first_invocation + g * per_group, hi = lo + per_group;
    uint32_t seq = r->seq;
    uint64_t e = h.at + 1;
    for (; e < h.size; ++e) {
      const TraceRecord& x = h.begin[e];
      if (x.invocation - lo >= hi - lo) break;
      if (x.info > 0xFFFF) refuse_info(h.before + e);
      seq = std::max(seq, x.seq);
    }
    h.end = e;
    h.group = g;
    h.last = g;
    h.seq_max = seq;
    return true;
  };
  size_t n_heads = 0;
  uint64_t before = 0;
  for (const auto& part : parts) {
    if (part.empty()) continue;
    Head& h = heads[n_heads++];
    h = {part.data(), 0, 0, part.size(), before, kNone, kNone, 0};
    before += part.size();
    if (!next_run(h)) return false;
  }
  reserve_room(total, groups);
  size_t at = 0;
  for (;;) {
    uint64_t g = kNone;
    for (size_t k = 0; k < n_heads; ++k) g = std::min(g, heads[k].group);
    if (g == kNone) break;
    // The workgroup's runs, one per part at most, in part order (the order of the parts put together).
    segments.clear();
    uint64_t n = 0;
    uint32_t seq = 0;
    for (size_t k = 0; k < n_heads; ++k) {
      Head& h = heads[k];
      if (h.group != g) continue;
      segments.push_back({h.begin + h.at, uint32_t(h.end - h.at)});
      n += h.end - h.at;
      seq = std::max(seq, h.seq_max);
    }
    at = code_group(at, g, segments, n, seq, first_invocation + g * per_group, per_group, coding);
    for (size_t k = 0; k < n_heads; ++k) {
      if (heads[k].group == g && !next_run(heads[k])) return false;
    }
  }
  out.insert(out.end(), room.get(), room.get() + at);
  return true;
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
                  uint32_t* group_begin, uint32_t coding) {
  Stream s{in.data(), in.data(), in.data() + in.size(), where};
  const uint64_t groups = end_workgroup - first_workgroup;
  if (group_begin && count > 0xFFFFFFFFu) s.fail("more than 2^32 - 1 records in one slice");
  uint64_t next_g = 0, n_out = 0, checked = 0;
  CodedState state;
  constexpr uint64_t kCheckRun = 1 << 14;
  while (s.p != s.end) {
    const uint64_t g = next_g + s.varint();
    if (g >= groups) s.fail("workgroup " + std::to_string(first_workgroup + g) + " outside the slice");
    if (group_begin) {
      for (uint64_t e = next_g; e <= g; ++e) group_begin[e] = uint32_t(n_out);  // g and the empty ones before it
    }
    next_g = g + 1;
    const uint8_t* body_end = nullptr;  // coding 2: where the workgroup's body must end
    if (coding == kCodingSizedGroups) {
      if (s.end - s.p < 4) s.fail("truncated");
      uint32_t size;
      std::memcpy(&size, s.p, 4);
      s.p += 4;
      if (size > uint64_t(s.end - s.p))
        s.fail("workgroup " + std::to_string(first_workgroup + g) + ": body of " + std::to_string(size) +
               " bytes past the end of the slice");
      body_end = s.p + size;
      state = CodedState{};
    }
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
        // Fast path, kRecordReadBytes or more left (every record but the last few of a slice); a defect
        // takes the careful path, which names it.
        uint64_t d;
        if (s.end - s.p >= int64_t(kRecordReadBytes)) {
          if (const uint8_t* q = decode_record(s.p, state, d)) {
            lane += int64_t(d);
            if (uint64_t(lane) >= per_group) s.fail("lane " + std::to_string(lane) + " outside the workgroup");
            s.p = q;
            out[n_out++] = TraceRecord{uint32_t(base + uint64_t(lane)), uint32_t(seq), state.info, state.offset};
            continue;
          }
        }
        if (s.p == s.end) s.fail("truncated");
        const uint8_t c = *s.p++;
        if (c & 0x80) s.fail("reserved control bit set");
        d = c & 7;
        if (d == 7) d += s.varint();
        lane += int64_t(d);
        if (uint64_t(lane) >= per_group) s.fail("lane " + std::to_string(lane) + " outside the workgroup");
        if (c & 8) {
          if (s.end - s.p < 2) s.fail("truncated");
          state.info = uint32_t(s.p[0]) | uint32_t(s.p[1]) << 8;
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
          state.offset = v;
        } else {
          const int64_t diff = int64_t(v >> 1) ^ -int64_t(v & 1);
          const int64_t off = int64_t(state.offset) + diff;
          if (off < 0 || off > 0xFFFFFFFFll) s.fail("offset outside 32 bits");
          state.offset = uint32_t(off);
        }
        out[n_out++] = TraceRecord{uint32_t(base + uint64_t(lane)), uint32_t(seq), state.info, state.offset};
      }
    }
    if (body_end && s.p != body_end)
      s.fail("workgroup " + std::to_string(first_workgroup + g) + ": its body ends " + std::to_string(s.p - body_end) +
             " bytes from the size it states");
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

bool index_workgroups(std::span<const uint8_t> in, uint64_t first_workgroup, uint64_t end_workgroup,
                      std::vector<std::pair<uint64_t, uint64_t>>& bodies) {
  const uint64_t groups = end_workgroup - first_workgroup;
  bodies.assign(groups, {0, 0});
  const uint8_t* const begin = in.data();
  const uint8_t* p = begin;
  const uint8_t* const end = begin + in.size();
  uint64_t next_g = 0;
  while (p != end) {
    uint64_t delta = 0;
    bool done = false;
    for (int shift = 0; shift < 35 && p != end; shift += 7) {
      const uint8_t b = *p++;
      delta |= uint64_t(b & 0x7F) << shift;
      if (!(b & 0x80)) {
        done = true;
        break;
      }
    }
    if (!done || delta >= groups - next_g || end - p < 4) return false;
    const uint64_t g = next_g + delta;
    uint32_t size;
    std::memcpy(&size, p, 4);
    p += 4;
    if (size == 0 || size > uint64_t(end - p)) return false;
    bodies[g] = {uint64_t(p - begin), uint64_t(p - begin) + size};
    p += size;
    next_g = g + 1;
  }
  return true;
}

}  // namespace hp::trace
