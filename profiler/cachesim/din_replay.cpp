#include "cachesim/din_replay.hpp"

#include <bit>
#include <charconv>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

#include "error.hpp"

namespace hp::cachesim {

namespace {

bool parse_size(std::string_view s, uint64_t& out) {
  if (s.empty()) return false;
  uint64_t mult = 1;
  const char last = char(std::tolower(static_cast<unsigned char>(s.back())));
  if (last == 'k' || last == 'm' || last == 'g') {
    mult = last == 'k' ? 1ull << 10 : last == 'm' ? 1ull << 20 : 1ull << 30;
    s.remove_suffix(1);
  }
  uint64_t v = 0;
  auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), v);
  if (ec != std::errc() || end != s.data() + s.size() || v == 0 || v > (~0ull) / mult) return false;
  out = v * mult;
  return true;
}

}  // namespace

CacheConfig parse_cache_spec(const std::string& spec, const std::string& option) {
  const size_t a = spec.find(':'), b = a == std::string::npos ? a : spec.find(':', a + 1);
  auto fail = [&](const std::string& why) -> CacheConfig {
    throw InputError(option + " '" + spec + "': " + why + " (expected SIZE:LINE:ASSOC, e.g. 16k:64:4)");
  };
  if (b == std::string::npos || spec.find(':', b + 1) != std::string::npos) return fail("not three fields");
  uint64_t size = 0, line = 0, assoc = 0;
  if (!parse_size(std::string_view(spec).substr(0, a), size)) return fail("bad size");
  if (!parse_size(std::string_view(spec).substr(a + 1, b - a - 1), line) || line > 0xFFFFFFFFull)
    return fail("bad line size");
  if (!parse_size(std::string_view(spec).substr(b + 1), assoc) || assoc > 0xFFFFFFFFull)
    return fail("bad associativity");
  CacheConfig c;
  c.size_bytes = size;
  c.line_bytes = uint32_t(line);
  c.sector_bytes = uint32_t(line);
  c.ways = uint32_t(assoc);
  if (std::string err = check_config(c); !err.empty()) return fail(err);
  return c;
}

DinReplay::DinReplay(const CacheConfig& l1, const CacheConfig& l2, bool curves)
    : l1_(l1), l2_(l2), curves_(curves), sd1_(l1.line_bytes), sd2_(l2.line_bytes) {}

void DinReplay::access(std::span<const trace::DinAccess> accesses) {
  Cache& l1 = l1_;
  Cache& l2 = l2_;
  DinResult& r = r_;
  const bool curves = curves_;
  const uint32_t s1 = l1.line_shift(), s2 = l2.line_shift();
  const uint32_t m1 = l1.full_mask(), m2 = l2.full_mask();
  for (const trace::DinAccess& a : accesses) {
    const uint64_t first = a.address >> s1, last = (a.address + a.size - 1) >> s1;
    for (uint64_t block = first; block <= last; ++block) {
      ++r.l1.fetches;
      a.write ? ++r.l1.write_fetches : ++r.l1.read_fetches;
      if (curves) sd1_.access(block);
      const Outcome o = a.write ? l1.update(block, m1) : l1.load(block, m1);
      r.l1_copies_back += o.written_back_sectors ? 1 : 0;
      if (!o.missing) continue;
      ++r.l1.misses;
      a.write ? ++r.l1.write_misses : ++r.l1.read_misses;
      // The L1 block's bytes, as L2 blocks.
      const uint64_t lo = (block << s1) >> s2, hi = (((block + 1) << s1) - 1) >> s2;
      for (uint64_t b2 = lo; b2 <= hi; ++b2) {
        ++r.l2.fetches;
        a.write ? ++r.l2.write_fetches : ++r.l2.read_fetches;
        if (curves) sd2_.access(b2);
        if (l2.load(b2, m2).missing) {
          ++r.l2.misses;
          a.write ? ++r.l2.write_misses : ++r.l2.read_misses;
        }
      }
    }
  }
}

DinResult DinReplay::result() const {
  DinResult r = r_;
  if (curves_) {
    r.l1_curve = sd1_.curve();
    r.l2_curve = sd2_.curve();
  }
  return r;
}

DinResult replay_din(std::span<const trace::DinAccess> accesses, const CacheConfig& l1c, const CacheConfig& l2c,
                     bool curves) {
  DinReplay replay(l1c, l2c, curves);
  replay.access(accesses);
  return replay.result();
}

DinResult replay_din_file(const std::filesystem::path& path, const CacheConfig& l1, const CacheConfig& l2, bool curves,
                          uint64_t& references) {
  trace::DinReader reader(path);
  DinReplay replay(l1, l2, curves);
  references = 0;
  constexpr size_t kSlots = 4;  // batches in flight between the parsing thread and the replay
  std::vector<trace::DinAccess> slots[kSlots];
  size_t count[kSlots] = {};
  for (auto& s : slots) s.resize(kDinBatch);
  if (std::thread::hardware_concurrency() < 2) {
    while (const size_t n = reader.read(slots[0])) {
      replay.access(std::span<const trace::DinAccess>(slots[0].data(), n));
      references += n;
    }
    return replay.result();
  }
  // One thread parses into the slots while this one replays them, in file order.
  std::mutex m;
  std::condition_variable cv;
  uint64_t produced = 0, consumed = 0;
  bool end = false;
  std::exception_ptr error;
  std::thread parser([&] {
    try {
      while (true) {
        {
          std::unique_lock lk(m);
          cv.wait(lk, [&] { return produced - consumed < kSlots; });
        }
        const size_t s = produced % kSlots;
        const size_t n = reader.read(slots[s]);
        std::lock_guard lk(m);
        if (n == 0) {
          end = true;
          cv.notify_all();
          return;
        }
        count[s] = n;
        ++produced;
        cv.notify_all();
      }
    } catch (...) {
      std::lock_guard lk(m);
      error = std::current_exception();
      end = true;
      cv.notify_all();
    }
  });
  std::unique_lock lk(m);
  while (true) {
    cv.wait(lk, [&] { return consumed < produced || end; });
    if (consumed == produced) break;  // the end, or the parser's error
    const size_t s = consumed % kSlots;
    lk.unlock();
    replay.access(std::span<const trace::DinAccess>(slots[s].data(), count[s]));
    references += count[s];
    lk.lock();
    ++consumed;
    cv.notify_all();
  }
  lk.unlock();
  parser.join();
  if (error) std::rethrow_exception(error);
  return replay.result();
}

}  // namespace hp::cachesim
