// SPDX-License-Identifier: MIT
#pragma once
/// Line plots written as standalone SVG documents (axes, ticks, grid, labels, legend), for the
/// rate–distortion curves of `btf report`. No plotting library and no script: the SVG is plain
/// markup that any browser shows offline.

#include <string>
#include <string_view>
#include <vector>

namespace btf::quality {

/// Escapes text for XML and HTML content and attribute values: & < > " '.
std::string xml_escape(std::string_view text);

/// An axis range and its tick positions, both on "nice" numbers (1, 2 or 5 times a power of ten).
struct AxisTicks {
    double min = 0, max = 1;
    std::vector<double> ticks;  ///< ascending, from min to max inclusive
};

/// A linear axis covering [lo, hi] with about `target` intervals: the step is the nice number
/// nearest (hi - lo) / target, and min/max are the multiples of the step around the data. An
/// empty range (lo == hi) is widened around its value.
AxisTicks linear_axis(double lo, double hi, int target = 5);
/// A logarithmic axis covering [lo, hi] (both > 0): ticks at 1, 2 and 5 times each power of ten
/// when the range spans at most two decades, at the powers of ten otherwise. min and max are tick
/// values around the data.
AxisTicks log_axis(double lo, double hi);
/// A tick label: the shortest of up to six significant digits ("0.05", "12.5", "1e-05" → "1e-05").
std::string format_tick(double value);

struct PlotPoint {
    double x = 0, y = 0;
    std::string label;  ///< shown as the marker's tooltip, e.g. "components=8"
};

struct PlotSeries {
    std::string name;  ///< legend entry
    std::vector<PlotPoint> points;
};

struct PlotAxis {
    std::string label;
    bool log = false;
};

struct PlotOptions {
    std::string title;
    PlotAxis x, y;
    int width = 640, height = 400;  ///< SVG size in pixels
};

/// One series per entry: markers joined by a line in order of x, a distinct colour (Okabe–Ito
/// palette, safe for colour-blind readers) and marker shape, and a legend entry. Points with a
/// non-finite coordinate, or a coordinate <= 0 on a log axis, are left out.
std::string svg_line_plot(const PlotOptions& options, const std::vector<PlotSeries>& series);

}  // namespace btf::quality
