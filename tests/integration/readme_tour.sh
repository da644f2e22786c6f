#!/usr/bin/env bash
# Runs the README's CLI tour exactly as written, so the README and the tool cannot drift apart.
#
# Usage: readme_tour.sh SOURCE_DIR BUILD_DIR [README]
#
# The tour is the fenced block between `<!-- tour:begin -->` and `<!-- tour:end -->` in README.md (or the
# README given). Its lines run, in order, as one bash script under `set -euo pipefail`, from a scratch
# folder laid out like a fresh clone after `scripts/run`: `build` is BUILD_DIR, `scenarios` and `reports`
# are the source tree's. So the first failing command fails the test and names itself, and nothing the tour
# writes lands in the source tree. Exit 77 (skipped) when there is no Vulkan device, unless
# HP_TESTS_REQUIRE_VULKAN=1 (as CI sets it).
#
# The README must also stay a front door: at most 300 lines.
set -euo pipefail
if [ $# -lt 2 ] || [ $# -gt 3 ]; then
  echo "usage: readme_tour.sh SOURCE_DIR BUILD_DIR [README]" >&2
  exit 2
fi
src=$(cd "$1" && pwd)
build=$(cd "$2" && pwd)
readme=${3:-$src/README.md}
max_lines=300

lines=$(wc -l <"$readme")
if [ "$lines" -gt "$max_lines" ]; then
  echo "readme_tour: $readme: $lines lines, more than $max_lines (details belong in docs/)" >&2
  exit 1
fi

# The block between the markers, without its code fences.
tour=$(awk '/<!-- tour:begin -->/ {on = 1; next} /<!-- tour:end -->/ {on = 0} on && !/^```/' "$readme")
if [ -z "$tour" ]; then
  echo "readme_tour: $readme: no tour between <!-- tour:begin --> and <!-- tour:end -->" >&2
  exit 1
fi
if ! grep -q '[^[:space:]]' <<<"$tour"; then
  echo "readme_tour: $readme: the tour is empty" >&2
  exit 1
fi

if ! "$build/apps/hybridprof" devices >/dev/null 2>&1; then
  if [ "${HP_TESTS_REQUIRE_VULKAN:-0}" = 1 ]; then
    echo "readme_tour: no usable Vulkan device, and HP_TESTS_REQUIRE_VULKAN=1" >&2
    exit 1
  fi
  echo "readme_tour: skipped: no usable Vulkan device"
  exit 77
fi

work=$(mktemp -d "${TMPDIR:-/tmp}/hp-tour.XXXXXX")
trap 'rm -rf "$work"' EXIT
ln -s "$build" "$work/build"
ln -s "$src/scenarios" "$work/scenarios"
ln -s "$src/reports" "$work/reports"

# Each command is echoed before it runs (bash's xtrace, one "+ " line per command), so a failure in the
# log names the README line that broke.
printf '%s\n' "set -euo pipefail" "set -x" "$tour" >"$work/tour.sh"
cd "$work"
if ! bash "$work/tour.sh"; then
  echo "readme_tour: a command of the README's tour failed (the last '+' line above)" >&2
  exit 1
fi
echo "readme_tour: every command of the tour ran ($(grep -c '^hybridprof' <<<"$tour") hybridprof commands)"
