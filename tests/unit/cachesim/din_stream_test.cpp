// The streamed Dinero reader (trace::DinReader) and file replay (cachesim::replay_din_file) against the
// whole-file parser and replay they replace on the CLI: the same accesses, the same counts, the same
// errors, across read-buffer boundaries and on lines the fast path hands to the full parser.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <functional>
#include <random>
#include <sstream>
#include <string>
#include <unistd.h>
#include <vector>

#include "cachesim/din_replay.hpp"
#include "error.hpp"
#include "trace/din.hpp"

namespace hp {
namespace {

namespace fs = std::filesystem;

struct TempFile {
  fs::path path;
  explicit TempFile(const std::string& name, const std::string& text)
      : path(fs::temp_directory_path() / ("hp_din_stream_" + std::to_string(::getpid()) + "_" + name)) {
    std::ofstream(path, std::ios::binary) << text;
  }
  ~TempFile() {
    std::error_code ec;
    fs::remove(path, ec);
  }
};

std::vector<trace::DinAccess> streamed(const fs::path& path, size_t batch) {
  trace::DinReader r(path);
  std::vector<trace::DinAccess> out, buf(batch);
  while (size_t n = r.read(buf)) out.insert(out.end(), buf.begin(), buf.begin() + long(n));
  return out;
}

std::vector<trace::DinAccess> whole(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return trace::parse_din(in, path.string());
}

void expect_same(const std::vector<trace::DinAccess>& a, const std::vector<trace::DinAccess>& b) {
  ASSERT_EQ(a.size(), b.size());
  for (size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i].write, b[i].write) << i;
    ASSERT_EQ(a[i].address, b[i].address) << i;
    ASSERT_EQ(a[i].size, b[i].size) << i;
  }
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "no error";
}

std::string hex(uint64_t v, bool upper = false) {
  std::ostringstream s;
  if (upper) s << std::uppercase;
  s << std::hex << v;
  return s.str();
}

// Mostly fast-path lines, with every other accepted shape mixed in: comments, blank lines, 0x prefixes,
// tabs and runs of spaces, CRLF, upper case, 0/1 labels, 16 hex digits, leading zeros past 16 digits.
std::string mixed_trace(size_t lines, uint32_t seed) {
  std::mt19937_64 rng(seed);
  std::string t;
  for (size_t i = 0; i < lines; ++i) {
    const uint64_t addr = rng() >> (rng() % 64);
    const uint32_t size = uint32_t(1 + rng() % 200);
    const char* label = (rng() & 1) ? "r" : "w";
    switch (rng() % 24) {
      case 0: t += "# a comment line " + std::to_string(i) + "\n"; break;
      case 1: t += "\n"; break;
      case 2: t += std::string(label) + " 0x" + hex(addr) + " 0X" + hex(size) + "\n"; break;
      case 3: t += std::string("\t") + label + "\t" + hex(addr) + "   " + hex(size) + " \n"; break;
      case 4: t += std::string(label) + " " + hex(addr) + " " + hex(size) + "\r\n"; break;
      case 5: t += std::string(label) + " " + hex(addr, true) + " " + hex(size, true) + "\n"; break;
      case 6: t += std::string((rng() & 1) ? "0" : "1") + " " + hex(addr) + " " + hex(size) + "\n"; break;
      case 7: t += std::string(label) + " " + "ffffffffffffffff " + hex(size) + "\n"; break;
      case 8: t += std::string(label) + " 00000000000000000000" + hex(addr) + " 0000000004\n"; break;
      case 9: t += "   \r\n"; break;
      default: t += std::string(label) + " " + hex(addr) + " " + hex(size) + "\n"; break;
    }
  }
  return t;
}

TEST(DinStream, SameAccessesAsTheWholeFileParserAcrossBufferBoundaries) {
  // ~3.5 MiB: several refills of the 1 MiB buffer, lines cut at every boundary.
  const TempFile f("mixed.din", mixed_trace(220000, 7));
  ASSERT_GT(fs::file_size(f.path), 3 * trace::DinReader::kBufferBytes);
  const auto expected = whole(f.path);
  ASSERT_GT(expected.size(), 100000u);
  for (size_t batch : {size_t(1), size_t(7), size_t(16384)}) expect_same(streamed(f.path, batch), expected);
}

TEST(DinStream, LastLineWithoutNewlineAndTinyFiles) {
  for (const std::string& text :
       {std::string(""), std::string("\n"), std::string("r 10 4"), std::string("w 0x20 1\r"),
        std::string("# only a comment"), std::string("r 10 4\nw 20 8"), std::string("r 1 1\n\n\n")}) {
    const TempFile f("tiny.din", text);
    expect_same(streamed(f.path, 3), whole(f.path));
  }
}

TEST(DinStream, ErrorsNameTheFileAndTheLineLikeTheWholeFileParser) {
  // The bad line far past the first buffer, in each shape the parser rejects.
  const std::string good = mixed_trace(60000, 3);
  size_t good_lines = 0;
  for (char c : good) good_lines += c == '\n';
  for (const std::string bad : {"x 10 4", "r 1g 4", "r 10", "r 10 0", "w 10 4 9", "r 10 100000000", "r",
                                "r 10000000000000000f 4", "r 0x 4", "r 10 4\v"}) {
    // Lines follow it, so the fast parser sees the bad line before the full parser does.
    const TempFile f("bad.din", good + bad + "\n" + mixed_trace(100, 4));
    const std::string want = error_of([&] { whole(f.path); });
    ASSERT_EQ(want.rfind(f.path.string() + ":" + std::to_string(good_lines + 1) + ": ", 0), 0u) << want;
    EXPECT_EQ(error_of([&] { streamed(f.path, 16384); }), want) << bad;
  }
  EXPECT_EQ(error_of([&] {
              trace::DinReader r("/nonexistent/x.din");
            }).rfind("/nonexistent/x.din: cannot open Dinero trace", 0),
            0u);
  EXPECT_EQ(error_of([&] { trace::DinReader r(fs::temp_directory_path()); }),
            fs::temp_directory_path().string() + ": is a directory, not a Dinero trace");
}

TEST(DinStream, LongCommentAndBlankLinesAreSkippedALongAccessLineIsAnError) {
  const size_t big = trace::DinReader::kBufferBytes * 2 + 123;
  {
    const TempFile f("longcomment.din",
                     "r 10 4\n  # " + std::string(big, 'c') + "\nw 20 8\n" + "#" + std::string(big, 'z'));
    const auto got = streamed(f.path, 16);
    expect_same(got, whole(f.path));
    EXPECT_EQ(got.size(), 2u);
  }
  {
    const TempFile f("longblank.din",
                     "r 10 4\n" + std::string(big, ' ') + "w 20 8\n" + std::string(big, '\t') + "\nr 1 1\n");
    const auto got = streamed(f.path, 16);
    expect_same(got, whole(f.path));
    EXPECT_EQ(got.size(), 3u);
  }
  {
    const TempFile f("longline.din", "r 10 4\nr 10 " + std::string(big, '0') + "4\n");
    EXPECT_EQ(error_of([&] { streamed(f.path, 16); }),
              f.path.string() + ":2: line longer than " + std::to_string(trace::DinReader::kBufferBytes) + " bytes");
  }
}

TEST(DinStream, FileReplayCountsEqualTheWholeFileReplay) {
  // Accesses spanning two and more L1 blocks, reads and writes, a footprint larger than the L2.
  std::mt19937_64 rng(11);
  std::string t;
  for (int i = 0; i < 400000; ++i) {
    const uint64_t addr = (rng() % (uint64_t(64) << 20)) & ~uint64_t(rng() % 2 ? 3 : 0);
    t += std::string(rng() % 4 ? "r " : "w ") + hex(addr) + " " + hex(1 + rng() % 160) + "\n";
  }
  const TempFile f("replay.din", t);
  const auto l1 = cachesim::parse_cache_spec("16k:64:4", "--l1");
  const auto l2 = cachesim::parse_cache_spec("1m:128:8", "--l2");
  for (bool curves : {false, true}) {
    const cachesim::DinResult want = cachesim::replay_din(trace::read_din(f.path), l1, l2, curves);
    uint64_t refs = 0;
    const cachesim::DinResult got = cachesim::replay_din_file(f.path, l1, l2, curves, refs);
    EXPECT_EQ(refs, 400000u);
    for (auto [g, w] : {std::pair{&got.l1, &want.l1}, std::pair{&got.l2, &want.l2}}) {
      EXPECT_EQ(g->fetches, w->fetches);
      EXPECT_EQ(g->read_fetches, w->read_fetches);
      EXPECT_EQ(g->write_fetches, w->write_fetches);
      EXPECT_EQ(g->misses, w->misses);
      EXPECT_EQ(g->read_misses, w->read_misses);
      EXPECT_EQ(g->write_misses, w->write_misses);
    }
    EXPECT_GT(got.l1.fetches, 400000u);  // some accesses span blocks
    EXPECT_GT(got.l2.misses, 0u);
    EXPECT_EQ(got.l1_copies_back, want.l1_copies_back);
    EXPECT_EQ(got.l1_curve.accesses, want.l1_curve.accesses);
    EXPECT_EQ(got.l2_curve.cold, want.l2_curve.cold);
    if (curves) {
      EXPECT_GT(got.l2_curve.accesses, 0u);
      for (uint64_t lines = 1; lines <= 1 << 20; lines *= 4)
        EXPECT_EQ(got.l2_curve.miss_ratio(lines), want.l2_curve.miss_ratio(lines)) << lines;
    }
  }
}

}  // namespace
}  // namespace hp
