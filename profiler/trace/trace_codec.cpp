#include "trace/trace_codec.hpp"

#include <algorithm>
#include <array>
#include <bit>
#include <cstring>
#include <stdexcept>

#if defined(__x86_64__)
#include <immintrin.h>
#endif

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
[[gnu::always_inline]] inline void put_record(uint8_t*& p, CodeState& s, uint32_t info, uint32_t offset, int64_t lane) {
  const uint64_t d = uint64_t(lane - s.prev_lane);
  s.prev_lane = lane;
  uint8_t control = uint8_t(std::min<uint64_t>(d, 7));
  if (info != s.prev_info) control |= 8;
  // A difference of 2^31 or more either way has a 33-bit zigzag: such an offset is stored as itself (mode 4).
  const uint64_t zz = zigzag(int64_t(offset) - int64_t(s.prev_offset));
  const uint32_t mode = std::min(uint32_t(std::bit_width(zz) + 7) >> 3, 4u);  // zz's bytes, 0..4 (4: the offset itself)
  control |= uint8_t(mode << 4);
  *p++ = control;
  if (d >= 7) put_varint(p, d - 7);
  if (info != s.prev_info) {
    *p++ = uint8_t(info);
    *p++ = uint8_t(info >> 8);
    s.prev_info = info;
  }
  const uint32_t v = mode == 4 ? offset : uint32_t(zz);
  std::memcpy(p, &v, 4);  // little-endian; only the first `mode` count
  p += mode;
  s.prev_offset = offset;
}

// The lanes of a row of 64 occupancy bytes that are set, as bits.
inline uint64_t occupied_lanes(const uint8_t* row) {
#if defined(__SSE2__)
  uint64_t m = 0;
  for (int q = 0; q < 4; ++q) {
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(row + 16 * q));
    m |= uint64_t(uint32_t(_mm_movemask_epi8(_mm_cmpeq_epi8(v, _mm_setzero_si128()))) ^ 0xFFFFu) << (16 * q);
  }
  return m;
#else
  uint64_t m = 0;
  for (int l = 0; l < 64; ++l) m |= uint64_t(row[l] != 0) << l;
  return m;
#endif
}

#if defined(__x86_64__)
// GCC 12's AVX-512 headers start several intrinsics from _mm512_undefined_epi32(), which -Wmaybe-uninitialized
// reports as a use of an uninitialized value (GCC bug 105593); nothing here reads one.
#if !defined(__clang__)
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
// One step of up to 64 lanes with AVX-512 (F, BW, VBMI2): the step's records, in lane order, are taken from
// a row of the tables with compress, then coded eight at a time, each record built in a 64-bit word (at most
// 8 bytes with up to 64 lanes: a lane delta of 7 or more then takes one varint byte) and the words packed
// with a byte compress. The same bytes as put_record's, which the tests compare.
[[gnu::target("avx512f,avx512bw,avx512vbmi2")]] uint8_t* code_step_avx512(uint8_t* p, CodeState& s, uint64_t lanes,
                                                                          const uint32_t* info_row,
                                                                          const uint32_t* offset_row) {
  // Staged values, index 0 the previous record's (lane -1 at a step's start), then the step's in lane order.
  alignas(64) uint32_t infos[96], offsets[96], lane_of[96];  // up to 1 + 64 values, then 16 zeros
  infos[0] = s.prev_info;
  offsets[0] = s.prev_offset;
  lane_of[0] = uint32_t(-1);
  uint32_t k = 1;
  const __m512i iota = _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
  for (uint32_t c = 0; c < 4; ++c) {
    const __mmask16 m = __mmask16(lanes >> (16 * c));
    if (!m) continue;
    _mm512_storeu_si512(infos + k, _mm512_maskz_compress_epi32(m, _mm512_loadu_si512(info_row + 16 * c)));
    _mm512_storeu_si512(offsets + k, _mm512_maskz_compress_epi32(m, _mm512_loadu_si512(offset_row + 16 * c)));
    _mm512_storeu_si512(lane_of + k,
                        _mm512_maskz_compress_epi32(m, _mm512_add_epi32(iota, _mm512_set1_epi32(int(16 * c)))));
    k += uint32_t(std::popcount(uint32_t(m)));
  }
  const uint32_t count = k - 1;
  // Defined values past the last record, which the last eight are read with (their lengths are then 0).
  _mm512_storeu_si512(infos + k, _mm512_setzero_si512());
  _mm512_storeu_si512(offsets + k, _mm512_setzero_si512());
  _mm512_storeu_si512(lane_of + k, _mm512_setzero_si512());
  const __m512i byte_in_word = _mm512_set1_epi64(0x0706050403020100ll);
  // pshufb indices (within each 128-bit lane) that copy each word's length byte over the word's eight bytes
  const __m512i len_to_bytes = _mm512_set_epi64(0x0808080808080808ll, 0, 0x0808080808080808ll, 0, 0x0808080808080808ll,
                                                0, 0x0808080808080808ll, 0);
  for (uint32_t i = 0; i < count; i += 8) {
    const __mmask8 valid = __mmask8(count - i >= 8 ? 0xFF : (1u << (count - i)) - 1);
    const __m512i off =
        _mm512_maskz_cvtepu32_epi64(0xFF, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(offsets + 1 + i)));
    const __m512i prev_off =
        _mm512_maskz_cvtepu32_epi64(0xFF, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(offsets + i)));
    const __m512i info =
        _mm512_maskz_cvtepu32_epi64(0xFF, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(infos + 1 + i)));
    const __m512i prev_info =
        _mm512_maskz_cvtepu32_epi64(0xFF, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(infos + i)));
    const __m512i lane =
        _mm512_maskz_cvtepi32_epi64(0xFF, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(lane_of + 1 + i)));
    const __m512i prev_lane =
        _mm512_maskz_cvtepi32_epi64(0xFF, _mm256_loadu_si256(reinterpret_cast<const __m256i*>(lane_of + i)));
    const __m512i d = _mm512_sub_epi64(lane, prev_lane);
    const __m512i diff = _mm512_sub_epi64(off, prev_off);
    const __m512i zz = _mm512_xor_si512(_mm512_slli_epi64(diff, 1), _mm512_srai_epi64(diff, 63));
    const __m512i one = _mm512_set1_epi64(1);
    __m512i mode = _mm512_maskz_mov_epi64(_mm512_cmpgt_epu64_mask(zz, _mm512_setzero_si512()), one);
    mode = _mm512_mask_add_epi64(mode, _mm512_cmpgt_epu64_mask(zz, _mm512_set1_epi64(0xFF)), mode, one);
    mode = _mm512_mask_add_epi64(mode, _mm512_cmpgt_epu64_mask(zz, _mm512_set1_epi64(0xFFFF)), mode, one);
    const __mmask8 whole = _mm512_cmpgt_epu64_mask(zz, _mm512_set1_epi64(0xFFFFFF));
    mode = _mm512_mask_add_epi64(mode, whole, mode, one);
    const __m512i value = _mm512_mask_blend_epi64(whole, zz, off);
    const __mmask8 new_info = _mm512_cmpneq_epi64_mask(info, prev_info);
    const __mmask8 long_delta = _mm512_cmpge_epi64_mask(d, _mm512_set1_epi64(7));
    __m512i word = _mm512_min_epi64(d, _mm512_set1_epi64(7));
    word = _mm512_mask_or_epi64(word, new_info, word, _mm512_set1_epi64(8));
    word = _mm512_or_si512(word, _mm512_slli_epi64(mode, 4));
    word =
        _mm512_mask_or_epi64(word, long_delta, word, _mm512_slli_epi64(_mm512_sub_epi64(d, _mm512_set1_epi64(7)), 8));
    __m512i pos = _mm512_mask_add_epi64(one, long_delta, one, one);  // bytes so far: control, varint
    word = _mm512_or_si512(word, _mm512_sllv_epi64(_mm512_maskz_mov_epi64(new_info, info), _mm512_slli_epi64(pos, 3)));
    pos = _mm512_mask_add_epi64(pos, new_info, pos, _mm512_set1_epi64(2));
    word = _mm512_or_si512(word, _mm512_sllv_epi64(value, _mm512_slli_epi64(pos, 3)));
    const __m512i len = _mm512_maskz_add_epi64(valid, pos, mode);
    const __mmask64 keep = _mm512_cmplt_epu8_mask(byte_in_word, _mm512_shuffle_epi8(len, len_to_bytes));
    _mm512_storeu_si512(p, _mm512_maskz_compress_epi8(keep, word));
    p += std::popcount(uint64_t(keep));
  }
  s.prev_info = infos[count];
  s.prev_offset = offsets[count];
  return p;
}
#if !defined(__clang__)
#pragma GCC diagnostic pop
#endif
const bool kCpuHasAvx512Vbmi2 =
    __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512vbmi2");
#else
const bool kCpuHasAvx512Vbmi2 = false;
#endif

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

bool SliceEncoder::simd_available() { return kCpuHasAvx512Vbmi2; }

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
  // record's info word and offset placed into its slot and the slot marked occupied, read back seq by seq
  // over the occupied lanes (linear time, and the table small enough to stay in the host's caches while the
  // workgroup is coded; a seq of at most 64 lanes is coded with AVX-512 where the host has it). A key that
  // repeats (the format allows it), or a table much larger than the workgroup's records, takes a comparison
  // sort of the workgroup's keys instead; both give the same order.
  const uint64_t seqs = uint64_t(max_seq) + 1;
  bool placed = seqs * per_group <= 8 * n + 4096;
  if (placed) {
    // The tables are kept unoccupied between workgroups (a row is cleared once coded), so a workgroup
    // touches only its own rows; 64 slots past the last row for the step coder's whole-vector reads.
    const uint64_t slots = seqs * per_group + 64;
    if (occupied.size() < slots) {
      occupied.resize(slots, 0);
      info_table.resize(slots);
      offset_table.resize(slots);
    }
    uint8_t* const occ = occupied.data();
    uint32_t* const infos = info_table.data();
    uint32_t* const offsets = offset_table.data();
    uint32_t i = 0;
    for (; i < n; ++i) {
      const TraceRecord& r = records[i];
      const uint64_t at_slot = uint64_t(r.seq) * per_group + (r.invocation - lane_base);
      if (occ[at_slot]) break;  // a repeated key: this workgroup is sorted instead
      occ[at_slot] = 1;
      infos[at_slot] = r.info;
      offsets[at_slot] = r.offset;
    }
    if (i < n) {
      placed = false;
      for (uint32_t k = 0; k < i; ++k)
        occ[uint64_t(records[k].seq) * per_group + (records[k].invocation - lane_base)] = 0;
    }
  }
  if (placed) {
    uint8_t* const occ = occupied.data();
    const uint32_t* const infos = info_table.data();
    const uint32_t* const offsets = offset_table.data();
    // Each seq's lanes as bits, ceil(per_group / 64) words a seq.
    const uint64_t words = (per_group + 63) / 64;
    row_lanes.resize(seqs * words);
    uint64_t* const lanes = row_lanes.data();
    uint64_t steps = 0;
    for (uint64_t seq = 0; seq < seqs; ++seq) {
      uint64_t any = 0;
      for (uint64_t w = 0; w < words; ++w) {
        const uint64_t left = per_group - 64 * w;
        uint64_t m = occupied_lanes(occ + seq * per_group + 64 * w);
        if (left < 64) m &= (uint64_t(1) << left) - 1;
        lanes[seq * words + w] = m;
        any |= m;
      }
      steps += any != 0;
    }
    put_varint(p, steps);
    const bool simd = simd_ && kCpuHasAvx512Vbmi2 && per_group <= 64;
    for (uint64_t seq = 0; seq < seqs; ++seq) {
      const uint64_t* const row_bits = lanes + seq * words;
      uint64_t count = 0;
      for (uint64_t w = 0; w < words; ++w) count += uint64_t(std::popcount(row_bits[w]));
      if (count == 0) continue;
      put_step_header(seq, count);
      const uint64_t row = seq * per_group;
#if defined(__x86_64__)
      if (simd) {
        p = code_step_avx512(p, s, row_bits[0], infos + row, offsets + row);
        std::memset(occ + row, 0, per_group);
        continue;
      }
#endif
      for (uint64_t w = 0; w < words; ++w) {
        for (uint64_t b = row_bits[w]; b != 0; b &= b - 1) {
          const uint64_t lane = 64 * w + uint64_t(std::countr_zero(b));
          put_record(p, s, infos[row + lane], offsets[row + lane], int64_t(lane));
        }
      }
      std::memset(occ + row, 0, per_group);
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
      for (; k < j; ++k) {
        const TraceRecord& r = records[k->second];
        put_record(p, s, r.info, r.offset, int64_t(k->first & 0xFFFFFFFFu));
      }
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
// a step, 1 + 5 + 2 + 4 a record, and a slice has no more steps than records, and 64 bytes for the step coder's
// whole-vector store past its last record. Left uninitialised: zeroing the bound would cost more than the coding.
void SliceEncoder::reserve_room(uint64_t records, uint64_t groups) {
  const size_t bound = 22 * records + 14 * groups + 16 + 64;
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
  cursor.assign(run_begin.begin(), run_begin.end() - 1);
  for (size_t k = 0; k < runs.size(); ++k) run_order[cursor[runs[k].group]++] = uint32_t(k);
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
      // 4 KiB ahead: the hardware's stream prefetch stops at page boundaries, and this is the slice's first
      // read of records another core wrote (a prefetch past the part's end is harmless).
      __builtin_prefetch(&x + 256);
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
