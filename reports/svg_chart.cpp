#include "svg_chart.hpp"

#include "colormap.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>

namespace hp::svg {

namespace {

// Colour-blind-safe palette (Okabe & Ito), cycled.
const char* const kPalette[] = {"#0072B2", "#E69F00", "#009E73", "#CC79A7", "#56B4E9", "#D55E00", "#F0E442", "#000000"};
const char* colour(size_t i) { return kPalette[i % (sizeof(kPalette) / sizeof(kPalette[0]))]; }

std::string num(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.2f", v);
  return buf;
}

void check_finite(double v, const char* what) {
  if (!std::isfinite(v)) throw std::invalid_argument(std::string("svg chart: non-finite ") + what);
}

// The plot frame shared by both chart kinds: margins, a title, a y axis with grid lines and labels.
struct Frame {
  double width, height;
  double left = 70, right = 20, top = 40, bottom = 90;
  double y0 = 0, y1 = 1;  // data range of the y axis (the first and last tick; log10 of them on a log axis)
  double x0 = 0, x1 = 1;  // data range of the x axis (line and scatter charts)
  bool log_x = false, log_y = false;

  double plot_w() const { return width - left - right; }
  double plot_h() const { return height - top - bottom; }
  double py(double y) const { return top + plot_h() * (1.0 - ((log_y ? std::log10(y) : y) - y0) / (y1 - y0)); }
  double px(double x) const { return left + plot_w() * ((log_x ? std::log10(x) : x) - x0) / (x1 - x0); }
  void set_x(const std::vector<double>& ticks) {
    x0 = log_x ? std::log10(ticks.front()) : ticks.front();
    x1 = log_x ? std::log10(ticks.back()) : ticks.back();
  }
  void set_y(const std::vector<double>& ticks) {
    y0 = log_y ? std::log10(ticks.front()) : ticks.front();
    y1 = log_y ? std::log10(ticks.back()) : ticks.back();
  }
};

// The ticks of one axis over [lo, hi]: log ticks, or nice ticks (from zero when `from_zero`).
std::vector<double> axis_ticks(bool log, double lo, double hi, bool from_zero) {
  if (log) return log_ticks(lo, hi);
  return nice_ticks(from_zero ? std::min(0.0, lo) : lo, hi);
}

void check_log(bool log, double v, const char* what) {
  if (log && !(v > 0.0)) throw std::invalid_argument(std::string("svg chart: ") + what + " <= 0 on a log axis");
}

std::string x_axis(const Frame& f, const std::vector<double>& ticks, const std::string& label) {
  std::string s = "<g class=\"x-axis\">\n";
  for (double t : ticks) {
    s += "<text class=\"tick\" x=\"" + num(f.px(t)) + "\" y=\"" + num(f.top + f.plot_h() + 16) +
         "\" text-anchor=\"middle\">" + escape(tick_label(t)) + "</text>\n";
  }
  s += "<text class=\"axis-label\" x=\"" + num(f.left + f.plot_w() / 2) + "\" y=\"" + num(f.top + f.plot_h() + 36) +
       "\" text-anchor=\"middle\">" + escape(label) + "</text>\n</g>\n";
  return s;
}

std::string header(const Frame& f, const std::string& title) {
  std::string s = "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n";
  s += "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"" + num(f.width) + "\" height=\"" +
       num(f.height) + "\" viewBox=\"0 0 " + num(f.width) + " " + num(f.height) +
       "\" font-family=\"sans-serif\" font-size=\"12\">\n";
  s += "<rect class=\"background\" x=\"0\" y=\"0\" width=\"" + num(f.width) + "\" height=\"" + num(f.height) +
       "\" fill=\"white\"/>\n";
  s += "<text class=\"title\" x=\"" + num(f.width / 2) + "\" y=\"22\" text-anchor=\"middle\" font-size=\"15\">" +
       escape(title) + "</text>\n";
  return s;
}

std::string y_axis(const Frame& f, const std::vector<double>& ticks, const std::string& label) {
  std::string s = "<g class=\"y-axis\">\n";
  for (double t : ticks) {
    const double y = f.py(t);
    s += "<line class=\"grid\" x1=\"" + num(f.left) + "\" y1=\"" + num(y) + "\" x2=\"" + num(f.left + f.plot_w()) +
         "\" y2=\"" + num(y) + "\" stroke=\"#dddddd\"/>\n";
    s += "<text class=\"tick\" x=\"" + num(f.left - 6) + "\" y=\"" + num(y + 4) + "\" text-anchor=\"end\">" +
         escape(tick_label(t)) + "</text>\n";
  }
  s += "<line class=\"axis\" x1=\"" + num(f.left) + "\" y1=\"" + num(f.top) + "\" x2=\"" + num(f.left) + "\" y2=\"" +
       num(f.top + f.plot_h()) + "\" stroke=\"black\"/>\n";
  s += "<line class=\"axis\" x1=\"" + num(f.left) + "\" y1=\"" + num(f.top + f.plot_h()) + "\" x2=\"" +
       num(f.left + f.plot_w()) + "\" y2=\"" + num(f.top + f.plot_h()) + "\" stroke=\"black\"/>\n";
  // The axis label beside the tick labels (a wide left margin, made for long group labels, leaves it there).
  const double cy = f.top + f.plot_h() / 2, lx = std::max(16.0, f.left - 54);
  s += "<text class=\"axis-label\" x=\"" + num(lx) + "\" y=\"" + num(cy) +
       "\" text-anchor=\"middle\" transform=\"rotate(-90 " + num(lx) + " " + num(cy) + ")\">" + escape(label) +
       "</text>\n";
  return s + "</g>\n";
}

// The legend's entries flow left to right and wrap onto further rows of 18 px; legend_extra_height says how
// much taller than one row it is, so a chart can grow to hold it.
double legend_entry_width(const std::string& name) { return 16 + 7.0 * double(name.size()) + 18; }

double legend_extra_height(double width, double left, const std::vector<std::string>& names) {
  double x = left;
  int rows = names.empty() ? 0 : 1;
  for (const std::string& n : names) {
    if (x > left && x + legend_entry_width(n) > width - 10) ++rows, x = left;
    x += legend_entry_width(n);
  }
  return rows > 1 ? 18.0 * (rows - 1) : 0.0;
}

}  // namespace

const char* series_colour(const std::string& name, size_t index) {
  // The frame's passes in their order, each with a colour of its own in every chart of every report.
  static const char* const kPasses[] = {"gbuffer",   "shadows", "reflections", "accumulate",
                                        "composite", "compact", "sort",        "consume"};
  for (size_t k = 0; k < sizeof(kPasses) / sizeof(kPasses[0]); ++k)
    if (name == kPasses[k]) return colour(k);
  return colour(index);
}

namespace {

std::string legend(const Frame& f, const std::vector<std::string>& names) {
  std::string s = "<g class=\"legend\">\n";
  double x = f.left;
  double y = f.height - 18 - legend_extra_height(f.width, f.left, names);
  for (size_t i = 0; i < names.size(); ++i) {
    if (x > f.left && x + legend_entry_width(names[i]) > f.width - 10) x = f.left, y += 18;
    s += "<rect class=\"legend-swatch\" x=\"" + num(x) + "\" y=\"" + num(y - 10) +
         "\" width=\"12\" height=\"12\" fill=\"" + series_colour(names[i], i) + "\"/>\n";
    s +=
        "<text class=\"legend-label\" x=\"" + num(x + 16) + "\" y=\"" + num(y) + "\">" + escape(names[i]) + "</text>\n";
    x += legend_entry_width(names[i]);
  }
  return s + "</g>\n";
}

std::string error_bar(double x, double y_low, double y_high, double half_width) {
  std::string s = "<g class=\"errorbar\" stroke=\"black\">";
  s += "<line x1=\"" + num(x) + "\" y1=\"" + num(y_low) + "\" x2=\"" + num(x) + "\" y2=\"" + num(y_high) + "\"/>";
  s += "<line x1=\"" + num(x - half_width) + "\" y1=\"" + num(y_low) + "\" x2=\"" + num(x + half_width) + "\" y2=\"" +
       num(y_low) + "\"/>";
  s += "<line x1=\"" + num(x - half_width) + "\" y1=\"" + num(y_high) + "\" x2=\"" + num(x + half_width) + "\" y2=\"" +
       num(y_high) + "\"/>";
  return s + "</g>\n";
}

void check_bars(const std::vector<double>& v, const std::vector<double>& lo, const std::vector<double>& hi, size_t n) {
  if (v.size() != n) throw std::invalid_argument("svg chart: a group or line has the wrong number of values");
  if ((!lo.empty() && lo.size() != n) || lo.size() != hi.size())
    throw std::invalid_argument("svg chart: error bars must be absent or one low and one high per value");
  for (double x : v) check_finite(x, "value");
  for (double x : lo) check_finite(x, "error bar");
  for (double x : hi) check_finite(x, "error bar");
}

}  // namespace

std::vector<double> nice_ticks(double lo, double hi, int target) {
  check_finite(lo, "axis bound");
  check_finite(hi, "axis bound");
  if (lo > hi) std::swap(lo, hi);
  if (hi == lo) {
    const double pad = lo == 0.0 ? 1.0 : std::abs(lo) * 0.1;
    lo -= pad;
    hi += pad;
  }
  const double raw = (hi - lo) / double(std::max(1, target));
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  double step = mag;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * mag >= raw) {
      step = m * mag;
      break;
    }
  }
  std::vector<double> ticks;
  const double first = std::floor(lo / step) * step;
  for (int i = 0;; ++i) {
    double t = first + step * i;
    if (std::abs(t) < step * 1e-9) t = 0.0;  // no "-0" or 1e-17 labels
    ticks.push_back(t);
    if (t >= hi - step * 1e-9) break;
  }
  return ticks;
}

std::vector<double> log_ticks(double lo, double hi) {
  check_finite(lo, "axis bound");
  check_finite(hi, "axis bound");
  if (lo > hi) std::swap(lo, hi);
  if (!(lo > 0.0)) throw std::invalid_argument("svg chart: a log axis needs values > 0");
  int e0 = int(std::floor(std::log10(lo) + 1e-9)), e1 = int(std::ceil(std::log10(hi) - 1e-9));
  if (e1 <= e0) e1 = e0 + 1;
  auto p10 = [](int e) { return std::pow(10.0, double(e)); };
  std::vector<double> ticks;
  if (e1 - e0 <= 2) {
    std::vector<double> all;
    for (int e = e0; e <= e1; ++e)
      for (double m : {1.0, 2.0, 5.0}) all.push_back(m * p10(e));
    size_t first = 0, last = all.size() - 1;
    for (size_t i = 0; i < all.size(); ++i)
      if (all[i] <= lo * (1 + 1e-12)) first = i;
    for (size_t i = all.size(); i-- > 0;)
      if (all[i] >= hi * (1 - 1e-12)) last = i;
    ticks.assign(all.begin() + std::ptrdiff_t(first), all.begin() + std::ptrdiff_t(last) + 1);
  } else {
    const int step = (e1 - e0 + 7) / 8;
    int e = e0;
    for (; e < e1; e += step) ticks.push_back(p10(e));
    ticks.push_back(p10(e));
  }
  return ticks;
}

std::string tick_label(double v) {
  char buf[32];
  if (v != 0.0 && (std::abs(v) >= 1e6 || std::abs(v) < 1e-3))
    std::snprintf(buf, sizeof(buf), "%.3g", v);
  else
    std::snprintf(buf, sizeof(buf), "%.6g", v);
  return buf;
}

std::string escape(const std::string& text) {
  std::string s;
  for (char c : text) {
    switch (c) {
      case '&': s += "&amp;"; break;
      case '<': s += "&lt;"; break;
      case '>': s += "&gt;"; break;
      case '"': s += "&quot;"; break;
      default: s += c;
    }
  }
  return s;
}

std::string render(const BarChart& c) {
  const size_t ns = c.series.size();
  if (ns == 0 || c.groups.empty()) throw std::invalid_argument("svg chart: a bar chart needs series and groups");
  double hi = c.y_max > 0 && std::isfinite(c.y_max) ? c.y_max : 0.0;
  for (const BarGroup& g : c.groups) {
    check_bars(g.values, g.low, g.high, ns);
    for (double v : g.values) hi = std::max(hi, v);
    for (double v : g.high) hi = std::max(hi, v);
  }
  const double slot = std::max(24.0, 14.0 * double(ns) + 16.0);  // width of one group
  // The group labels are rotated by 30 degrees below the axis: the frame makes room for the longest one
  // under the plot (and for the legend under that), and for the first one to the left, so no label is
  // clipped or runs into the legend whatever its length. kCharW: a generous average glyph width at 12 px.
  constexpr double kCharW = 7.0, kCos = 0.8660254, kSin = 0.5;
  size_t longest = 0;
  for (const BarGroup& g : c.groups) longest = std::max(longest, g.label.size());
  const double label_drop = 14 + double(longest) * kCharW * kSin + 12;  // axis to the lowest label pixel
  const double left = std::max(70.0, double(c.groups.front().label.size()) * kCharW * kCos - slot / 2 + 8);
  const double width = std::max({360.0, left + 20 + slot * double(c.groups.size()),
                                 double(c.title.size()) * 8.5 + 40});  // the title (15 px) fits too
  const double extra = legend_extra_height(width, left, c.series);
  Frame f{width, 0};
  f.left = left;
  f.bottom = label_drop + 10 + 18 + extra + 8;  // labels, a gap, the legend's rows
  f.height = f.top + 250 + f.bottom;
  const std::vector<double> ticks = nice_ticks(0.0, hi);  // bars start at zero: lengths compare
  f.y0 = ticks.front();
  f.y1 = ticks.back();
  const double group_w = f.plot_w() / double(c.groups.size());
  const double bar_w = std::min(28.0, (group_w - 10.0) / double(ns));
  std::string s = header(f, c.title) + y_axis(f, ticks, c.y_label);
  for (size_t g = 0; g < c.groups.size(); ++g) {
    const BarGroup& grp = c.groups[g];
    const double gx = f.left + group_w * double(g) + (group_w - bar_w * double(ns)) / 2;
    s += "<g class=\"group\">\n";
    for (size_t i = 0; i < ns; ++i) {
      const double x = gx + bar_w * double(i), y = f.py(grp.values[i]);
      s += "<rect class=\"bar\" x=\"" + num(x) + "\" y=\"" + num(y) + "\" width=\"" + num(bar_w * 0.9) +
           "\" height=\"" + num(f.py(0.0) - y) + "\" fill=\"" + series_colour(c.series[i], i) + "\"><title>" +
           escape(c.series[i] + ": " + tick_label(grp.values[i])) + "</title></rect>\n";
      if (!grp.low.empty()) s += error_bar(x + bar_w * 0.45, f.py(grp.low[i]), f.py(grp.high[i]), bar_w * 0.2);
    }
    const double lx = f.left + group_w * (double(g) + 0.5), ly = f.top + f.plot_h() + 14;
    s += "<text class=\"group-label\" x=\"" + num(lx) + "\" y=\"" + num(ly) +
         "\" text-anchor=\"end\" transform=\"rotate(-30 " + num(lx) + " " + num(ly) + ")\">" + escape(grp.label) +
         "</text>\n</g>\n";
  }
  return s + legend(f, c.series) + "</svg>\n";
}

std::string render(const LineChart& c) {
  if (c.lines.empty()) throw std::invalid_argument("svg chart: a line chart needs lines");
  double xlo = INFINITY, xhi = -INFINITY, ylo = INFINITY, yhi = 0.0;
  for (const Line& l : c.lines) {
    if (l.x.empty()) throw std::invalid_argument("svg chart: line '" + l.name + "' has no points");
    check_bars(l.y, l.low, l.high, l.x.size());
    for (double x : l.x) {
      check_finite(x, "x");
      check_log(c.log_x, x, "x");
      xlo = std::min(xlo, x);
      xhi = std::max(xhi, x);
    }
    for (const auto* v : {&l.y, &l.low, &l.high}) {
      for (double y : *v) {
        check_log(c.log_y, y, "y");
        ylo = std::min(ylo, y);
        yhi = std::max(yhi, y);
      }
    }
  }
  std::vector<std::string> line_names;
  for (const Line& l : c.lines) line_names.push_back(l.name);
  const double extra = legend_extra_height(640, 70, line_names);  // a legend of several rows: a taller chart
  Frame f{640, 400 + extra};
  f.bottom = 70 + extra;
  f.log_x = c.log_x;
  f.log_y = c.log_y;
  const std::vector<double> yt = c.log_y ? log_ticks(ylo, yhi) : nice_ticks(0.0, yhi),
                            xt = axis_ticks(c.log_x, xlo, xhi, false);
  f.set_y(yt);
  f.set_x(xt);
  std::string s = header(f, c.title) + y_axis(f, yt, c.y_label) + x_axis(f, xt, c.x_label);
  std::vector<std::string> names;
  for (size_t i = 0; i < c.lines.size(); ++i) {
    const Line& l = c.lines[i];
    names.push_back(l.name);
    // Points in x order, so a line never doubles back.
    std::vector<size_t> order(l.x.size());
    for (size_t k = 0; k < order.size(); ++k) order[k] = k;
    std::sort(order.begin(), order.end(), [&](size_t a, size_t b) { return l.x[a] < l.x[b]; });
    std::string pts;
    for (size_t k : order) {  // appended piece by piece: "..." + string trips GCC 12's -Wrestrict (PR 105651)
      if (!pts.empty()) pts += ' ';
      pts += num(f.px(l.x[k]));
      pts += ',';
      pts += num(f.py(l.y[k]));
    }
    s += "<g class=\"series\">\n<polyline class=\"line\" fill=\"none\" stroke-width=\"2\" stroke=\"" +
         std::string(series_colour(l.name, i)) + "\" points=\"" + pts + "\"/>\n";
    for (size_t k : order) {
      s += "<circle class=\"point\" cx=\"" + num(f.px(l.x[k])) + "\" cy=\"" + num(f.py(l.y[k])) + "\" r=\"3\" fill=\"" +
           series_colour(l.name, i) + "\"/>\n";
      if (!l.low.empty()) s += error_bar(f.px(l.x[k]), f.py(l.low[k]), f.py(l.high[k]), 4);
    }
    s += "</g>\n";
  }
  return s + legend(f, names) + "</svg>\n";
}

std::string render(const ScatterChart& c) {
  if (c.points.empty()) throw std::invalid_argument("svg chart: a scatter chart needs points");
  double xlo = INFINITY, xhi = -INFINITY, ylo = INFINITY, yhi = -INFINITY;
  for (const ScatterPoint& p : c.points) {
    check_finite(p.x, "x");
    check_finite(p.y, "y");
    check_log(c.log_x, p.x, "x");
    check_log(c.log_y, p.y, "y");
    xlo = std::min(xlo, p.x);
    xhi = std::max(xhi, p.x);
    ylo = std::min(ylo, p.y);
    yhi = std::max(yhi, p.y);
  }
  const bool numbered =
      std::any_of(c.points.begin(), c.points.end(), [](const ScatterPoint& p) { return !p.label.empty(); });
  std::vector<std::string> names = {numbered ? "cells (labels: as numbered in the table)" : "cells"};
  if (std::any_of(c.points.begin(), c.points.end(), [](const ScatterPoint& p) { return p.front; }))
    names.push_back("Pareto front (lower is better on both axes)");
  // A legend of more than one row makes the chart taller, under the x axis' label.
  const double extra = legend_extra_height(640, 70, names);
  Frame f{640, 420 + extra};
  f.bottom = 70 + extra;
  f.right = 40;  // room for the number beside a rightmost point
  f.log_x = c.log_x;
  f.log_y = c.log_y;
  const std::vector<double> xt = axis_ticks(c.log_x, xlo, xhi, false), yt = axis_ticks(c.log_y, ylo, yhi, false);
  f.set_x(xt);
  f.set_y(yt);
  std::string s = header(f, c.title) + y_axis(f, yt, c.y_label) + x_axis(f, xt, c.x_label);

  // The front as a step line: from each front point right to the next one's x, then down to it.
  std::vector<const ScatterPoint*> front;
  for (const ScatterPoint& p : c.points)
    if (p.front) front.push_back(&p);
  std::sort(front.begin(), front.end(),
            [](const ScatterPoint* a, const ScatterPoint* b) { return a->x != b->x ? a->x < b->x : a->y > b->y; });
  if (!front.empty()) {
    std::string pts = num(f.px(front[0]->x)) + "," + num(f.py(front[0]->y));
    for (size_t i = 1; i < front.size(); ++i) {
      pts += " " + num(f.px(front[i]->x)) + "," + num(f.py(front[i - 1]->y));
      pts += " " + num(f.px(front[i]->x)) + "," + num(f.py(front[i]->y));
    }
    s += "<polyline class=\"pareto\" fill=\"none\" stroke-width=\"2\" stroke-dasharray=\"6 3\" stroke=\"" +
         std::string(colour(1)) + "\" points=\"" + pts + "\"/>\n";
  }
  // Labels go where they overlap nothing: of the places around their point, the first that is clear of
  // every point and every label placed before it and lies inside the chart; where none is, the one that
  // overlaps least. Widths are estimated (10 px DejaVu Sans: about 6.2 px a character).
  struct Box {
    double x0, y0, x1, y1;
  };
  const auto overlap = [](const Box& a, const Box& b) {
    const double w = std::min(a.x1, b.x1) - std::max(a.x0, b.x0), h = std::min(a.y1, b.y1) - std::max(a.y0, b.y0);
    return w > 0 && h > 0 ? w * h : 0.0;
  };
  std::vector<Box> taken;
  for (const ScatterPoint& p : c.points) {
    const double r = p.front ? 5 : 4;
    taken.push_back({f.px(p.x) - r, f.py(p.y) - r, f.px(p.x) + r, f.py(p.y) + r});
  }
  std::vector<std::pair<double, double>> label_at(c.points.size());  // text origin (start, baseline)
  for (size_t i = 0; i < c.points.size(); ++i) {
    const ScatterPoint& p = c.points[i];
    if (p.label.empty()) continue;
    const double x = f.px(p.x), y = f.py(p.y), w = 6.2 * double(p.label.size()), h = 10;
    // The eight places beside the point first, then further up and down in steps of a line, for points
    // that crowd together (a cluster's labels stack beside it).
    std::vector<std::pair<double, double>> places = {{x + 7, y - 7},      {x + 7, y + 14},    {x - 7 - w, y - 7},
                                                     {x - 7 - w, y + 14}, {x + 8, y + 3.5},   {x - 8 - w, y + 3.5},
                                                     {x - w / 2, y - 9},  {x - w / 2, y + 18}};
    for (int ring = 1; ring <= 4; ++ring) {
      const double up = y - 7 - 12.0 * ring, down = y + 14 + 12.0 * ring;
      for (const auto& place :
           {std::pair{x + 7, up}, std::pair{x + 7, down}, std::pair{x - 7 - w, up}, std::pair{x - 7 - w, down}})
        places.push_back(place);
    }
    double best = INFINITY;
    for (const auto& [tx, ty] : places) {
      const Box b{tx, ty - h + 1, tx + w, ty + 2};
      double cost = 0;
      for (size_t k = 0; k < taken.size(); ++k) cost += k == i ? 0 : overlap(b, taken[k]);
      const bool inside = b.x0 >= 2 && b.x1 <= f.width - 2 && b.y0 >= f.top && b.y1 <= f.height - f.bottom;
      if (!inside) cost += w * h;
      if (cost < best) {
        best = cost;
        label_at[i] = {tx, ty};
      }
      if (cost == 0) break;
    }
    taken.push_back({label_at[i].first, label_at[i].second - h + 1, label_at[i].first + w, label_at[i].second + 2});
  }
  s += "<g class=\"points\">\n";
  for (size_t i = 0; i < c.points.size(); ++i) {
    const ScatterPoint& p = c.points[i];
    const double x = f.px(p.x), y = f.py(p.y);
    const std::string tip = p.tooltip.empty()
                                ? (p.label.empty() ? "" : p.label + ": ") + tick_label(p.x) + ", " + tick_label(p.y)
                                : p.tooltip;
    s += std::string("<circle class=\"") + (p.front ? "point front" : "point") + "\" cx=\"" + num(x) + "\" cy=\"" +
         num(y) + "\" r=\"" + (p.front ? "5" : "4") + "\" fill=\"" + (p.front ? colour(1) : colour(0)) +
         "\" stroke=\"black\"><title>" + escape(tip) + "</title></circle>\n";
    if (!p.label.empty()) {
      s += "<text class=\"point-label\" x=\"" + num(label_at[i].first) + "\" y=\"" + num(label_at[i].second) +
           "\" font-size=\"10\">" + escape(p.label) + "</text>\n";
    }
  }
  s += "</g>\n";
  return s + legend(f, names) + "</svg>\n";
}

std::string render_colour_bar(const std::string& title, std::uint64_t max_count) {
  constexpr double kW = 420, kH = 64, kX0 = 16, kX1 = 404, kY = 24, kBar = 16;
  std::string s = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + tick_label(kW) + "\" height=\"" +
                  tick_label(kH) + "\" viewBox=\"0 0 " + tick_label(kW) + " " + tick_label(kH) +
                  "\" font-family=\"DejaVu Sans, sans-serif\" font-size=\"11\">\n"
                  "<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n<defs><linearGradient id=\"ramp\">";
  for (int i = 0; i <= 20; ++i) {
    const float t = float(i) / 20.0f;
    const std::array<float, 3> c = miss_ramp_srgb(t);
    char stop[96];
    std::snprintf(stop, sizeof(stop), "<stop offset=\"%.2f\" stop-color=\"rgb(%d,%d,%d)\"/>", double(t),
                  int(c[0] * 255.0f + 0.5f), int(c[1] * 255.0f + 0.5f), int(c[2] * 255.0f + 0.5f));
    s += stop;
  }
  s += "</linearGradient></defs>\n<text x=\"" + tick_label(kX0) + "\" y=\"14\">" + escape(title) + "</text>\n";
  s += "<rect x=\"" + tick_label(kX0) + "\" y=\"" + tick_label(kY) + "\" width=\"" + tick_label(kX1 - kX0) +
       "\" height=\"" + tick_label(kBar) + "\" fill=\"url(#ramp)\" stroke=\"#444\" stroke-width=\"0.5\"/>\n";
  // Ticks at 0, 1, 10, 100, ... below the maximum, and the maximum itself, where the heatmap puts them.
  std::vector<std::uint64_t> ticks = {0};
  for (std::uint64_t v = 1; v < max_count; v *= 10) ticks.push_back(v);
  if (max_count > 0) ticks.push_back(max_count);
  const double top = std::log1p(double(std::max<std::uint64_t>(max_count, 1)));
  const auto x_of = [&](std::uint64_t v) { return kX0 + (kX1 - kX0) * std::log1p(double(v)) / top; };
  double last_x = -1e9;
  for (size_t i = 0; i < ticks.size(); ++i) {
    const double x = x_of(ticks[i]);
    const bool end = i + 1 == ticks.size();
    // No label over its neighbour: a power of ten too close to the previous label or to the maximum goes.
    if (!end && (x - last_x < 28 || x_of(ticks.back()) - x < 28)) continue;
    s += "<line x1=\"" + tick_label(x) + "\" x2=\"" + tick_label(x) + "\" y1=\"" + tick_label(kY + kBar) + "\" y2=\"" +
         tick_label(kY + kBar + 4) + "\" stroke=\"#444\"/>\n";
    s += "<text x=\"" + tick_label(x) + "\" y=\"" + tick_label(kY + kBar + 16) + "\" text-anchor=\"" +
         (end && ticks.size() > 1 ? "end"
          : i == 0                ? "start"
                                  : "middle") +
         "\">" + std::to_string(ticks[i]) + "</text>\n";
    last_x = x;
  }
  s += "</svg>\n";
  return s;
}

}  // namespace hp::svg
