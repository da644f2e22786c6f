// What the report says beside the study it reproduces (F. Santoro, "Ray Tracing and Rasterization: an
// Hybrid renderer", 2020: Unity + PIX on a Vega 56). The generic sections call these hooks; everything
// specific to the study (its figures, its names for our axes) lives here.
#pragma once

#include <string>

namespace hp::study {

/// The study's Table 1 and what it found for the same comparison, for an axis whose comparison the study
/// also made (leaf "geometry": its EBO / noEBO; leaf "jitter": its shared offset); empty for any other
/// axis. `have_cache`: whether the run's cells carry cache tables to set beside the study's.
std::string comparison_note(const std::string& axis_leaf, bool have_cache);

}  // namespace hp::study
