// What the report says beside the study it reproduces (F. Santoro, "Ray Tracing and Rasterization: an
// Hybrid renderer", 2020: Unity + PIX on a Vega 56). The generic sections call these hooks; everything
// specific to the study (its figures, its names for our axes) lives here.
#pragma once

#include <string>

namespace hp::study {

/// One row of the study's Table 1 (PIX on a Vega 56, reflection pass): "offset" is one shared jitter offset
/// per frame (our `jitter: shared`), "EBO" an index buffer (our `geometry: indexed`).
struct Table1Row {
  const char* label;
  bool shared_offset, indexed;
  double l1_hit, l1_miss, l2_hit, l2_miss;
};
const Table1Row& table1(bool shared_offset, bool indexed);

/// The study's sorting experiment (section 4.2): the compacted path's passes as PIX timed them, and its
/// verdict on the whole: worse than the direct reflection pass.
constexpr double kSortingMs = 24.63, kSortedTraversalMs = 7.90;

/// The study's Table 1 and what it found for the same comparison, for an axis whose comparison the study
/// also made (leaf "geometry": its EBO / noEBO; leaf "jitter": its shared offset); empty for any other
/// axis. `have_cache`: whether the run's cells carry cache tables to set beside the study's.
std::string comparison_note(const std::string& axis_leaf, bool have_cache);

}  // namespace hp::study
