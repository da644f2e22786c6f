#include "study.hpp"

#include "cell_result.hpp"
#include "markdown.hpp"

namespace hp::study {

namespace {

std::string fmt(const char* f, double v) { return format_number(f, v); }
std::string pct(double ratio) { return fmt("%+.1f%%", (ratio - 1.0) * 100.0); }

using StudyRow = Table1Row;
// Study Table 1 (PIX on a Vega 56, reflection pass): L1 hit, L1 miss, L2 hit, L2 miss.
constexpr StudyRow kTable1[] = {
    {"offset + noEBO", true, false, 4873530, 291719, 115552, 217475},
    {"offset + EBO", true, true, 6251450, 258988, 91876, 214712},
    {"nooffset + noEBO", false, false, 5374096, 290892, 134387, 194732},
    {"nooffset + EBO", false, true, 5979267, 241950, 87422, 192207},
};
const StudyRow& study(bool shared, bool indexed) { return table1(shared, indexed); }

}  // namespace

const Table1Row& table1(bool shared, bool indexed) {
  for (const StudyRow& r : kTable1)
    if (r.shared_offset == shared && r.indexed == indexed) return r;
  return kTable1[0];
}

std::string comparison_note(const std::string& leaf, bool have_cache) {
  if (leaf != "geometry" && leaf != "jitter") return "";
  std::string s = "\n**Beside the study (Santoro 2020, Table 1: PIX on a Vega 56, reflection pass).** ";
  s +=
      "\"offset\" is one shared jitter offset per frame (our `jitter: shared`), \"EBO\" an index buffer "
      "(our `geometry: indexed`).\n\n| study configuration | L1 hit | L1 miss | L2 hit | L2 miss | L1 hit rate |\n|---|---|---|---|---|---|\n";
  for (const StudyRow& r : kTable1) {
    s += std::string("| ") + r.label + " | " + md::count(r.l1_hit) + " | " + md::count(r.l1_miss) + " | " +
         md::count(r.l2_hit) + " | " + md::count(r.l2_miss) + " | " +
         fmt("%.1f%%", 100.0 * r.l1_hit / (r.l1_hit + r.l1_miss)) + " |\n";
  }
  s += "\n";
  if (leaf == "geometry") {
    s += "In the study the index buffer raised L1 hits by " +
         pct(study(true, true).l1_hit / study(true, false).l1_hit).substr(1) + " with a shared offset and by " +
         pct(study(false, true).l1_hit / study(false, false).l1_hit).substr(1) + " without one.";
  } else {
    s += "In the study the shared offset changed L1 hits by " +
         pct(study(true, true).l1_hit / study(false, true).l1_hit) + " with an index buffer and by " +
         pct(study(true, false).l1_hit / study(false, false).l1_hit) + " without one.";
  }
  if (have_cache) {
    s += " Our L1-hit changes for the same comparison are in the sentences above (our scene, our cache preset, "
         "one traced frame per cell); the full tables are in each cell's section.\n";
  } else {
    s += " Our L1/L2 columns for this comparison appear beside these once GPU traces are captured: this run's "
         "cells carry no cache tables (add `\"trace\": {\"passes\": [\"reflections\"]}` to the scenario).\n";
  }
  return s;
}

}  // namespace hp::study
