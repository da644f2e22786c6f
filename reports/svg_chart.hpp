// A small SVG chart writer: axes with "nice" ticks (linear or log10), labels, grouped bars with error
// bars, lines with markers and error bars, labelled scatter points with a highlighted Pareto front,
// and a legend. No plotting library is packaged for C++ on Debian 12, and the report needs only
// these three chart kinds. Output is plain SVG 1.1 that browsers and GitHub's markdown viewer render;
// every element carries a class ("bar", "errorbar", "series", "point", "point front", "pareto",
// "point-label", "tick", "legend") so tests and stylesheets can find it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace hp::svg {

/// Bars grouped by category: groups[g].values[s] is series s in group g. low/high (same sizes as
/// values, or empty) draw an error bar from low to high.
struct BarGroup {
  std::string label;
  std::vector<double> values, low, high;
};
struct BarChart {
  std::string title, y_label;
  std::vector<std::string> series;  ///< legend entries, one colour each
  std::vector<BarGroup> groups;
  double y_max = 0;  ///< the y axis covers at least [0, y_max]: charts split from one set share a scale
};

/// One line of a line chart: points (x[i], y[i]); low/high empty or as long as y (error bars).
struct Line {
  std::string name;
  std::vector<double> x, y, low, high;
};
struct LineChart {
  std::string title, x_label, y_label;
  std::vector<Line> lines;
  /// Log10 axes: every value (and error bar) on that axis must then be > 0. A linear y axis starts at 0.
  bool log_x = false, log_y = false;
};

/// One point of a scatter chart.
struct ScatterPoint {
  double x = 0, y = 0;
  std::string label;    ///< drawn beside the point (empty: none)
  std::string tooltip;  ///< the point's <title> (empty: the label and the coordinates)
  bool front = false;   ///< on the Pareto front: drawn highlighted ("point front") and joined by the front line
};
/// Points with labels and tooltips; the front points are joined, in x order, by a step line
/// (class "pareto") that bounds the region they dominate when both axes are minimised.
struct ScatterChart {
  std::string title, x_label, y_label;
  std::vector<ScatterPoint> points;
  bool log_x = false, log_y = false;  ///< log10 axes (values must then be > 0)
};

/// The colour of a bar series or line: each of the frame's passes (gbuffer, shadows, reflections, accumulate,
/// composite, compact, sort, consume) has its own in every chart of every report; any other name the
/// palette's entry for its index.
const char* series_colour(const std::string& name, size_t index);

/// Ticks covering [lo, hi] at a step of 1, 2 or 5 times a power of ten, about `target` of them.
/// The first tick is <= lo and the last >= hi. lo == hi gives a range around that value.
std::vector<double> nice_ticks(double lo, double hi, int target = 5);

/// Ticks for a log10 axis covering [lo, hi] (both > 0): powers of ten, with 2 and 5 times them when
/// the range spans two decades or less, and every n-th power when it spans more than eight.
/// The first tick is <= lo and the last >= hi. Throws std::invalid_argument unless 0 < lo.
std::vector<double> log_ticks(double lo, double hi);

/// A tick label without trailing zeros ("0.5", "12", "1e+06" for large magnitudes).
std::string tick_label(double v);

/// Escapes &, <, >, " for text and attributes.
std::string escape(const std::string& text);

/// The SVG document. Throws std::invalid_argument when sizes disagree or a value is not finite.
std::string render(const BarChart& chart);
std::string render(const LineChart& chart);
std::string render(const ScatterChart& chart);

/// The colour bar of a miss heatmap: the heatmaps' ramp (core/colormap.hpp) from 0 to `max_count` on the
/// heatmaps' log scale (position log(1 + c) / log(1 + max)), with ticks at 0, 1, 10, 100, ... and the maximum,
/// and `title` above it.
std::string render_colour_bar(const std::string& title, std::uint64_t max_count);

}  // namespace hp::svg
