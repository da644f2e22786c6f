// The subcommands of `hybridprof`, in thin cmd_*.cpp files (`devices` beside `render`, `merge` beside
// `run`). Each adds itself to the app with its options and a callback; errors are thrown (hp::InputError,
// hp::DeviceError) and turned into exit codes by main.
#pragma once

#include <CLI/CLI.hpp>

namespace hp::cli {

void add_render_command(CLI::App& app);
void add_devices_command(CLI::App& app);
void add_bvh_command(CLI::App& app);
void add_cachesim_command(CLI::App& app);
void add_run_command(CLI::App& app);
void add_trace_command(CLI::App& app);
void add_merge_command(CLI::App& app);
void add_report_command(CLI::App& app);
void add_gate_command(CLI::App& app);

}  // namespace hp::cli
