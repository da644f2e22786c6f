// GPU presets: the execution model and cache figures of one GPU, loaded from a JSON file.
//
// Shipped presets live in profiler/cachesim/presets/NAME.json (vega56, ga102, h100), each citing the
// sources of its figures in "sources". A preset is found by name in the source tree's presets folder
// (compile definition HP_CACHESIM_PRESET_DIR), then beside the installed executable
// (EXE_DIR/presets, EXE_DIR/../share/hybridprof/presets); an argument containing '/' or ending in
// ".json" is a path to a custom preset.
//
// Schema (every key required unless marked optional; unknown keys are errors):
//   name (string), description (string, optional), sources (array of strings),
//   compute_units, wave_width, max_waves_per_cu (positive integers),
//   coalescing ("line": unique lines per wavefront step, AMD-like; "sector": unique sectors grouped
//               by line, NVIDIA-like),
//   l1_hit_counting (optional, "request"): what the L1 table's lookups and hits count, see HitCounting
//               ("request" | "quarter_wave" | "lane"); the L2 is always counted per request,
//   l1, l2: { size_bytes, line_bytes, sector_bytes (optional, default line_bytes), ways,
//             channels (optional, 1), channel_interleave_bytes (optional, line_bytes),
//             replacement ("lru" | "fifo" | "random", optional, lru), seed (optional, 1) }
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "cachesim/cache.hpp"

namespace hp::cachesim {

enum class Coalescing : uint8_t { line, sector };

// What one L1 load lookup is, for the L1's lookup and hit counts (docs/cache-model.md, "Counting L1
// hits"). The caches see the same coalesced requests, in the same order, under every counting: a
// request changes the L1's state once and misses or hits as a whole, so misses (and everything below
// the L1: the L2 sees the L1's line requests) are the same under all three; only lookups and hits
// (lookups - misses) differ. Per L1 load request of a wavefront step:
//   request       one lookup (the coalesced line request; the default);
//   quarter_wave  one lookup per quarter of the wavefront (lanes [0, q), [q, 2q), ..., q = wave_width / 4
//                 rounded up: 16 lanes on wave64, GCN's vector memory unit taking 16 lanes a cycle) that
//                 has a lane in the request: the first misses when the request misses, the others hit;
//   lane          one lookup per lane access the request serves (a lane whose access spans two lines
//                 counts once in each line's request): the first misses when the request misses, every
//                 further lane hits (its line was just fetched).
enum class HitCounting : uint8_t { request, quarter_wave, lane };
const char* to_string(HitCounting c);
// Parses "request", "quarter_wave" or "lane"; false for anything else.
bool parse_hit_counting(std::string_view text, HitCounting& out);

struct Preset {
  std::string name;
  std::string description;
  std::vector<std::string> sources;
  uint32_t compute_units = 1;
  uint32_t wave_width = 64;
  uint32_t max_waves_per_cu = 40;
  Coalescing coalescing = Coalescing::line;
  HitCounting l1_hit_counting = HitCounting::request;
  CacheConfig l1, l2;
  std::filesystem::path file;  // where it was loaded from (empty when built in code)
};

// Parses and validates preset JSON text; errors are hp::InputError "ORIGIN: KEY.PATH: reason".
Preset parse_preset(std::string_view json_text, const std::string& origin);
Preset load_preset_file(const std::filesystem::path& path);
// By name (shipped presets) or path; an unknown name lists the known ones.
Preset find_preset(std::string_view name_or_path);

// The preset scaled down for a trace that records 1 in `k` workgroups: 1/k of the compute units (each
// keeps its L1 and its occupancy, so a CU still sees as many workgroups, as densely, as in the full
// frame) and 1/k of the L2 (fewer sets, same ways and lines; channels reduced to fit), so the shared L2
// sees the traffic of 1/k of the CUs in 1/k of the space. k = 1 returns the preset unchanged.
Preset scale_for_sampling(const Preset& preset, uint32_t k);
std::vector<std::string> known_presets();
std::vector<std::filesystem::path> preset_dirs();

}  // namespace hp::cachesim
