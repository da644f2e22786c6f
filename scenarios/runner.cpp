#include "runner.hpp"

#include "atomic_file.hpp"
#include "cache_analysis.hpp"
#include "cell_record.hpp"
#include "error.hpp"
#include "frame_profiler.hpp"
#include "input_file.hpp"
#include "json_depth.hpp"
#include "reference/compare.hpp"
#include "scene/load.hpp"
#include "stable_id.hpp"
#include "timing/jsonl.hpp"
#include "timing/result_json.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <set>
#include <unistd.h>

namespace hp {

namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

constexpr const char* kResults = "results.jsonl";
constexpr const char* kFolderFile = "matrix.json";
constexpr const char* kUnsupportedFile = "unsupported.json";
constexpr const char* kRoundsFile = "rounds.jsonl";  // finished rounds of cells not finished yet

// What a results folder belongs to: the matrix's name and a hash of its expanded cells' ids.
json folder_identity(const std::string& matrix, std::vector<std::string> ids, std::uint32_t rounds) {
  std::sort(ids.begin(), ids.end());
  std::string all;
  for (const std::string& id : ids) all += id + "\n";
  return {{"schema", "hybridprof.results-folder"}, {"version", 1},    {"matrix", matrix}, {"cells", ids.size()},
          {"cells_hash", stable_id(all)},          {"rounds", rounds}};
}

// OUT/matrix.json, or null when the folder has none (new, or written before folders recorded their matrix).
json read_folder_identity(const fs::path& dir) {
  const fs::path path = dir / kFolderFile;
  std::error_code ec;
  if (!fs::exists(path, ec)) return nullptr;
  const std::string text = read_input_file(path, "results folder file");
  check_json_depth(text, path.string());
  json j;
  try {
    j = json::parse(text);
  } catch (const json::exception& e) {
    throw InputError(path.string() + ": not valid JSON (" + std::string(e.what()).substr(0, 120) + ")");
  }
  if (!j.is_object() || j.value("schema", json()) != "hybridprof.results-folder" || !j.contains("matrix") ||
      !j["matrix"].is_string() || !j.contains("cells_hash") || !j["cells_hash"].is_string() || !j.contains("cells") ||
      !j["cells"].is_number_unsigned())
    throw InputError(path.string() + ": not a hybridprof results-folder file (schema, matrix, cells, cells_hash)");
  return j;
}

std::string identity_text(const json& id) {
  return "'" + id["matrix"].get<std::string>() + "' (" + std::to_string(id["cells"].get<std::uint64_t>()) + " cells, " +
         id["cells_hash"].get<std::string>() + ")";
}

// Throws when `dir` records another matrix than `want`.
void check_folder_matrix(const fs::path& dir, const json& have, const json& want, const std::string& hint) {
  if (have.is_null()) return;
  if (have["matrix"] != want["matrix"] || have["cells_hash"] != want["cells_hash"]) {
    throw InputError(dir.string() + ": holds the results of matrix " + identity_text(have) + ", not of " +
                     identity_text(want) + hint);
  }
  // Folders written before runs had rounds measured one round.
  const json rounds_have = have.value("rounds", json(1)), rounds_want = want.value("rounds", json(1));
  if (rounds_have != rounds_want) {
    throw InputError(dir.string() + ": holds matrix " + identity_text(have) + " measured in " + rounds_have.dump() +
                     " round(s), not " + rounds_want.dump() + hint);
  }
}

// The build and driver that measured a result line, for telling a stale cell.
std::string measured_by(const json& line) {
  const json* env = nullptr;
  if (line.contains("result") && line["result"].is_object() && line["result"].contains("environment"))
    env = &line["result"]["environment"];
  if (!env || !env->is_object()) return "?";
  const json& dev = env->value("device", json::object());
  return "commit " + env->value("git_commit", std::string("?")) + ", " + dev.value("name", std::string("?")) + " / " +
         dev.value("driver_info", std::string("?"));
}

Camera camera_for(const Scenario& s, const Scene& scene) {
  const float aspect = float(s.frame.width) / float(s.frame.height);
  Camera cam = scene.has_camera ? scene.camera : auto_frame(scene, aspect);
  if (s.camera_position) cam.position = *s.camera_position;
  if (s.camera_target) cam.target = *s.camera_target;
  if (s.camera_fov_deg) cam.vfov_deg = *s.camera_fov_deg;
  return cam;
}

std::string format_double(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.4g", v);
  return buf;
}

std::string eta(double seconds) {
  char buf[32];
  if (seconds < 60)
    std::snprintf(buf, sizeof(buf), "%.0fs", seconds);
  else
    std::snprintf(buf, sizeof(buf), "%dm%02ds", int(seconds) / 60, int(seconds) % 60);
  return buf;
}

// Appends one line and makes it durable before the next cell starts.
void append_line(const fs::path& path, const std::string& line) {
  FILE* f = std::fopen(path.c_str(), "ab");
  if (!f) throw InputError(path.string() + ": cannot open for appending");
  const bool ok = std::fwrite(line.data(), 1, line.size(), f) == line.size() && std::fputc('\n', f) != EOF &&
                  std::fflush(f) == 0 && ::fsync(::fileno(f)) == 0;
  std::fclose(f);
  if (!ok) throw InputError(path.string() + ": write failed");
}

// The cache folder of reference images: $HP_REFERENCE_CACHE, else OUT/references.
fs::path reference_cache(const fs::path& out) {
  const char* env = std::getenv("HP_REFERENCE_CACHE");
  return env && *env ? fs::path(env) : out / "references";
}

// Renders `s.error_frames` accumulated frames, compares them with the (cached) CPU reference of the
// untransformed scene and writes the reference and an error map into the cell folder.
json measure_error(Frame& frame, const Scenario& s, const Scene& ref_scene, const Camera& ref_camera,
                   const fs::path& out, const fs::path& cell_dir, json& images, const std::string& id) {
  ReferenceSettings rs;
  rs.width = s.frame.width;
  rs.height = s.frame.height;
  rs.shadows = s.frame.rt.shadows;
  rs.reflections = s.frame.rt.reflections;
  rs.reflection_shadows = s.frame.rt.reflection_shadows;
  rs.roughness_threshold = s.frame.rt.roughness_threshold;
  rs.samples = s.reference_samples;
  const std::string ref_id = reference_id(s.scene, ref_scene, ref_camera, rs);
  const fs::path cache = reference_cache(out);
  ReferenceImage ref;
  const bool cached = load_reference(cache.string(), ref_id, rs.width, rs.height, ref);
  if (!cached) {
    ref = render_reference(ref_scene, ref_camera, rs);
    save_reference(cache.string(), ref_id, ref);
  }

  frame.reset_accumulation();
  for (uint32_t i = 0; i < s.error_frames; ++i) frame.render(FrameQueries::none);
  FrameReadback gpu;
  gpu.color = frame.read_color();
  if (s.frame.rt.shadows) gpu.shadow = frame.read_aov(Aov::shadow);
  gpu.normal = frame.read_aov(Aov::normal);
  gpu.depth = frame.read_depth();
  gpu.view = frame.view();
  CompareOptions co;
  co.image.threshold = s.error_threshold;
  co.image.flip = s.error_flip;
  Image4f flip_map;
  json e = compare_with_reference(gpu, ref, WorldTransform{s.world_scale, s.world_translate}, co, &flip_map);
  e["frames"] = s.error_frames;
  e["reference"] = {{"id", ref_id},
                    {"samples", rs.samples},
                    {"cached", cached},
                    {"render_s", cached ? json(nullptr) : json(ref.render_s)},
                    {"rays", cached ? json(nullptr) : json(ref.rays)}};
  write_image((cell_dir / "reference.png").string(), ref.color);
  images["reference"] = "cells/" + id + "/reference.png";
  if (s.error_flip) {
    write_image((cell_dir / "flip.png").string(), flip_map);
    images["flip"] = "cells/" + id + "/flip.png";
  }
  return e;
}

}  // namespace

CellScene prepare_cell_scene(const Scenario& s, const Scene& loaded) {
  CellScene c;
  c.scene = loaded;
  if (s.light_direction) c.scene.light.direction = glm::normalize(*s.light_direction);
  if (s.light_intensity) c.scene.light.intensity = *s.light_intensity;
  c.camera = camera_for(s, c.scene);
  c.reference_camera = c.camera;
  if (s.error) c.reference_scene = c.scene;  // the reference sees the untransformed world
  if (s.world_scale != 1.0 || s.world_translate != glm::dvec3(0.0)) {
    transform_world(c.scene, c.camera, s.world_scale, s.world_translate);
  }
  return c;
}

std::vector<std::string> unmet_expectations(const CellRecord& cell, const json& expect) {
  std::vector<std::string> unmet;
  const json& e = cell.error;
  const auto number = [&](const json::json_pointer& p) -> std::optional<double> {
    if (!e.is_object() || !e.contains(p) || !e[p].is_number()) return std::nullopt;
    return e[p].get<double>();
  };
  const auto check = [&](const char* key, std::optional<double> value, const char* what) {
    if (!expect.contains(key)) return;
    const double bound = expect[key].get<double>();
    if (!value) {
      unmet.push_back(std::string(what) + " was not measured (" + key + ")");
    } else if (!(*value <= bound)) {
      unmet.push_back(std::string(what) + " " + format_double(*value) + " > " + format_double(bound) + " (" + key +
                      ")");
    }
  };
  const auto fraction = [&](const char* num, const char* den) -> std::optional<double> {
    const auto n = number(json::json_pointer(num)), d = number(json::json_pointer(den));
    if (!n || !d) return std::nullopt;
    return *d > 0 ? *n / *d : 0.0;
  };
  check("max_non_finite", number(json::json_pointer("/image/non_finite")), "non-finite pixels");
  check("max_acne_fraction", fraction("/shadow/acne", "/shadow/compared"), "acne fraction");
  check("max_leak_fraction", fraction("/shadow/leaks", "/shadow/compared"), "leak fraction");
  check("max_coverage_mismatch_fraction", fraction("/coverage_mismatch", "/image/pixels"),
        "coverage-mismatch fraction");
  check("max_relmse", number(json::json_pointer("/image/relmse")), "relMSE");
  check("max_depth_rel", number(json::json_pointer("/depth/max_rel")), "largest relative position error");
  return unmet;
}

std::vector<json> read_results(const std::string& out_dir) {
  std::vector<json> out;
  const fs::path path = fs::path(out_dir) / kResults;
  std::error_code ec;
  if (!fs::exists(path, ec)) return out;
  const std::string content = read_input_file(path, "results file");
  for_each_jsonl_line(content, path.string(), "result", [&](json r, const std::string& where) {
    // What resuming and merging rely on; `report` and `gate` check the rest of the line (parse_cell).
    if (!r.is_object() || r.value("schema", json()) != "hybridprof.cell")
      throw InputError(where + ": not a hybridprof cell (field 'schema' is not \"hybridprof.cell\")");
    if (!r.contains("id") || !r["id"].is_string()) throw InputError(where + ": field 'id' missing or not a string");
    if (!r.contains("result") || !r["result"].is_object())
      throw InputError(where + ": field 'result' missing or not an object");
    out.push_back(std::move(r));
  });
  return out;
}


namespace {

// The finished lines of a results folder, by id, and their order in the file.
struct FinishedCells {
  std::map<std::string, json> lines;
  std::vector<std::string> file_order;
};

// Reads OUT for a run of `m`: a folder that records another matrix is refused, and one from before folders
// recorded their matrix must hold only this matrix's cells. A partial last line is cut off so appends stay
// aligned.
FinishedCells read_finished(const RunOptions& o, const std::vector<std::string>& cell_ids, const json& identity) {
  const fs::path out(o.out_dir);
  check_folder_matrix(out, read_folder_identity(out), identity, ": choose another --out");
  const std::set<std::string> ids(cell_ids.begin(), cell_ids.end());
  std::vector<json> lines = read_results(o.out_dir);
  for (const json& r : lines) {
    if (!ids.count(r["id"].get<std::string>())) {
      throw InputError(o.out_dir + ": holds cell " + r["id"].get<std::string>() + " of matrix '" +
                       r.value("matrix", std::string("?")) + "', which is not a cell of " + identity_text(identity) +
                       ": choose another --out");
    }
  }
  FinishedCells done;
  for (json& r : lines) {
    done.file_order.push_back(r["id"].get<std::string>());
    done.lines[done.file_order.back()] = std::move(r);
  }
  const fs::path results = out / kResults;
  if (fs::exists(results)) {
    std::ifstream in(results, std::ios::binary);
    std::string content((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    const size_t last = content.rfind('\n');
    const size_t keep = last == std::string::npos ? 0 : last + 1;
    if (keep != content.size()) fs::resize_file(results, keep);
  }
  return done;
}

// Rewrites OUT/results.jsonl with the finished lines as `done` holds them now, in file order, leaving out
// the cells in `drop`.
void rewrite_results(const RunOptions& o, FinishedCells& done, const std::vector<std::string>& drop = {}) {
  std::string kept;
  for (const std::string& id : done.file_order)
    if (std::find(drop.begin(), drop.end(), id) == drop.end()) kept += done.lines[id].dump() + "\n";
  write_file_atomically(fs::path(o.out_dir) / kResults, kept);
}

// Removes the stale cells' lines (the others kept as they were) and folders.
void remove_stale(const RunOptions& o, FinishedCells& done, const std::vector<std::string>& stale,
                  const std::string& now) {
  std::fprintf(stderr, "hybridprof run: %zu cell(s) in %s were measured by %s, not %s: running them again\n",
               stale.size(), o.out_dir.c_str(), measured_by(done.lines[stale.front()]).c_str(), now.c_str());
  rewrite_results(o, done, stale);
  for (const std::string& id : stale) {
    std::error_code ignore;
    fs::remove_all(fs::path(o.out_dir) / "cells" / id, ignore);
  }
}

// Marks the reused stale cells' lines (every other line kept as it was).
void mark_stale(const RunOptions& o, FinishedCells& done, const std::vector<std::string>& reused,
                const std::string& now) {
  std::fprintf(stderr,
               "hybridprof run: %zu cell(s) in %s were measured by %s, not %s: kept (--reuse-stale) and "
               "marked stale\n",
               reused.size(), o.out_dir.c_str(), measured_by(done.lines[reused.front()]).c_str(), now.c_str());
  for (const std::string& id : reused)
    done.lines[id]["stale"] = {{"measured_by", measured_by(done.lines[id])}, {"reused_by", now}};
  rewrite_results(o, done);
}

// One more frame, traced (the timed frames ran uninstrumented), then the cache simulator: the cell's
// "cache" tables, file names relative to OUT.
json capture_cache(Frame& frame, const Scenario& s, const fs::path& out, const fs::path& cell_dir) {
  CaptureOptions co;
  co.shadows = std::find(s.trace_passes.begin(), s.trace_passes.end(), "shadows") != s.trace_passes.end();
  co.reflections = std::find(s.trace_passes.begin(), s.trace_passes.end(), "reflections") != s.trace_passes.end();
  co.sample_every = s.trace_sample_every;
  co.sample_block = s.trace_sample_block;
  co.tiled_images = s.trace_tiled_images;
  co.final_image = false;  // the cell's images come from the timed frames: only the traced passes run
  const fs::path trace_path = cell_dir / "trace.hptrace";
  CacheAnalysisOptions ao;
  ao.preset = s.cache_preset;
  if (s.trace_scale_model) ao.scale_for_sampling = s.trace_sample_every;  // 1 for a full trace
  ao.heatmap_dir = cell_dir.string();
  // The capture streams each slice into the simulator (and into a trace file only when the scenario
  // keeps one): memory stays bounded by a couple of slices whatever the resolution.
  const trace::TraceHeader header = frame.trace_header(co.tiled_images);
  CacheAnalysis analysis(header, ao);
  std::vector<CapturedPass> captured;
  if (s.trace_keep) {
    trace::TraceWriter writer(trace_path, header);
    trace::TeeSink both(writer, analysis);
    captured = frame.render_captured(co, both);
    writer.finish();
  } else {
    captured = frame.render_captured(co, analysis);
  }
  json cache = analysis.finish();
  for (auto& p : cache["passes"]) {
    for (auto& [k, v] : p["heatmaps"].items()) {
      v = fs::relative(fs::path(v.get<std::string>()), out).string();
    }
    for (const CapturedPass& c : captured) {
      if (c.pass == p["pass"]) {
        p["capture"] = {{"workgroups", c.workgroups},
                        {"sampled_workgroups", c.sampled_workgroups},
                        {"sample_every", s.trace_sample_every},
                        {"sample_block", s.trace_sample_block},
                        {"slices", c.slices},
                        {"reruns", c.reruns}};
      }
    }
  }
  if (s.trace_keep) cache["trace_file"] = fs::relative(trace_path, out).string();
  return cache;
}

// What every cell of a run shares: the device, its environment, the scenes loaded so far.
struct RunContext {
  vk::Context& ctx;
  const Environment& env;
  const fs::path& out;
  std::map<std::string, Scene> scenes;
};

// A cell folder that goes unless kept: only cells with a results line keep files.
struct CellDirGuard {
  fs::path dir;
  bool keep = false;
  CellDirGuard(fs::path d) : dir(std::move(d)) {}
  CellDirGuard(const CellDirGuard&) = delete;
  CellDirGuard& operator=(const CellDirGuard&) = delete;
  ~CellDirGuard() {
    std::error_code e;
    if (!keep) fs::remove_all(dir, e);
  }
};

// A cell's frame kept between its rounds (with the scene it renders, which the frame refers to).
struct LiveFrame {
  std::unique_ptr<CellScene> scene;
  std::unique_ptr<Frame> frame;
  std::uint64_t last_use = 0;
};

LiveFrame build_frame(RunContext& run, const Scenario& s) {
  auto it = run.scenes.find(s.scene_path);
  if (it == run.scenes.end()) {
    try {
      it = run.scenes.emplace(s.scene_path, load_scene(s.scene_path)).first;
    } catch (const InputError& e) {
      throw InputError(s.scene_where + ": " + e.what());
    }
  }
  LiveFrame live;
  live.scene = std::make_unique<CellScene>(prepare_cell_scene(s, it->second));
  live.frame = std::make_unique<Frame>(run.ctx, live.scene->scene, live.scene->camera, s.frame);
  return live;
}

// One round of one cell: its timed frames, the load around them and where the visit came in the round.
struct RoundRecord {
  CellRoundVisit visit;
  Environment env;  ///< as the visit started
  FrameTimings timings;
  QueryOverheadSamples overhead;
  double wall_s = 0.0;
};

json to_json(const std::string& id, const RoundRecord& r) {
  return {{"schema", "hybridprof.round"},
          {"version", 1},
          {"id", id},
          {"visit", r.visit},
          {"result", timing_result_json(r.env, r.timings)},
          {"overhead_samples", {{"with", r.overhead.with_queries}, {"without", r.overhead.without_queries}}},
          {"wall_s", r.wall_s}};
}

// A rounds.jsonl line back (checked: a line that does not read is InputError naming the file and line).
RoundRecord parse_round(const json& line, const std::string& where) {
  const CellRoundVisit visit = parse_round_visit(line.value("visit", json()), where);
  try {
    TimingResult t = parse_timing_result(line.at("result"));
    const json& o = line.at("overhead_samples");
    return RoundRecord{visit, std::move(t.environment), std::move(t.timings),
                       QueryOverheadSamples{o.at("with").get<std::vector<double>>(),
                                            o.at("without").get<std::vector<double>>()},
                       line.at("wall_s").get<double>()};
  } catch (const json::exception& e) {
    throw InputError(where + ": not a round of an interleaved run (" + std::string(e.what()).substr(0, 120) + ")");
  } catch (const InputError& e) {
    throw InputError(where + ": " + e.what());
  }
}

// The frames round `r` of `rounds` times of a cell measuring `frames` in all (the first frames % rounds
// rounds take one more).
std::uint32_t frames_in_round(std::uint32_t frames, std::uint32_t rounds, std::uint32_t r) {
  return frames / rounds + (r < frames % rounds ? 1u : 0u);
}

// Times one round of cell `s` on `live` (built for this visit when `rebuilt`).
RoundRecord measure_round(RunContext& run, const Scenario& s, Frame& frame, CellRoundVisit visit) {
  const auto t0 = std::chrono::steady_clock::now();
  ProfileOptions po;
  // A frame built for the visit warms up as the scenario says; one kept alive re-warms with one frame
  // (the host's caches went to the other cells meanwhile).
  po.warmup = visit.rebuilt ? s.warmup : std::min<std::uint32_t>(s.warmup, 1u);
  po.frames = visit.frames;
  po.measure_query_overhead = s.query_overhead;
  po.measure_overlap = s.overlap;
  po.count_invocations = visit.round == 0 || visit.rebuilt;
  // The environment as the visit starts (its date and the machine's load), and the load once its timed
  // frames are done: a round timed while other work loads the cores says so.
  RoundRecord r{visit, capture_environment(run.env.device), FrameTimings(0, 0, TimingSource::GpuTimestamps), {}, 0.0};
  r.visit.load.start = r.env.load_1min;
  r.timings = profile_frames(frame, po, &r.overhead);
  r.visit.load.end = read_load_1min();
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return r;
}

// The cell's record from its rounds (in round order), with its images, cache tables and error measured on
// `frame`, which has rendered its last round. Images go into OUT/cells/<id>/.
CellRecord finish_cell(RunContext& run, const Matrix& m, size_t i, const std::string& id, LiveFrame& live,
                       std::vector<RoundRecord>& rounds, std::uint64_t seed) {
  const Scenario& s = m.cells[i];
  const auto t0 = std::chrono::steady_clock::now();
  Frame& frame = *live.frame;
  const fs::path cell_dir = run.out / "cells" / id;
  fs::create_directories(cell_dir);
  json images = json::object();
  write_image((cell_dir / "color.png").string(), frame.read_color());
  images["color"] = "cells/" + id + "/color.png";
  if (s.frame.rt.shadows) {
    write_image((cell_dir / "shadow.png").string(), frame.read_aov(Aov::shadow));
    images["shadow"] = "cells/" + id + "/shadow.png";
  }
  if (run.ctx.validation_enabled() && run.ctx.validation_message_count() > 0) {
    throw std::runtime_error("cell " + id + ": validation messages; last: " + run.ctx.last_validation_message());
  }
  std::vector<FrameTimings> timings;
  std::vector<QueryOverheadSamples> overhead;
  CellRounds design{m.rounds, seed, {}};
  double wall_s = 0.0;
  for (RoundRecord& r : rounds) {
    timings.push_back(std::move(r.timings));
    overhead.push_back(std::move(r.overhead));
    design.visits.push_back(r.visit);
    wall_s += r.wall_s;
  }
  FrameTimings pooled = FrameTimings::pool_rounds(timings, overhead);
  TimingSummary summary = pooled.summarize();
  Counters counters = pooled.total_counters();
  CellRecord rec(TimingResult{rounds.front().env, std::move(pooled), std::move(summary), std::move(counters)});
  rec.id = id;
  rec.matrix = m.name;
  rec.name = s.name;
  rec.axes = m.cell_axis_values[i];
  rec.config = s.canonical();
  rec.load_1min = CellLoad{rounds.front().visit.load.start, rounds.back().visit.load.end};
  rec.rounds = design;
  rec.triangles = triangle_count(live.scene->scene);
  if (const RtGeometry* g = frame.rt_geometry()) {
    const bvh::BvhStats st = bvh::bvh_stats(g->bvh);
    rec.bvh = CellBvh{g->build_ms, st.nodes, st.leaves, st.max_depth, st.sah_cost};
  }
  if (const AccelStructure* as = frame.accel_structure()) {
    const AsBuildStats& a = as->stats();
    rec.accel = CellAccel{to_string(s.frame.rt.traversal),
                          to_string(as->order()),
                          to_string(as->layout()),
                          a.blas_count,
                          a.instances,
                          a.compacted,
                          a.build_ms,
                          a.build_timed_on_device,
                          a.triangles,
                          a.blas_bytes,
                          a.tlas_bytes,
                          a.scratch_bytes};
  }
  if (!s.trace_passes.empty()) rec.cache = capture_cache(frame, s, run.out, cell_dir);
  if (s.error) {
    rec.error = measure_error(frame, s, live.scene->reference_scene, live.scene->reference_camera, run.out, cell_dir,
                              images, id);
  }
  rec.report = m.report;
  if (m.expect.is_object() && m.cell_axis_values[i].contains("case")) {
    const std::string name = m.cell_axis_values[i]["case"].get<std::string>();
    if (m.expect.contains(name)) rec.expect = CellExpect{m.expect[name], unmet_expectations(rec, m.expect[name])};
  }
  for (const auto& [k, v] : images.items()) rec.images[k] = v.get<std::string>();
  rec.wall_s = wall_s + std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return rec;
}

// OUT/rounds.jsonl: the finished rounds of the cells not finished yet, by id and round. Lines of cells
// that are not to run, measured by another build or driver (`now`), or of rounds the matrix does not have
// are dropped (the file is rewritten without them); a partial last line is cut off.
std::map<std::string, std::map<std::uint32_t, RoundRecord>> read_rounds(const fs::path& out,
                                                                        const std::set<std::string>& todo,
                                                                        std::uint32_t rounds, const std::string& now) {
  std::map<std::string, std::map<std::uint32_t, RoundRecord>> done;
  const fs::path path = out / kRoundsFile;
  std::error_code ec;
  if (!fs::exists(path, ec)) return done;
  const std::string content = read_input_file(path, "rounds file");
  std::string kept;
  bool dropped = false;
  const bool partial =
      for_each_jsonl_line(content, path.string(), "round", [&](const json& line, const std::string& where) {
        if (!line.is_object() || line.value("schema", json()) != "hybridprof.round" || !line.contains("id") ||
            !line["id"].is_string())
          throw InputError(where + ": not a hybridprof round (field 'schema' or 'id')");
        const std::string id = line["id"].get<std::string>();
        RoundRecord r = parse_round(line, where);
        if (!todo.count(id) || r.visit.round >= rounds || measured_by(line) != now) {
          dropped = true;
          return;
        }
        kept += line.dump() + "\n";
        done[id].insert_or_assign(r.visit.round, std::move(r));
      });
  if (dropped || partial) write_file_atomically(path, kept);  // a partial last line: an interrupted write
  return done;
}

}  // namespace

std::string unsupported_reason(const vk::Context& ctx, const Scenario& s) {
  const bool traced = s.frame.rt.shadows || s.frame.rt.reflections;
  return traced ? traversal_unsupported(ctx, s.frame.rt.traversal) : "";
}

RunSummary run_matrix(const Matrix& m, const RunOptions& o) {
  RunSummary sum;
  sum.cells = m.cells.size();
  const fs::path out(o.out_dir);
  std::vector<std::string> cell_ids;  // each cell's id, computed once (it hashes the canonical config)
  for (const Scenario& c : m.cells) cell_ids.push_back(c.id());
  const json identity = folder_identity(m.name, cell_ids, m.rounds);
  FinishedCells done = read_finished(o, cell_ids, identity);

  const std::vector<bool> selected = select_cells(m, o.filters);
  std::vector<size_t> shard_cells;
  for (size_t i = 0; i < m.cells.size(); ++i)
    if (o.shard.contains(i) && selected[i]) shard_cells.push_back(i);
  sum.in_shard = shard_cells.size();
  if (shard_cells.empty()) return sum;

  vk::Context ctx({o.device, o.validate, true});
  if (ctx.info().timestamp_valid_bits == 0)
    std::fprintf(stderr, "hybridprof run: %s\n", host_timing_note(false).c_str());
  const Environment env = capture_environment(describe_device(ctx));

  // A cell measured by another build or on another driver is stale: its line and files go, and it runs
  // again (its timings would not be comparable with the others').
  json now_line = {{"result", {{"environment", env}}}};
  const std::string now = measured_by(now_line);
  std::vector<std::string> stale, reused;
  std::vector<size_t> todo;
  json unsupported = json::array();
  for (size_t i : shard_cells) {
    if (const std::string why = unsupported_reason(ctx, m.cells[i]); !why.empty()) {
      unsupported.push_back({{"id", cell_ids[i]},
                             {"name", m.cells[i].name},
                             {"axes", m.cell_axis_values[i]},
                             {"device", ctx.info().name},
                             {"reason", why}});
      sum.unsupported.push_back(cell_ids[i] + " (" + m.cells[i].name + "): " + why);
      continue;
    }
    const auto it = done.lines.find(cell_ids[i]);
    if (it != done.lines.end() && (measured_by(it->second) == now || o.reuse_stale)) {
      ++sum.already_done;
      if (measured_by(it->second) != now && !it->second.contains("stale")) reused.push_back(it->first);
      continue;
    }
    if (it != done.lines.end()) stale.push_back(it->first);
    todo.push_back(i);
  }
  if (!stale.empty()) remove_stale(o, done, stale, now);
  sum.stale = stale.size();
  if (!reused.empty()) mark_stale(o, done, reused, now);
  sum.stale_reused = reused.size();
  // The cells this device cannot run, for the report; a device that can run them all leaves no list.
  if (!unsupported.empty() && fs::exists(out)) {
    write_json_atomically(out / kUnsupportedFile, unsupported);
  } else if (unsupported.empty()) {
    std::error_code rm;
    fs::remove(out / kUnsupportedFile, rm);
  }
  if (todo.empty()) return sum;
  // Created once there is work and a device for it: a failed start leaves no empty folder behind.
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) throw InputError(o.out_dir + ": cannot create the output folder: " + ec.message());
  write_json_atomically(out / kFolderFile, identity);
  if (!unsupported.empty()) write_json_atomically(out / kUnsupportedFile, unsupported);
  RunContext run{ctx, env, out, {}};
  const bool tty = o.progress && ::isatty(::fileno(stderr));
  const bool log_lines = o.progress && !tty;  // a CI log or a pipe: one plain line per visit
  const auto t_start = std::chrono::steady_clock::now();
  // Interleaved rounds: every round visits the cells still to run in a fresh shuffled order (seeded by the
  // matrix's name and the round) and times frames/rounds of each cell's frames, so a drift of the machine
  // reaches every cell alike. Each finished round is a line of OUT/rounds.jsonl: an interrupted run loses
  // no finished round. A cell's frame stays alive between rounds while at most `live_frames` are; beyond
  // that the least recently used goes and is built again (and warmed up again) at its next visit.
  std::set<std::string> todo_ids;
  for (size_t i : todo) todo_ids.insert(cell_ids[i]);
  std::map<std::string, std::map<std::uint32_t, RoundRecord>> rounds = read_rounds(out, todo_ids, m.rounds, now);
  const std::uint64_t seed = stable_hash64("rounds:" + m.name);
  std::map<size_t, LiveFrame> live;
  std::uint64_t uses = 0;
  size_t visits_total = 0, visits_done = 0;
  for (size_t i : todo) {
    visits_total += m.rounds;
    visits_done += rounds[cell_ids[i]].size();
  }
  const size_t visits_resumed = visits_done;
  std::set<size_t> finished;  // cells with their results line
  // A cell's last round done: its record from the rounds, images and the measurements that need no timing.
  // A cell that fails takes its half-written folder with it.
  const auto finish = [&](size_t i, LiveFrame& frame) {
    const std::string& id = cell_ids[i];
    CellDirGuard cell_guard(out / "cells" / id);
    std::vector<RoundRecord> in_order;
    for (auto& [round, rr] : rounds[id]) in_order.push_back(std::move(rr));
    rounds.erase(id);
    append_line(out / kResults, to_json(finish_cell(run, m, i, id, frame, in_order, seed)).dump());
    cell_guard.keep = true;
    finished.insert(i);
    ++sum.ran;
  };
  for (std::uint32_t r = 0; r < m.rounds && !(o.stop && o.stop->load()); ++r) {
    std::vector<size_t> order;
    for (size_t i : todo)
      if (!finished.count(i) && !rounds[cell_ids[i]].count(r)) order.push_back(i);
    std::mt19937_64 rng(seed + r);
    std::shuffle(order.begin(), order.end(), rng);
    for (size_t k = 0; k < order.size(); ++k) {
      const size_t i = order[k];
      const std::string& id = cell_ids[i];
      const Scenario& s = m.cells[i];
      if (o.stop && o.stop->load()) break;
      if (tty || log_lines) {
        const double el = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
        const size_t ran = visits_done - visits_resumed;
        const std::string left = ran == 0 ? "?" : eta(el / double(ran) * double(visits_total - visits_done));
        std::fprintf(stderr, "%s[round %u/%u, cell %zu/%zu] %s %s  ETA %s%s", tty ? "\r" : "hybridprof run: ", r + 1,
                     m.rounds, k + 1, order.size(), id.c_str(), m.cell_axis_values[i].dump().c_str(), left.c_str(),
                     tty ? "   " : "\n");
        std::fflush(stderr);
      }
      auto it = live.find(i);
      const bool rebuilt = it == live.end();
      if (rebuilt) {
        if (live.size() >= std::max<size_t>(o.live_frames, 1)) {
          auto lru = std::min_element(live.begin(), live.end(), [](const auto& a, const auto& b) {
            return a.second.last_use < b.second.last_use;
          });
          live.erase(lru);
        }
        it = live.emplace(i, build_frame(run, s)).first;
      }
      it->second.last_use = ++uses;
      const CellRoundVisit visit{
          r, std::uint32_t(k), std::uint32_t(order.size()), frames_in_round(s.frames, m.rounds, r), rebuilt, {}};
      RoundRecord rec = measure_round(run, s, *it->second.frame, visit);
      append_line(out / kRoundsFile, to_json(id, rec).dump());
      rounds[id].insert_or_assign(r, std::move(rec));
      ++visits_done;
      if (rounds[id].size() < m.rounds) continue;
      // The cell's last round: its record, images and the measurements that need no timing.
      finish(i, it->second);
      live.erase(it);
    }
  }
  if (o.stop && o.stop->load()) {
    // Interrupted between two visits: every finished round is in the journal, no cell folder is half written.
    sum.interrupted = true;
    for (const auto& [id, done_rounds] : rounds) sum.rounds_journalled += done_rounds.size();
    if (tty) std::fprintf(stderr, "\n");
    return sum;
  }
  // Cells whose every round was already in the journal (interrupted before their record was written).
  for (size_t i : todo) {
    const auto rit = rounds.find(cell_ids[i]);
    if (finished.count(i) || rit == rounds.end() || rit->second.size() < m.rounds) continue;
    LiveFrame fresh = build_frame(run, m.cells[i]);
    fresh.frame->render(FrameQueries::none);
    finish(i, fresh);
  }
  // Every cell of this run has its record: the rounds' journal has served.
  std::error_code rm;
  fs::remove(out / kRoundsFile, rm);
  if (tty) std::fprintf(stderr, "\n");
  return sum;
}

size_t merge_results(const std::string& out_dir, const std::vector<std::string>& shard_dirs) {
  const fs::path out(out_dir);
  // Every shard is read and checked before anything is written: a bad shard leaves the output as it was.
  std::vector<std::pair<std::string, std::vector<json>>> shards;
  for (const std::string& d : shard_dirs) {
    if (!fs::exists(fs::path(d) / kResults)) throw InputError(d + ": no " + std::string(kResults) + " to merge");
    shards.emplace_back(d, read_results(d));
  }
  // Every folder must record one and the same matrix (a folder without a record is taken as it is).
  json identity = read_folder_identity(out);
  for (const std::string& d : shard_dirs) {
    const json id = read_folder_identity(d);
    if (id.is_null()) continue;
    if (identity.is_null())
      identity = id;
    else
      check_folder_matrix(d, id, identity, ": shards of different matrices cannot be merged");
  }
  std::set<std::string> seen;
  for (const json& r : read_results(out_dir)) seen.insert(r["id"].get<std::string>());
  std::error_code ec;
  fs::create_directories(out, ec);
  if (ec) throw InputError(out_dir + ": cannot create the output folder: " + ec.message());
  if (!identity.is_null()) write_json_atomically(out / kFolderFile, identity);
  size_t added = 0;
  for (const auto& [d, lines] : shards) {
    for (const json& r : lines) {
      const std::string id = r["id"].get<std::string>();
      if (!seen.insert(id).second) continue;
      const fs::path cell = fs::path(d) / "cells" / id;
      if (fs::exists(cell)) {
        fs::create_directories(out / "cells");
        fs::copy(cell, out / "cells" / id, fs::copy_options::recursive | fs::copy_options::overwrite_existing);
      }
      append_line(out / kResults, r.dump());
      ++added;
    }
  }
  return added;
}

}  // namespace hp
