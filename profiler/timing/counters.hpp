// Deterministic work counters beside the times. Timings drift by several percent between processes on
// shared machines; these counts (rays cast, BVH nodes visited, triangles tested, compute invocations)
// do not, so two runs of one scenario on one driver must give identical Counters, and a difference is
// a real change in the work done, not noise.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

namespace hp {

// The counter names the renderer fills; other names are allowed (the container is open).
namespace counter {
inline constexpr const char* rays_cast = "rays_cast";
inline constexpr const char* nodes_visited = "nodes_visited";
inline constexpr const char* triangles_tested = "triangles_tested";
inline constexpr const char* compute_invocations = "compute_invocations";
}  // namespace counter

// Named uint64 counters per pass. Ordered maps, so iteration, JSON output and comparison do not
// depend on insertion order.
class Counters {
 public:
  using PassCounters = std::map<std::string, std::uint64_t>;

  // Sets pass/name to value (overwrites).
  void set(const std::string& pass, const std::string& name, std::uint64_t value);
  // Adds value to pass/name (0 when absent). Wraps modulo 2^64 like the GPU's counters.
  void add(const std::string& pass, const std::string& name, std::uint64_t value);
  // Adds every counter of `other` to this one (sum over frames).
  void add(const Counters& other);
  // pass/name, or 0 when absent.
  std::uint64_t get(const std::string& pass, const std::string& name) const;
  // Sum of `name` over all passes.
  std::uint64_t total(const std::string& name) const;

  const std::map<std::string, PassCounters>& passes() const { return passes_; }
  bool empty() const { return passes_.empty(); }

  // Exact equality: the same passes with the same names and values. A counter explicitly set to 0
  // differs from an absent one (a pass that stopped reporting is a change worth seeing).
  bool operator==(const Counters&) const = default;

 private:
  std::map<std::string, PassCounters> passes_;
};

// One line per difference ("shadows/rays_cast: 1024 != 1000", "reflections/nodes_visited: missing
// on the right"), for test and gate messages; empty when a == b.
std::vector<std::string> counter_differences(const Counters& a, const Counters& b);

}  // namespace hp
