// The command line as a user meets it: exit codes, one-line errors, nothing half-written.
#include "atomic_file.hpp"
#include "common/scratch_dir.hpp"

#include <gtest/gtest.h>

#include <array>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <regex>
#include <string>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

namespace {

namespace fs = std::filesystem;

struct CmdResult {
  int code = -1;
  std::string output;  // stdout + stderr
};

CmdResult run(const std::string& args, const std::string& env = "") {
  const std::string cmd = env + " " + std::string(HP_CLI_PATH) + " " + args + " 2>&1";
  CmdResult r;
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return r;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), p)) > 0) r.output.append(buf.data(), n);
  const int status = pclose(p);
  r.code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

fs::path temp_dir() { return hp::test::scratch_dir(); }

size_t line_count(const std::string& s) {
  size_t n = 0;
  for (char c : s) n += c == '\n';
  return n;
}

// A bad-input failure as docs/cli.md promises: exit 2 and one line that names `what` (a file, field,
// option or limit).
void expect_bad_input(const CmdResult& r, const std::string& what) {
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_EQ(line_count(r.output), 1u) << r.output;
  EXPECT_NE(r.output.find(what), std::string::npos) << "expected '" << what << "' in: " << r.output;
}

bool have_vulkan() { return run("devices").code == 0; }

// Skips a test without a Vulkan device, or fails it where HP_TESTS_REQUIRE_VULKAN=1 (scripts/test under CI).
#define HP_CLI_REQUIRE_VULKAN()                                                                       \
  do {                                                                                                \
    if (have_vulkan()) break;                                                                         \
    const char* hp_req_ = std::getenv("HP_TESTS_REQUIRE_VULKAN");                                     \
    if (hp_req_ && std::string(hp_req_) == "1") GTEST_FAIL() << "no Vulkan device: `devices` failed"; \
    GTEST_SKIP() << "no Vulkan device";                                                               \
  } while (0)

TEST(Cli, HelpListsSubcommands) {
  CmdResult r = run("--help");
  EXPECT_EQ(r.code, 0);
  EXPECT_NE(r.output.find("render"), std::string::npos);
  EXPECT_NE(r.output.find("devices"), std::string::npos);
  // No arguments at all: the same help, not an error.
  const CmdResult bare = run("");
  EXPECT_EQ(bare.code, 0) << bare.output;
  EXPECT_EQ(bare.output, r.output);
}

// No folder is created that was not asked for, and a missing one is named before any work; a file that is
// not glTF is named as such, not as a JSON parse error.
TEST(Cli, MissingOutputFoldersAndOtherSceneFormatsAreNamed) {
  const fs::path dir = temp_dir();
  const fs::path missing = dir / "no_such_folder";
  expect_bad_input(run("render --scene builtin:cornell --width 32 --height 32 --out " + (missing / "x.png").string()),
                   "the folder " + missing.string() + " does not exist");
  EXPECT_FALSE(fs::exists(missing));
  const CmdResult t = run("render --scene builtin:cornell --width 32 --height 32 --out " + (dir / "x.png").string() +
                          " --timings " + (missing / "t.json").string());
  expect_bad_input(t, "--timings " + (missing / "t.json").string());
  EXPECT_FALSE(fs::exists(dir / "x.png")) << "checked before the frame was rendered";
  { std::ofstream(dir / "box.obj") << "v 0 0 0\n"; }
  expect_bad_input(run("render --scene " + (dir / "box.obj").string() + " --out " + (dir / "y.png").string()),
                   "unsupported format '.obj'");
  fs::remove_all(dir);
}

// Ctrl-C during `run`: the visit under way finishes and is journalled, the run says what it kept and exits
// 130, no cell folder is left without its results line, and the same command resumes and finishes.
TEST(Cli, InterruptedRunSaysWhatItKeptAndResumes) {
  HP_CLI_REQUIRE_VULKAN();
  const fs::path d = temp_dir() / "interrupt";
  fs::remove_all(d);
  fs::create_directories(d);
  const fs::path matrix = d / "m.json", out = d / "out", log = d / "log.txt";
  std::ofstream(matrix) << R"({"name": "interrupt", "rounds": 6,
      "base": {"scene": "builtin:cornell", "resolution": [64, 48], "frames": 6, "warmup": 0},
      "axes": {"seed": [1, 2, 3]}})";
  const pid_t pid = ::fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    FILE* f = std::freopen(log.c_str(), "w", stderr);
    (void)f;
    ::execl(HP_CLI_PATH, HP_CLI_PATH, "run", matrix.c_str(), "--out", out.c_str(), "--quiet", nullptr);
    std::_Exit(127);
  }
  // Once a round is journalled, interrupt.
  const fs::path journal = out / "rounds.jsonl";
  for (int i = 0; i < 600 && !(fs::exists(journal) && fs::file_size(journal) > 0); ++i) ::usleep(100000);
  ::kill(pid, SIGINT);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status)) << "killed by a signal instead of stopping";
  EXPECT_EQ(WEXITSTATUS(status), 130);
  std::ifstream lf(log);
  const std::string text((std::istreambuf_iterator<char>(lf)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("hybridprof run: interrupted: "), std::string::npos) << text;
  EXPECT_NE(text.find("run the same command again to resume"), std::string::npos) << text;
  // Every cell folder has its results line.
  size_t lines = 0;
  {
    std::ifstream rf(out / "results.jsonl");
    for (std::string l; std::getline(rf, l);) {
      ++lines;
      const std::string id = nlohmann::json::parse(l)["id"];
      EXPECT_TRUE(fs::exists(out / "cells" / id));
    }
  }
  size_t folders = 0;
  if (fs::exists(out / "cells"))
    for ([[maybe_unused]] const auto& e : fs::directory_iterator(out / "cells")) ++folders;
  EXPECT_EQ(folders, lines);
  EXPECT_LT(lines, 3u) << "interrupted before the last round";
  EXPECT_TRUE(fs::exists(journal)) << "the finished rounds are kept";
  const CmdResult again = run("run " + matrix.string() + " --out " + out.string() + " --quiet");
  ASSERT_EQ(again.code, 0) << again.output;
  EXPECT_NE(again.output.find(std::to_string(lines) + " already done, " + std::to_string(3 - lines) + " run"),
            std::string::npos)
      << again.output;
  EXPECT_FALSE(fs::exists(journal));
  // Off a terminal (a CI log) progress is one plain line per visit, and --quiet has none.
  EXPECT_EQ(again.output.find("[round"), std::string::npos) << again.output;
  const CmdResult logged = run("run " + matrix.string() + " --out " + (d / "out2").string());
  ASSERT_EQ(logged.code, 0) << logged.output;
  EXPECT_NE(logged.output.find("hybridprof run: [round 1/6, cell 1/3] "), std::string::npos) << logged.output;
  EXPECT_NE(logged.output.find("hybridprof run: [round 6/6, cell 3/3] "), std::string::npos) << logged.output;
  EXPECT_EQ(logged.output.find('\r'), std::string::npos);
  fs::remove_all(d);
}

// A scene path in a scenario resolves against the scenario file's folder, and a scene that does not load is
// one line naming the scenario file and the key.
TEST(Cli, ScenarioScenePathsAreRelativeToTheFile) {
  HP_CLI_REQUIRE_VULKAN();
  const fs::path d = temp_dir() / "scene_paths";
  fs::remove_all(d);
  fs::create_directories(d / "scenarios");
  std::ofstream(d / "scenarios" / "m.json") << R"({"scene": "../scenes/missing.gltf", "resolution": [32, 24]})";
  const CmdResult r =
      run("run " + (d / "scenarios" / "m.json").string() + " --out " + (d / "out").string() + " --quiet");
  expect_bad_input(r, (d / "scenarios" / "m.json").string() + ": scene: ");
  EXPECT_NE(r.output.find((d / "scenes" / "missing.gltf").string()), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(d / "out" / "results.jsonl"));
  fs::remove_all(d);
}

// `devices --json`: the same facts as the text, one JSON array on stdout.
TEST(Cli, DevicesAsJson) {
  HP_CLI_REQUIRE_VULKAN();
  const CmdResult r = run("devices --json");
  ASSERT_EQ(r.code, 0) << r.output;
  const nlohmann::json list = nlohmann::json::parse(r.output);
  ASSERT_TRUE(list.is_array());
  ASSERT_FALSE(list.empty());
  EXPECT_EQ(list[0]["index"], 0);
  EXPECT_EQ(list[0]["traversals"][0], "compute");
  EXPECT_GT(list[0]["subgroup_size"].get<int>(), 0);
  EXPECT_NE(run("devices").output.find(list[0]["name"].get<std::string>()), std::string::npos);
  // How the compute traversal divides and reads its texels, on lavapipe and elsewhere (docs/gpu-passes.md).
  for (const auto& d : list) {
    EXPECT_EQ(d["traversal_division"], d["driver_name"] == "llvmpipe" ? "float" : "double") << d.dump();
    EXPECT_EQ(d["traversal_texel_reads"], d["driver_name"] == "llvmpipe" ? "storage" : "uniform") << d.dump();
  }
}

// `bvh --make-rays N` writes N camera rays into the --rays file and casts them, so the tour's ray commands
// need no file from elsewhere.
TEST(Cli, BvhMakesItsOwnRays) {
  const fs::path d = temp_dir() / "make_rays";
  fs::remove_all(d);
  fs::create_directories(d);
  const CmdResult r = run("bvh --scene builtin:cornell --make-rays 1000 --rays " + (d / "r.bin").string() + " --hits " +
                          (d / "h.bin").string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(fs::file_size(d / "r.bin"), 1000u * 32u);
  EXPECT_EQ(fs::file_size(d / "h.bin"), 1000u * 16u);
  EXPECT_NE(r.output.find("wrote 1000 camera rays"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("rays: 1000 (closest hit, binary32 nodes)"), std::string::npos) << r.output;
  fs::remove_all(d);
}

// `bvh` times its build and its CPU cast: one run each by default, said to be the process's first; with --repeats
// the first apart and the median of the later runs with its 95% interval (their range below 6 later runs).
TEST(Cli, BvhTimesSayWhatTheyMeasured) {
  const fs::path d = temp_dir() / "bvh_repeats";
  fs::remove_all(d);
  fs::create_directories(d);
  const std::string rays = " --make-rays 500 --rays " + (d / "r.bin").string() + " --hits " + (d / "h.bin").string();
  CmdResult r = run("bvh --scene builtin:cornell" + rays);
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("M triangles/s), one build, all threads, "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("M rays/s), one cast, all threads, "), std::string::npos) << r.output;
  EXPECT_EQ(r.output.find("median of"), std::string::npos) << r.output;
  r = run("bvh --scene builtin:cornell --threads 1 --repeats 8" + rays);
  ASSERT_EQ(r.code, 0) << r.output;
  for (const char* step : {"build time: ", "cast time: "}) {
    const std::size_t at = r.output.find(step);
    ASSERT_NE(at, std::string::npos) << r.output;
    const std::string line = r.output.substr(at, r.output.find('\n', at) - at);
    EXPECT_NE(line.find("median of the 7 after the first (95% interval "), std::string::npos) << line;
    EXPECT_NE(line.find("; the first "), std::string::npos) << line;
    EXPECT_NE(line.find("; 1 thread, "), std::string::npos) << line;
  }
  EXPECT_EQ(fs::file_size(d / "h.bin"), 500u * 16u);
  r = run("bvh --scene builtin:cornell --repeats 3");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("median of the 2 after the first (too few for a 95% interval; range "), std::string::npos)
      << r.output;
  EXPECT_EQ(r.output.find("build phases:"), std::string::npos) << r.output;  // cornell is too small to fork
  // A two-thread build of a scene large enough to fork says where its time went; one thread never forks.
  r = run("bvh --scene builtin:pica --threads 2 --repeats 3");
  ASSERT_EQ(r.code, 0) << r.output;
  const std::size_t at = r.output.find("build phases: references ");
  ASSERT_NE(at, std::string::npos) << r.output;
  const std::string line = r.output.substr(at, r.output.find('\n', at) - at);
  EXPECT_NE(line.find(" ms; the top of the tree "), std::string::npos) << line;
  EXPECT_NE(line.find("; below its first fork, side by side, "), std::string::npos) << line;
  EXPECT_NE(line.find("; medians of the 2 after the first"), std::string::npos) << line;
  r = run("bvh --scene builtin:pica --threads 1");
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.output.find("build phases:"), std::string::npos) << r.output;
  expect_bad_input(run("bvh --scene builtin:cornell --repeats 0"), "--repeats");
  expect_bad_input(run("bvh --scene builtin:cornell --repeats 1001"), "--repeats");
  fs::remove_all(d);
}

// A long render says how far it is (off a terminal: a plain line at the end and at most every 5 s); --quiet
// says nothing.
TEST(Cli, RenderShowsProgressUnlessQuiet) {
  HP_CLI_REQUIRE_VULKAN();
  const fs::path d = temp_dir();
  const std::string cmd =
      "render --scene builtin:cornell --width 32 --height 24 --warmup 1 --frames 3 --out " + (d / "p.png").string();
  const CmdResult r = run(cmd);
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("hybridprof render: frames: 4/4, "), std::string::npos) << r.output;
  const CmdResult q = run(cmd + " --quiet");
  ASSERT_EQ(q.code, 0) << q.output;
  EXPECT_EQ(q.output.find("hybridprof render: frames"), std::string::npos) << q.output;
}

// gate --ab says how many of its fresh processes have finished, with an ETA; --quiet says nothing.
TEST(Cli, GateAbShowsProgressUnlessQuiet) {
  HP_CLI_REQUIRE_VULKAN();
  const fs::path d = temp_dir() / "gate_ab";
  fs::create_directories(d);
  const fs::path scenario = d / "tiny.json";
  std::ofstream(scenario) << R"({"name": "tiny", "base": {"scene": "builtin:cornell", "resolution": [32, 24],
    "frames": 2, "warmup": 0, "counters": false, "overlap": false}})";
  const std::string cmd = std::string("gate --ab --baseline-cmd ") + HP_CLI_PATH + " --candidate-cmd " + HP_CLI_PATH +
                          " --scenario " + scenario.string() + " --trials 2";
  const CmdResult r = run(cmd);
  EXPECT_NE(r.code, 1) << r.output;  // identical commands: no regression (inconclusive with 2 processes a side)
  EXPECT_NE(r.output.find("gate --ab: processes: 4/4, "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(" done, "), std::string::npos) << r.output;
  const CmdResult q = run(cmd + " --quiet");
  EXPECT_NE(q.code, 1) << q.output;
  EXPECT_EQ(q.output.find("gate --ab: processes"), std::string::npos) << q.output;
  fs::remove_all(d);
}

// A trace replay says how far each pass is, in records out of the file's count; --quiet says nothing.
TEST(Cli, CachesimShowsReplayProgressUnlessQuiet) {
  HP_CLI_REQUIRE_VULKAN();
  const fs::path d = temp_dir();
  const fs::path trace = d / "t.hptrace";
  CmdResult r =
      run("trace --scene builtin:cornell --width 32 --height 24 --passes shadows --quiet --out " + trace.string());
  ASSERT_EQ(r.code, 0) << r.output;
  r = run("cachesim " + trace.string());
  ASSERT_EQ(r.code, 0) << r.output;
  std::smatch m;
  ASSERT_TRUE(std::regex_search(r.output, m, std::regex("hybridprof cachesim: shadows records: ([0-9]+)/([0-9]+), ")))
      << r.output;
  EXPECT_EQ(m[1].str(), m[2].str());
  EXPECT_GT(std::stoull(m[1].str()), 0u);
  const CmdResult q = run("cachesim " + trace.string() + " --quiet");
  ASSERT_EQ(q.code, 0) << q.output;
  EXPECT_EQ(q.output.find("hybridprof cachesim:"), std::string::npos) << q.output;
  EXPECT_NE(q.output.find("pass 'shadows'"), std::string::npos) << q.output;
}

// A trace that the disk cannot hold stops as soon as its projection says so, with the projection in a
// one-line error, and leaves nothing behind: an 8 MB tmpfs in a private mount namespace, where the shadow
// pass of pica at 640x360 takes about 11 MB (trace format 2). Skipped where such a mount cannot be made (not root, no
// unshare).
TEST(Cli, TraceRefusesWhatTheDiskCannotHold) {
  HP_CLI_REQUIRE_VULKAN();
  const fs::path d = temp_dir() / "small_disk";
  fs::create_directories(d);
  const std::string mount = "mount -t tmpfs -o size=8m hp_small_disk " + d.string();
  if (std::system(("unshare -m sh -c '" + mount + "' >/dev/null 2>&1").c_str()) != 0) {
    GTEST_SKIP() << "cannot mount a tmpfs in a private mount namespace here";
  }
  const std::string on_small_disk = "unshare -m sh -c '" + mount + " && exec \"$0\" \"$@\"'";
  // 32 MiB: four parts of 524 K records, above the densest row of this pass (284 K records), so that the
  // disk is the only limit the capture meets (a part too small for one row is an error of its own, which
  // the device can reach before the writer's first progress call projects the file).
  const std::string args =
      "trace --scene builtin:pica --width 640 --height 360 --passes shadows --trace-buffer-mib 32 "
      "--out " +
      (d / "t.hptrace").string();
  CmdResult r = run(args + " --quiet", on_small_disk);
  expect_bad_input(r, "--out " + (d / "t.hptrace").string() + ": the shadows pass projects to about");
  EXPECT_NE(r.output.find("free; sample workgroups (--sample-every)"), std::string::npos) << r.output;
  // The projection is said before most of the file is written, and the tmpfs holds nothing afterwards
  // (listed from inside the namespace, where it lives).
  const std::string then_list =
      "unshare -m sh -c '" + mount + " && { \"$0\" \"$@\"; rc=$?; echo left: $(ls -A " + d.string() + "); exit $rc; }'";
  r = run(args, then_list);
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("hybridprof trace: shadows: about "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(" free in " + d.string()), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("\nleft:\n"), std::string::npos) << r.output;
  fs::remove_all(d);
}

// OpenImageIO is loaded only when an image is written: a command that writes none does not need it, and
// one that does names the module it could not load, exits non-zero and leaves no image behind.
TEST(Cli, ImagesLoadTheImageModuleOnlyWhenWritten) {
  HP_CLI_REQUIRE_VULKAN();
  const fs::path d = temp_dir();
  const std::string env = "HP_IMAGE_MODULE=" + (d / "missing.so").string();
  CmdResult r = run("trace --scene builtin:cornell --width 32 --height 24 --passes shadows --quiet --out " +
                        (d / "t.hptrace").string(),
                    env);
  EXPECT_EQ(r.code, 0) << r.output;
  r = run("render --scene builtin:cornell --width 32 --height 24 --quiet --out " + (d / "c.png").string(), env);
  EXPECT_NE(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("cannot load the image module " + (d / "missing.so").string()), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(d / "c.png"));
  for (const auto& e : fs::directory_iterator(d)) EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos);
}

TEST(Cli, RenderWritesPngAndAov) {
  HP_CLI_REQUIRE_VULKAN();
  const fs::path d = temp_dir();
  CmdResult r = run("render --scene builtin:cornell --width 96 --height 64 --out " + (d / "c.png").string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(d / "c.png"));
  EXPECT_GT(fs::file_size(d / "c.png"), 500u);
  r = run("render --scene builtin:cornell --width 96 --height 64 --aov depth --out " + (d / "z.exr").string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(d / "z.exr"));
  // No temporary files left beside the outputs.
  for (const auto& e : fs::directory_iterator(d))
    EXPECT_EQ(e.path().filename().string().find(".tmp"), std::string::npos);
  fs::remove_all(d);
}

TEST(Cli, HostTimingSaysSoAndLabelsTheTimes) {
  HP_CLI_REQUIRE_VULKAN();
  const fs::path d = temp_dir();
  CmdResult r = run("render --scene builtin:cornell --width 32 --height 24 --frames 2 --host-timing --out " +
                    (d / "c.png").string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("hybridprof: passes timed on the host as asked (--host-timing)"), std::string::npos)
      << r.output;
  EXPECT_NE(r.output.find("measured frames (cpu-wall)"), std::string::npos) << r.output;
  r = run("render --scene builtin:cornell --width 32 --height 24 --frames 2 --out " + (d / "c.png").string());
  ASSERT_EQ(r.code, 0) << r.output;
  EXPECT_EQ(r.output.find("timed on the host"), std::string::npos) << "lavapipe and GPUs have timestamps";
  fs::remove_all(d);
}

TEST(Cli, CachesimCountsTheL1PerRequestQuarterWaveOrLane) {
  HP_CLI_REQUIRE_VULKAN();
  const fs::path d = temp_dir();
  const fs::path trace = d / "t.hptrace";
  CmdResult r = run("trace --scene builtin:cornell --width 64 --height 48 --passes shadows --out " + trace.string());
  ASSERT_EQ(r.code, 0) << r.output;
  auto replay = [&](const std::string& counting) {
    const fs::path out = d / (counting + ".json");
    const CmdResult c =
        run("cachesim " + trace.string() + " --preset vega56 --l1-hit-counting " + counting + " --out " + out.string());
    EXPECT_EQ(c.code, 0) << c.output;
    EXPECT_NE(c.output.find("lookups and hits counted per " + counting), std::string::npos) << c.output;
    EXPECT_NE(c.output.find("L1 by counting (the L1 row: per " + counting), std::string::npos) << c.output;
    std::ifstream in(out);
    return nlohmann::json::parse(in)["passes"][0];
  };
  const nlohmann::json req = replay("request"), lane = replay("lane"), quarter = replay("quarter_wave");
  EXPECT_EQ(req["l1_hit_counting"], "request");
  EXPECT_EQ(lane["l1_hit_counting"], "lane");
  // All three countings in every output, the same whichever the table uses; misses and the L2 unchanged.
  EXPECT_EQ(req["l1_by_counting"], lane["l1_by_counting"]);
  EXPECT_EQ(req["l1_by_counting"], quarter["l1_by_counting"]);
  EXPECT_EQ(req["l2"], lane["l2"]);
  EXPECT_EQ(req["l1"]["misses"], lane["l1"]["misses"]);
  EXPECT_EQ(req["l1"]["requests"], req["l1_by_counting"]["request"]["lookups"]);
  EXPECT_EQ(lane["l1"]["requests"], req["l1_by_counting"]["lane"]["lookups"]);
  EXPECT_EQ(lane["l1"]["hits"], req["l1_by_counting"]["lane"]["hits"]);
  EXPECT_EQ(quarter["l1"]["hits"], req["l1_by_counting"]["quarter_wave"]["hits"]);
  EXPECT_GT(lane["l1"]["hits"].get<uint64_t>(), quarter["l1"]["hits"].get<uint64_t>());
  EXPECT_GT(quarter["l1"]["hits"].get<uint64_t>(), req["l1"]["hits"].get<uint64_t>());
  ASSERT_FALSE(req["buffers"].empty());
  const nlohmann::json& b = req["buffers"][0];
  EXPECT_EQ(b["l1_by_counting"]["request"]["lookups"], b["l1_requests"]);
  EXPECT_EQ(b["l1_by_counting"]["lane"]["misses"], b["l1_misses"]);
  r = run("cachesim " + trace.string() + " --l1-hit-counting lanes");
  expect_bad_input(r, "--l1-hit-counting: 'lanes' is not request, quarter_wave or lane");
  std::ofstream(d / "t.din") << "r 0 4\n";
  r = run("cachesim --din " + (d / "t.din").string() + " --l1-hit-counting lane");
  expect_bad_input(r, "--din excludes --l1-hit-counting");
  fs::remove_all(d);
}

TEST(Cli, CachesimExportsOneComputeUnitOrNamesTheLimitAndWritesNothing) {
  HP_CLI_REQUIRE_VULKAN();
  const fs::path d = temp_dir();
  const fs::path trace = d / "t.hptrace", din = d / "cu.din";
  CmdResult r = run("trace --scene builtin:cornell --width 64 --height 48 --out " + trace.string());
  ASSERT_EQ(r.code, 0) << r.output;
  // Progress per pass: rows done and what the file holds so far.
  EXPECT_NE(r.output.find("hybridprof trace: shadows rows: 6/6, "), std::string::npos) << r.output;
  EXPECT_NE(r.output.find(" M records ("), std::string::npos) << r.output;
  r = run("cachesim " + trace.string() + " --preset vega56 --export-din " + din.string() + " --export-cu 56");
  expect_bad_input(r, "compute unit 56 does not exist (preset 'vega56' has 56)");
  EXPECT_FALSE(fs::exists(din));
  EXPECT_FALSE(hp::atomic_temporary_exists(din));
  // A good export: the file has exactly the lines the command reports.
  r = run("cachesim " + trace.string() + " --preset vega56 --export-din " + din.string() + " --export-cu 0");
  ASSERT_EQ(r.code, 0) << r.output;
  const size_t at = r.output.find("exported ");
  ASSERT_NE(at, std::string::npos) << r.output;
  const unsigned long reported = std::stoul(r.output.substr(at + 9));
  std::ifstream in(din);
  std::string line;
  unsigned long lines = 0;
  while (std::getline(in, line)) ++lines;
  EXPECT_EQ(lines, reported);
  EXPECT_GT(lines, 0u);
  EXPECT_FALSE(hp::atomic_temporary_exists(din));
  // The sort's dispatches are traced passes too: `trace` can export one (checked before the capture).
  r = run(
      "trace --scene builtin:cornell --width 32 --height 24 --reflection-path compact --sort octant --passes reflections "
      "--out " +
      trace.string() + " --export-din " + (d / "sort.din").string() + " --din-pass sort_scatter_0");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("pass sort_scatter_0"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(d / "sort.din"));
  fs::remove_all(d);
}

// bvh --gpu: the rays of a file through the passes' traversal on the device, checked ray by ray against the
// reference (random rays, axis-aligned ones with signed zeros, a NaN direction).
TEST(Cli, BvhGpuCastsTheRaysAndAgreesWithTheReference) {
  HP_CLI_REQUIRE_VULKAN();
  const fs::path dir = temp_dir();
  const fs::path rays = dir / "rays.bin";
  {
    std::ofstream f(rays, std::ios::binary);
    uint32_t state = 7;
    auto next = [&state] {
      state = state * 1664525u + 1013904223u;
      return float(state >> 8) / float(1u << 24);
    };
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int i = 0; i < 1000; ++i) {
      float r[8] = {next() * 2 - 1, next() * 2 - 1, next() * 2 - 1, 0.0f,
                    next() - 0.5f,  next() - 0.5f,  next() - 0.5f,  1e30f};
      if (i % 10 == 1) r[4] = r[5] = 0.0f;         // along z
      if (i % 10 == 2) r[4] = -0.0f, r[6] = 0.0f;  // along y, signed zeros
      if (i == 3) r[5] = nan;                      // never hits
      f.write(reinterpret_cast<const char*>(r), sizeof(r));
    }
  }
  // The driver's traversals write their own hits to --hits (same format), checked by agreement.
  const bool driver = run("devices").output.find("ray-query, pipeline") != std::string::npos;
  for (const char* traversal : {"ray-query", "pipeline"}) {
    if (!driver) break;
    const fs::path hits = dir / (std::string(traversal) + ".bin");
    const CmdResult r = run("bvh --scene builtin:cornell --rays " + rays.string() + " --hits " + hits.string() +
                            " --gpu --validate --as-order morton --traversal " + traversal);
    EXPECT_EQ(r.code, 0) << traversal << "\n" << r.output;
    EXPECT_NE(r.output.find(std::string(traversal) + " vs reference: 1000 of 1000 rays agree"), std::string::npos)
        << r.output;
    EXPECT_EQ(fs::file_size(hits), 1000u * 16u) << "one hit record (int32 prim, float32 t u v) per ray";
  }
  for (const char* extra : {"--validate", "--any-hit --geometry soup", "--granularity object",
                            "--node-layout wide4 --validate", "--node-layout wide4 --any-hit --granularity object"}) {
    const CmdResult r = run("bvh --scene builtin:cornell --rays " + rays.string() + " --hits " +
                            (dir / "hits.bin").string() + " --gpu " + extra);
    EXPECT_EQ(r.code, 0) << extra << "\n" << r.output;
    EXPECT_NE(r.output.find("gpu vs reference: 1000 of 1000 rays equal"), std::string::npos) << extra << "\n"
                                                                                             << r.output;
    EXPECT_NE(r.output.find("by timestamps"), std::string::npos) << extra << "\n" << r.output;
    EXPECT_NE(r.output.find("median of 3 after an untimed first (too few for a 95% interval; range "),
              std::string::npos)
        << extra << "\n"
        << r.output;
  }
  // --repeats N times N - 1 GPU casts after the untimed one, enough for the median's 95% interval from 7 on.
  const CmdResult r = run("bvh --scene builtin:cornell --rays " + rays.string() + " --hits " +
                          (dir / "hits.bin").string() + " --gpu --repeats 8");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("median of 7 after an untimed first (95% interval "), std::string::npos) << r.output;
  fs::remove_all(dir);
}

TEST(Cli, NodeLayoutsAreChecked) {
  expect_bad_input(run("bvh --scene builtin:cornell --node-layout wide8"), "--node-layout");
  expect_bad_input(run("bvh --scene builtin:cornell --node-layout wide4 --leaf-size 16"),
                   "bvh: --node-layout wide4 holds leaves of at most 15 primitives: --leaf-size 16");
  expect_bad_input(
      run("render --scene builtin:cornell --node-layout wide4 --traversal ray-query --out /tmp/hp_never.png"),
      "--node-layout wide4 applies to --traversal compute only");
  expect_bad_input(run("render --scene builtin:cornell --node-layout binary --out /tmp/hp_never.png"),
                   "--node-layout binary: unknown BVH node layout (choose binary32 or wide4)");
  EXPECT_FALSE(fs::exists("/tmp/hp_never.png"));
}

TEST(Cli, BvhGpuOptionsNeedGpu) {
  const CmdResult r = run("bvh --scene builtin:cornell --geometry soup");
  expect_bad_input(r, "--gpu");
  expect_bad_input(run("bvh --scene builtin:cornell --traversal ray-query"), "--gpu");
}

TEST(Cli, TraversalOptionsAreNamed) {
  expect_bad_input(run("render --scene builtin:cornell --traversal rtx --out /tmp/hp_never.png"),
                   "--traversal rtx: unknown traversal (choose compute, ray-query or pipeline)");
  expect_bad_input(run("render --scene builtin:cornell --as-order morton --out /tmp/hp_never.png"),
                   "--as-order/--as-layout/--as-compaction apply to --traversal ray-query or pipeline only");
  expect_bad_input(run("trace --scene builtin:cornell --traversal pipeline --out /tmp/hp_never.hptrace"),
                   "--traversal pipeline: the ray-generation shaders have no instrumented variant");
  EXPECT_FALSE(fs::exists("/tmp/hp_never.png"));
  EXPECT_FALSE(fs::exists("/tmp/hp_never.hptrace"));
}

TEST(Cli, CpuReferenceNeedsNoDevice) {
  const fs::path d = temp_dir();
  const fs::path out = d / "ref.exr";
  // No Vulkan ICD at all: the CPU reference still renders.
  CmdResult r = run("render --scene builtin:cornell --width 48 --height 36 --cpu-reference 4 --out " + out.string(),
                    "VK_ICD_FILENAMES=/nonexistent.json VK_DRIVER_FILES=/nonexistent.json");
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("CPU reference 48x36"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(out));
  r = run("render --scene builtin:cornell --width 48 --height 36 --cpu-reference 4 --aov depth --out " +
          (d / "x.png").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_EQ(line_count(r.output), 1u) << r.output;
  EXPECT_NE(r.output.find("--aov must be color or shadow"), std::string::npos);
  EXPECT_FALSE(fs::exists(d / "x.png"));
  fs::remove_all(d);
}

TEST(Cli, BadSceneIsOneLineExit2) {
  CmdResult r = run("render --scene /nonexistent/scene.gltf --out /tmp/never.png");
  expect_bad_input(r, "/nonexistent/scene.gltf");
}

TEST(Cli, UnknownBuiltinIsOneLineExit2) {
  CmdResult r = run("render --scene builtin:nope --out /tmp/never.png");
  expect_bad_input(r, "builtin:nope");
  EXPECT_NE(r.output.find("builtin:pica"), std::string::npos) << "the known ones are listed: " << r.output;
}

TEST(Cli, AbsurdResolutionNamesTheLimitAndWritesNothing) {
  const fs::path d = temp_dir();
  const fs::path out = d / "huge.png";
  CmdResult r = run("render --scene builtin:cornell --width 100000 --height 10 --out " + out.string());
  expect_bad_input(r, "limit");
  EXPECT_FALSE(fs::exists(out));
  r = run("render --scene builtin:cornell --width 0 --height 10 --out " + out.string());
  expect_bad_input(r, "0x10");
  EXPECT_FALSE(fs::exists(out));
  fs::remove_all(d);
}

TEST(Cli, UnknownAovAndBadVectorAreExit2) {
  CmdResult r = run("render --scene builtin:cornell --aov bogus --out /tmp/never.png");
  expect_bad_input(r, "--aov");
  r = run("render --scene builtin:cornell --light-dir 1,nan,0 --out /tmp/never.png");
  expect_bad_input(r, "--light-dir");
  r = run("render --bogus-option");
  expect_bad_input(r, "--bogus-option");
  r = run("render --width");  // an option without its value
  expect_bad_input(r, "--width");
}

// Audit finds (2026-11-30): outputs were checked only when written, after the work, with other outputs
// already on disk; `--timings /dev/null` renamed a file over the device node (as root); NaN passed the
// range checks; options of one mode were silently ignored in the other.
TEST(Cli, OutputsAndOptionsAreCheckedBeforeAnyWork) {
  const fs::path d = temp_dir();
  std::ofstream(d / "afile") << "x";
  const std::string under_file = (d / "afile" / "t.json").string();
  CmdResult r = run("render --scene builtin:cornell --width 32 --height 24 --timings " + under_file + " --out " +
                    (d / "f.png").string());
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_EQ(line_count(r.output), 1u) << r.output;
  EXPECT_NE(r.output.find("--timings " + under_file + ": " + (d / "afile").string() + " is not a folder"),
            std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(d / "f.png")) << "the image was written before the bad --timings path was noticed";
  // A special file is never replaced (a FIFO here; /dev/null in the audit).
  const fs::path fifo = d / "fifo";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  r = run("render --scene builtin:cornell --width 32 --height 24 --timeline " + fifo.string() + " --out " +
          (d / "f.png").string());
  expect_bad_input(r, "is not a regular file");
  EXPECT_TRUE(fs::is_fifo(fifo));
  for (const char* bad : {"--fov nan", "--roughness-threshold nan"}) {
    r = run(std::string("render --scene builtin:cornell ") + bad + " --out " + (d / "f.png").string());
    EXPECT_EQ(r.code, 2) << bad << ": " << r.output;
    EXPECT_NE(r.output.find("not a finite number"), std::string::npos) << r.output;
  }
  r = run("render --scene builtin:cornell --cpu-reference 4 --timings t.json --out " + (d / "f.png").string());
  expect_bad_input(r, "--timings excludes --cpu-reference");
  // trace: a bad --image, an export of a pass that is not traced, an absurd frame count: no trace file.
  const std::string trace = (d / "t.hptrace").string();
  for (const std::string& bad :
       {std::string("--image x.jpg"), std::string("--passes shadows --export-din d.din --din-pass reflections"),
        std::string("--frames-before 4294967295"), std::string("--preset h100"),
        // the compaction path traces passes named compact and consume
        std::string("--reflection-path compact --passes reflections --export-din d.din --din-pass reflections")}) {
    r = run("trace --scene builtin:cornell --width 32 --height 24 --out " + trace + " " + bad);
    EXPECT_EQ(r.code, 2) << bad << ": " << r.output;
    EXPECT_EQ(line_count(r.output), 1u) << r.output;
    EXPECT_FALSE(fs::exists(trace)) << bad;
  }
  // cachesim: trace-file options with a Dinero replay, and the reverse, are errors.
  std::ofstream(d / "t.din") << "r 0 4\n";
  r = run("cachesim --din " + (d / "t.din").string() + " --preset h100");
  expect_bad_input(r, "--din excludes --preset");
  r = run("cachesim " + trace + " --l1 8k:64:4");  // (the trace file does not exist: the option is what fails)
  expect_bad_input(r, "excludes --l1");
  // bvh: a bad --hits path is noticed before the triangles are exported.
  r = run("bvh --scene builtin:cornell --export-triangles " + (d / "tris.bin").string() + " --rays " +
          (d / "t.din").string() + " --hits " + (d / "afile" / "h.bin").string());
  expect_bad_input(r, "--hits");
  EXPECT_FALSE(fs::exists(d / "tris.bin"));
  fs::remove_all(d);
}

TEST(Cli, UnknownSubcommandAndOptionsOfAnotherModeAreNamed) {
  const std::pair<const char*, const char*> cases[] = {
      {"bogus", "unknown subcommand 'bogus' (known: render,"},
      {"report /nonexistent --time-unit s", "--time-unit: only with --format gbench"},
      {"gate --baseline a --candidate b --trials 3", "--trials requires --ab"},
  };
  for (const auto& [args, what] : cases) expect_bad_input(run(args), what);
}

TEST(Cli, NoVulkanDeviceIsExit3WithHowToInstall) {
  // An ICD list that names no existing driver: the loader finds no device.
  CmdResult r = run("render --scene builtin:cornell --width 8 --height 8 --out /tmp/never.png",
                    "VK_ICD_FILENAMES=/nonexistent/icd.json VK_DRIVER_FILES=/nonexistent/icd.json");
  EXPECT_EQ(r.code, 3) << r.output;
  EXPECT_EQ(line_count(r.output), 1u) << r.output;
  EXPECT_NE(r.output.find("mesa-vulkan-drivers"), std::string::npos) << r.output;
}

TEST(Cli, UnknownDeviceIsExit3) {
  HP_CLI_REQUIRE_VULKAN();
  CmdResult r = run("render --scene builtin:cornell --device no-such-gpu-xyz --out /tmp/never.png");
  EXPECT_EQ(r.code, 3) << r.output;
  EXPECT_NE(r.output.find("no-such-gpu-xyz"), std::string::npos) << r.output;
}

}  // namespace
