// The SVG writer's output parsed back as XML (a small tag reader: well-formedness and element counts).
#include "svg_chart.hpp"

#include <gtest/gtest.h>

#include <set>

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>
#include <string>
#include <vector>

namespace hp::svg {
namespace {

struct Element {
  std::string name;
  std::map<std::string, std::string> attrs;
};

// Reads every start tag, checks that end tags match and that nothing is left open. Throws on
// malformed input; returns the elements in document order.
std::vector<Element> parse_xml(const std::string& s) {
  std::vector<Element> out;
  std::vector<std::string> open;
  size_t i = 0;
  while ((i = s.find('<', i)) != std::string::npos) {
    const size_t end = s.find('>', i);
    if (end == std::string::npos) throw std::runtime_error("unterminated tag");
    std::string tag = s.substr(i + 1, end - i - 1);
    i = end + 1;
    if (tag.starts_with("?")) continue;
    if (tag.starts_with("/")) {
      if (open.empty() || open.back() != tag.substr(1)) throw std::runtime_error("mismatched </" + tag.substr(1) + ">");
      open.pop_back();
      continue;
    }
    const bool self_closing = tag.ends_with("/");
    if (self_closing) tag.pop_back();
    Element e;
    size_t p = tag.find_first_of(" \n");
    e.name = tag.substr(0, p);
    while (p != std::string::npos && p < tag.size()) {
      const size_t eq = tag.find('=', p);
      if (eq == std::string::npos) break;
      const size_t q1 = tag.find('"', eq), q2 = tag.find('"', q1 + 1);
      if (q1 != eq + 1 || q2 == std::string::npos) throw std::runtime_error("bad attribute in <" + e.name + ">");
      std::string key = tag.substr(p, eq - p);
      key.erase(0, key.find_first_not_of(" \n"));
      const std::string value = tag.substr(q1 + 1, q2 - q1 - 1);
      if (value.find('<') != std::string::npos) throw std::runtime_error("unescaped < in an attribute");
      e.attrs[key] = value;
      p = q2 + 1;
    }
    out.push_back(e);
    if (!self_closing) open.push_back(e.name);
  }
  if (!open.empty()) throw std::runtime_error("<" + open.back() + "> left open");
  return out;
}

size_t count(const std::vector<Element>& els, const std::string& name, const std::string& cls) {
  size_t n = 0;
  for (const Element& e : els)
    if (e.name == name && (cls.empty() || (e.attrs.count("class") && e.attrs.at("class") == cls))) ++n;
  return n;
}

// A heatmap's colour bar: the heatmaps' own ramp (black at 0, yellow at the maximum) and ticks where the
// heatmap's log scale puts 0, 1, 10, ... and the maximum; a power of ten too close to the maximum loses its
// label rather than overlapping it.
TEST(SvgChart, ColourBarFollowsTheHeatmapScale) {
  const std::string bar = svg::render_colour_bar("shadows L1 misses per pixel", 95);
  EXPECT_NE(bar.find("<stop offset=\"0.00\" stop-color=\"rgb(0,0,0)\"/>"), std::string::npos) << bar;
  EXPECT_NE(bar.find("<stop offset=\"1.00\" stop-color=\"rgb(255,255,0)\"/>"), std::string::npos);
  for (const char* label : {">0</text>", ">1</text>", ">10</text>", ">95</text>"})
    EXPECT_NE(bar.find(label), std::string::npos) << label;
  // log(1 + 10) / log(1 + 95) of the 388-pixel bar from x = 16.
  EXPECT_NE(bar.find("x=\"219.837\""), std::string::npos) << bar;
  const std::string close = svg::render_colour_bar("t", 120);  // 100 sits 11 px from 120
  EXPECT_EQ(close.find(">100</text>"), std::string::npos) << close;
  EXPECT_NE(close.find(">120</text>"), std::string::npos);
  EXPECT_NE(svg::render_colour_bar("t", 0).find(">0</text>"), std::string::npos);
}

TEST(SvgChart, BarChartHasBarsErrorBarsAndLegend) {
  BarChart c;
  c.title = "times <ms> & more";
  c.y_label = "ms";
  c.series = {"gbuffer", "shadows", "reflections"};
  c.groups = {{"cell a", {12, 3, 7}, {11, 2.5, 6}, {13, 3.5, 8}}, {"cell b", {10, 4, 6}, {9, 3, 5}, {11, 5, 7}}};
  const std::string svg = render(c);
  const auto els = parse_xml(svg);
  EXPECT_EQ(els.front().name, "svg");
  EXPECT_EQ(count(els, "rect", "bar"), 6u);
  EXPECT_EQ(count(els, "g", "errorbar"), 6u);
  EXPECT_EQ(count(els, "rect", "legend-swatch"), 3u);
  EXPECT_EQ(count(els, "text", "group-label"), 2u);
  EXPECT_GE(count(els, "text", "tick"), 3u);
  EXPECT_NE(svg.find("times &lt;ms&gt; &amp; more"), std::string::npos);
  // The tallest bar (12, in series 0) is taller than the shortest (3).
  double h12 = 0, h3 = 0;
  for (const Element& e : els) {
    if (e.name != "rect" || e.attrs.count("class") == 0 || e.attrs.at("class") != "bar") continue;
    const double h = std::stod(e.attrs.at("height"));
    if (h12 == 0)
      h12 = h;
    else if (h3 == 0)
      h3 = h;
  }
  EXPECT_NEAR(h3 / h12, 3.0 / 12.0, 0.01);
}

TEST(SvgChart, LineChartHasOnePolylinePerLine) {
  LineChart c;
  c.title = "time vs pixels";
  c.x_label = "pixels";
  c.y_label = "ms";
  c.lines = {{"shadows", {4608, 9216, 36864}, {1, 2, 8}, {}, {}},
             {"reflections", {36864, 4608, 9216}, {9, 2, 3}, {8, 1, 2}, {10, 3, 4}}};
  const auto els = parse_xml(render(c));
  EXPECT_EQ(count(els, "polyline", "line"), 2u);
  EXPECT_EQ(count(els, "circle", "point"), 6u);
  EXPECT_EQ(count(els, "g", "errorbar"), 3u);
  EXPECT_EQ(count(els, "text", "legend-label"), 2u);
  // Points are drawn in x order, so the polyline's x coordinates increase.
  for (const Element& e : els) {
    if (e.name != "polyline") continue;
    std::string pts = e.attrs.at("points");
    double last = -1;
    size_t p = 0;
    while (p < pts.size()) {
      const double x = std::stod(pts.substr(p));
      EXPECT_GT(x, last);
      last = x;
      p = pts.find(' ', p);
      if (p == std::string::npos) break;
      ++p;
    }
  }
}

// The coordinates of a polyline's points.
std::vector<std::pair<double, double>> polyline_points(const Element& e) {
  std::vector<std::pair<double, double>> out;
  const std::string pts = e.attrs.at("points");
  size_t p = 0;
  while (p < pts.size()) {
    const size_t comma = pts.find(',', p);
    const size_t space = pts.find(' ', comma);
    out.push_back({std::stod(pts.substr(p, comma - p)), std::stod(pts.substr(comma + 1, space - comma - 1))});
    if (space == std::string::npos) break;
    p = space + 1;
  }
  return out;
}

TEST(SvgChart, ScatterChartHighlightsTheParetoFront) {
  ScatterChart c;
  c.title = "time vs error";
  c.x_label = "ms";
  c.y_label = "relMSE";
  // Front: (1, 9), (2, 4), (5, 1); (3, 6) and (6, 8) are dominated.
  c.points = {{3, 6, "c", "", false},
              {1, 9, "a", "", true},
              {6, 8, "e <1>", "tip e", false},
              {5, 1, "d", "", true},
              {2, 4, "b", "", true}};
  const std::string svg = render(c);
  const auto els = parse_xml(svg);
  EXPECT_EQ(count(els, "circle", "point"), 2u);
  EXPECT_EQ(count(els, "circle", "point front"), 3u);
  EXPECT_EQ(count(els, "text", "point-label"), 5u);
  EXPECT_EQ(count(els, "title", ""), 5u);  // one tooltip per point
  EXPECT_NE(svg.find("<title>tip e</title>"), std::string::npos);
  EXPECT_NE(svg.find("<title>a: 1, 9</title>"), std::string::npos);  // default tooltip: label and coordinates
  EXPECT_NE(svg.find("e &lt;1&gt;"), std::string::npos);
  ASSERT_EQ(count(els, "polyline", "pareto"), 1u);
  // A step line through the three front points in x order: p0, (x1, y0), p1, (x2, y1), p2.
  for (const Element& e : els) {
    if (e.name != "polyline") continue;
    const auto pts = polyline_points(e);
    ASSERT_EQ(pts.size(), 5u);
    for (size_t i = 1; i < pts.size(); ++i) {
      EXPECT_GE(pts[i].first, pts[i - 1].first);    // x never goes back
      EXPECT_GE(pts[i].second, pts[i - 1].second);  // y never rises (svg y grows downwards)
      EXPECT_TRUE(pts[i].first == pts[i - 1].first || pts[i].second == pts[i - 1].second) << "not a step";
    }
  }
  // Without front points there is no front line.
  for (ScatterPoint& p : c.points) p.front = false;
  EXPECT_EQ(count(parse_xml(render(c)), "polyline", "pareto"), 0u);
}

// Point labels never overlap each other or another point, and stay inside the chart, even where front
// points crowd together (the shadow sweep's front: two points 2 ms apart on a 20-45 ms axis, two near the
// right edge).
TEST(SvgChart, ScatterLabelsNeitherCollideNorLeaveTheChart) {
  ScatterChart c;
  c.title = "crowded";
  c.points = {{23.7, 140104, "1", "", true}, {24.6, 140273, "", "", false}, {25.9, 138220, "2", "", true},
              {42.5, 23685, "3", "", true},  {44.0, 170, "4", "", true},    {44.1, 171, "5", "", true},
              {44.2, 172, "6", "", true},    {44.3, 173, "7", "", true}};
  const std::string svg = render(c);
  const auto els = parse_xml(svg);
  double width = 0, height = 0;
  struct Box {
    double x0, y0, x1, y1;
  };
  std::vector<Box> labels, points;
  for (const Element& e : els) {
    if (e.name == "svg") {
      width = std::stod(e.attrs.at("width"));
      height = std::stod(e.attrs.at("height"));
    } else if (e.name == "text" && e.attrs.count("class") && e.attrs.at("class") == "point-label") {
      const double x = std::stod(e.attrs.at("x")), y = std::stod(e.attrs.at("y"));
      labels.push_back({x, y - 9, x + 6.2, y + 2});  // every label here is one character
    } else if (e.name == "circle") {
      const double x = std::stod(e.attrs.at("cx")), y = std::stod(e.attrs.at("cy")), r = std::stod(e.attrs.at("r"));
      points.push_back({x - r, y - r, x + r, y + r});
    }
  }
  ASSERT_EQ(labels.size(), 7u);
  ASSERT_EQ(points.size(), 8u);
  const auto hit = [](const Box& a, const Box& b) {
    return std::min(a.x1, b.x1) > std::max(a.x0, b.x0) && std::min(a.y1, b.y1) > std::max(a.y0, b.y0);
  };
  for (size_t i = 0; i < labels.size(); ++i) {
    EXPECT_GE(labels[i].x0, 0.0) << "label " << i;
    EXPECT_LE(labels[i].x1, width) << "label " << i;
    EXPECT_GE(labels[i].y0, 0.0) << "label " << i;
    EXPECT_LE(labels[i].y1, height) << "label " << i;
    for (size_t k = i + 1; k < labels.size(); ++k) EXPECT_FALSE(hit(labels[i], labels[k])) << i << " and " << k;
    for (size_t k = 0; k < points.size(); ++k)
      EXPECT_FALSE(hit(labels[i], points[k])) << "label " << i << ", point " << k;
  }
}

TEST(SvgChart, ScatterChartLogAxes) {
  ScatterChart c;
  c.title = "log";
  c.log_x = c.log_y = true;
  c.points = {{1e-4, 10, "a", "", true}, {1e-3, 100, "b", "", false}, {1e-2, 1000, "c", "", false}};
  const std::string svg = render(c);
  const auto els = parse_xml(svg);
  for (const char* t : {">0.0001<", ">0.001<", ">0.01<", ">10<", ">100<", ">1000<"})
    EXPECT_NE(svg.find(t), std::string::npos) << t;
  // Equal ratios are equal distances on log axes.
  std::vector<double> cx, cy;
  for (const Element& e : els) {
    if (e.name != "circle") continue;
    cx.push_back(std::stod(e.attrs.at("cx")));
    cy.push_back(std::stod(e.attrs.at("cy")));
  }
  ASSERT_EQ(cx.size(), 3u);
  EXPECT_NEAR(cx[1] - cx[0], cx[2] - cx[1], 0.02);
  EXPECT_NEAR(cy[0] - cy[1], cy[1] - cy[2], 0.02);
  EXPECT_GT(cx[1] - cx[0], 50.0);
  c.points.push_back({0.0, 1.0, "zero", "", false});
  EXPECT_THROW(render(c), std::invalid_argument);  // 0 cannot be on a log axis
  c.log_x = false;
  EXPECT_NO_THROW(render(c));
  c.points.push_back({1.0, std::nan(""), "nan", "", false});
  EXPECT_THROW(render(c), std::invalid_argument);
  EXPECT_THROW(render(ScatterChart{}), std::invalid_argument);
}

TEST(SvgChart, LineChartLogAxes) {
  LineChart c;
  c.title = "error vs k";
  c.log_x = c.log_y = true;
  c.lines = {{"L1", {2, 4, 8, 16}, {0.1, 0.2, 0.4, 0.8}, {}, {}}};
  const auto els = parse_xml(render(c));
  ASSERT_EQ(count(els, "polyline", "line"), 1u);
  // A power law is a straight line on log-log axes: equal steps in both.
  std::vector<double> cx, cy;
  for (const Element& e : els) {
    if (e.name != "circle") continue;
    cx.push_back(std::stod(e.attrs.at("cx")));
    cy.push_back(std::stod(e.attrs.at("cy")));
  }
  ASSERT_EQ(cx.size(), 4u);
  for (size_t i = 2; i < 4; ++i) {
    EXPECT_NEAR(cx[i] - cx[i - 1], cx[1] - cx[0], 0.02);
    EXPECT_NEAR(cy[i] - cy[i - 1], cy[1] - cy[0], 0.02);
  }
  c.lines[0].y[0] = 0.0;
  EXPECT_THROW(render(c), std::invalid_argument);
  c.log_y = false;
  EXPECT_NO_THROW(render(c));
}

TEST(SvgChart, LogTicksCoverTheRange) {
  const auto t = log_ticks(3e-4, 0.07);
  EXPECT_LE(t.front(), 3e-4);
  EXPECT_GE(t.back(), 0.07);
  EXPECT_EQ(t.front(), 1e-4);
  EXPECT_NEAR(t.back(), 0.1, 1e-12);
  for (size_t i = 1; i < t.size(); ++i) EXPECT_GT(t[i], t[i - 1]);
  const auto narrow = log_ticks(3, 40);  // two decades or less: 1-2-5 steps
  EXPECT_EQ(narrow.front(), 2.0);
  EXPECT_EQ(narrow.back(), 50.0);
  EXPECT_NE(std::find(narrow.begin(), narrow.end(), 5.0), narrow.end());
  const auto wide = log_ticks(1e-12, 1e6);  // 18 decades: every third power at most 9 ticks
  EXPECT_LE(wide.size(), 10u);
  EXPECT_LE(wide.front(), 1e-12);
  EXPECT_GE(wide.back(), 1e6);
  EXPECT_THROW(log_ticks(0, 1), std::invalid_argument);
}

TEST(SvgChart, NiceTicksCoverTheRange) {
  const auto t = nice_ticks(0.0, 13.7);
  EXPECT_LE(t.front(), 0.0);
  EXPECT_GE(t.back(), 13.7);
  EXPECT_GE(t.size(), 3u);
  EXPECT_LE(t.size(), 9u);
  EXPECT_DOUBLE_EQ(t[1] - t[0], 5.0);  // 13.7 / 5 = 2.74 rounds up to a step of 5
  const auto s = nice_ticks(4608, 36864);
  EXPECT_LE(s.front(), 4608);
  EXPECT_GE(s.back(), 36864);
  EXPECT_EQ(nice_ticks(2.0, 2.0).size() >= 2, true);
  EXPECT_EQ(tick_label(0.5), "0.5");
  EXPECT_EQ(tick_label(12), "12");
}

TEST(SvgChart, RejectsInconsistentInput) {
  BarChart c;
  c.series = {"a", "b"};
  c.groups = {{"g", {1}, {}, {}}};
  EXPECT_THROW(render(c), std::invalid_argument);
  c.groups = {{"g", {1, std::nan("")}, {}, {}}};
  EXPECT_THROW(render(c), std::invalid_argument);
  LineChart l;
  EXPECT_THROW(render(l), std::invalid_argument);
}

}  // namespace
TEST(SvgChart, LongLegendsWrapAndTheChartGrows) {
  LineChart one;
  one.title = "t";
  one.lines.push_back({"short", {1, 2}, {1, 2}, {}, {}});
  const std::string a = render(one);
  EXPECT_NE(a.find("height=\"400.00\""), std::string::npos);
  LineChart many = one;
  for (int i = 0; i < 4; ++i) {
    many.lines.push_back({"case=framed view, reversed_z=" + std::to_string(i), {1, 2}, {2, 3}, {}, {}});
  }
  const std::string b = render(many);
  EXPECT_EQ(b.find("height=\"400.00\""), std::string::npos) << "a legend of several rows makes the chart taller";
  // Every legend label stays inside the chart's width: its x plus its length at the legend's estimate of
  // 7 px a character.
  const std::string width_key = "<svg xmlns=\"http://www.w3.org/2000/svg\" version=\"1.1\" width=\"";
  ASSERT_NE(b.find(width_key), std::string::npos);
  const double width = std::stod(b.substr(b.find(width_key) + width_key.size()));
  EXPECT_GT(width, 100.0);
  const std::string key = "class=\"legend-label\" x=\"";
  std::set<std::string> rows;
  size_t labels = 0;
  size_t at = 0;
  while ((at = b.find(key, at)) != std::string::npos) {
    at += key.size();
    const double x = std::stod(b.substr(at));
    const size_t ypos = b.find("y=\"", at) + 3;
    rows.insert(b.substr(ypos, b.find('"', ypos) - ypos));
    const size_t text = b.find('>', at) + 1;
    const std::string label = b.substr(text, b.find('<', text) - text);
    EXPECT_GT(x, 0.0) << label;
    EXPECT_LE(x + 7.0 * double(label.size()), width) << label;
    ++labels;
  }
  EXPECT_EQ(labels, many.lines.size());
  EXPECT_GE(rows.size(), 2u);
}

// Long cell labels (rotated 30 degrees under the axis) stay inside the picture and above the legend, and a
// long title fits: nothing clipped or overlapping, whatever the labels' length (seen: a 434 px chart with
// its title clipped and its labels over the legend).
TEST(SvgChart, LongGroupLabelsAndTitleFitAboveTheLegend) {
  BarChart c;
  c.title = "Median pass time per cell (error bars: 95% CI of the median)";
  c.y_label = "ms";
  c.series = {"gbuffer", "shadows", "reflections", "accumulate", "composite"};
  for (const char* label :
       {"as_layout=flat, as_order=leaf, traversal=compute", "b", "as_order=morton, traversal=pipeline"}) {
    c.groups.push_back({label, {1, 2, 3, 4, 5}, {}, {}});
  }
  const std::vector<Element> els = parse_xml(render(c));
  double width = 0, height = 0, legend_top = 1e9, lowest_label = 0;
  for (const Element& e : els) {
    if (e.name == "svg") {
      width = std::stod(e.attrs.at("width"));
      height = std::stod(e.attrs.at("height"));
    }
    if (e.name == "rect" && e.attrs.count("class") && e.attrs.at("class") == "legend-swatch") {
      legend_top = std::min(legend_top, std::stod(e.attrs.at("y")));
    }
  }
  // Each group label is anchored at its end and rotated -30 degrees about (x, y): its baseline runs up to
  // the right into the anchor, so the text lies left of and below it, down to y + length * sin 30.
  size_t k = 0;
  for (const Element& e : els) {
    if (e.name != "text" || !e.attrs.count("class") || e.attrs.at("class") != "group-label") continue;
    const double x = std::stod(e.attrs.at("x")), y = std::stod(e.attrs.at("y"));
    const double len = 7.0 * double(c.groups[k++].label.size());
    EXPECT_GE(x - len * std::cos(M_PI / 6), 0.0) << "label clipped on the left";
    lowest_label = std::max(lowest_label, y + len * std::sin(M_PI / 6) + 4);
  }
  EXPECT_EQ(k, c.groups.size());
  EXPECT_LT(lowest_label, legend_top) << "labels run into the legend";
  EXPECT_LT(legend_top, height);
  EXPECT_GE(width, 8.5 * double(c.title.size())) << "the title is clipped";
}

// A pass keeps its colour whatever the other series (seen: shadows orange in one report, green in another).
TEST(SvgChart, EachPassHasOneColourInEveryChart) {
  const auto fill_of = [](const std::string& svg, const std::string& series) {
    const std::string key = "<title>" + series + ": ";
    const size_t t = svg.find(key);
    EXPECT_NE(t, std::string::npos) << series;
    const size_t f = svg.rfind("fill=\"", t);
    return svg.substr(f + 6, 7);
  };
  BarChart a;
  a.title = "a";
  a.series = {"gbuffer", "shadows", "reflections"};
  a.groups.push_back({"x", {1, 2, 3}, {}, {}});
  BarChart b = a;
  b.series = {"reflections", "consume", "shadows"};
  const std::string sa = render(a), sb = render(b);
  EXPECT_EQ(fill_of(sa, "shadows"), fill_of(sb, "shadows"));
  EXPECT_EQ(fill_of(sa, "reflections"), fill_of(sb, "reflections"));
  EXPECT_NE(fill_of(sb, "consume"), fill_of(sb, "shadows"));
  EXPECT_STREQ(series_colour("shadows", 0), series_colour("shadows", 5));
  EXPECT_STREQ(series_colour("case=a", 2), series_colour("case=b", 2)) << "other names: by index";
}

}  // namespace hp::svg
