// `hybridprof`: one binary, one subcommand per job. Errors become one line on stderr and an exit code:
// 2 bad input (file, field, option, limit), 3 no usable Vulkan device, 1 internal error.
#include "apps/commands.hpp"
#include "error.hpp"
#include "hp_git_commit.hpp"

#include <cstdio>
#include <exception>
#include <string>

int main(int argc, char** argv) {
  CLI::App app{"hybridprof: where the time and the memory traffic of a hybrid (raster + ray-traced) frame go"};
  app.name("hybridprof");  // the usage line says hybridprof, whatever path it was started by
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string("hybridprof ") + HP_VERSION + " (" + HP_GIT_COMMIT + ")");
  hp::cli::add_render_command(app);
  hp::cli::add_devices_command(app);
  hp::cli::add_run_command(app);
  hp::cli::add_merge_command(app);
  hp::cli::add_report_command(app);
  hp::cli::add_gate_command(app);
#ifdef HP_HAVE_BVH_COMMAND
  hp::cli::add_bvh_command(app);
#endif
#ifdef HP_HAVE_CACHESIM_COMMAND
  hp::cli::add_cachesim_command(app);
  hp::cli::add_trace_command(app);
#endif
  // No arguments: the help, as `--help` prints it (what a first-time user wants), exit 0.
  if (argc == 1) {
    std::printf("%s", app.help().c_str());
    return 0;
  }
  // A first word that is neither an option nor a subcommand: name it (CLI11 would only say that a
  // subcommand is required).
  if (argc > 1 && argv[1][0] != '-') {
    std::string known;
    bool found = false;
    for (const CLI::App* sub : app.get_subcommands({})) {
      known += (known.empty() ? "" : ", ") + sub->get_name();
      found = found || sub->get_name() == argv[1];
    }
    if (!found) {
      std::fprintf(stderr, "hybridprof: error: unknown subcommand '%s' (known: %s)\n", argv[1], known.c_str());
      return 2;
    }
  }
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // --help and --version are "errors" with exit code 0 (CLI11 prints them); bad options are input errors:
    // one line, exit 2.
    if (e.get_exit_code() == 0) return app.exit(e);
    std::string message = e.what();
    for (char& c : message) {
      if (c == '\n') c = ' ';
    }
    std::fprintf(stderr, "hybridprof: error: %s (--help lists the options)\n", message.c_str());
    return 2;
  } catch (const hp::InputError& e) {
    std::fprintf(stderr, "hybridprof: error: %s\n", e.what());
    return 2;
  } catch (const hp::DeviceError& e) {
    std::fprintf(stderr, "hybridprof: error: %s\n", e.what());
    return 3;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hybridprof: internal error: %s\n", e.what());
    return 1;
  }
  return 0;
}
