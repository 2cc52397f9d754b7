#include "client/plot.h"

#include <cairo.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <numbers>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace mlclust::client {
namespace {

constexpr double kMarginLeft = 95, kMarginRight = 30, kMarginBottom = 75;
constexpr double kMarginTopWithTitle = 50, kMarginTop = 25;
// The axes stand this far off the data area, so that a zero-energy plateau (the planar and
// sphere energies' curves up to their elbow) is not drawn on the x axis.
constexpr double kAxisGap = 8;

absl::Status CheckInput(std::span<const EnergyCurvePoint> curve, const EnergyPlotOptions& options) {
  if (curve.empty()) return absl::InvalidArgumentError("the energy curve has no levels to plot");
  for (size_t i = 0; i < curve.size(); ++i) {
    if (curve[i].clusters == 0) {
      return absl::InvalidArgumentError(absl::StrCat("level ", i, " has 0 clusters"));
    }
    if (!std::isfinite(curve[i].energy)) {
      return absl::InvalidArgumentError(
          absl::StrCat("level ", i, " has a non-finite energy (", curve[i].energy, ")"));
    }
  }
  for (int size : {options.width, options.height}) {
    if (size < 200 || size > 8000) {
      return absl::InvalidArgumentError(
          absl::StrCat("the plot must be 200 to 8000 pixels wide "
                       "and high, not ",
                       options.width, " x ", options.height));
    }
  }
  for (uint32_t elbow : options.elbows) {
    if (std::none_of(curve.begin(), curve.end(),
                     [&](const EnergyCurvePoint& p) { return p.clusters == elbow; })) {
      return absl::InvalidArgumentError(
          absl::StrCat("elbow at ", elbow, " clusters: no level of the curve has that many"));
    }
  }
  if (options.chosen != 0 &&
      std::none_of(curve.begin(), curve.end(),
                   [&](const EnergyCurvePoint& p) { return p.clusters == options.chosen; })) {
    return absl::InvalidArgumentError(absl::StrCat(
        "chosen level at ", options.chosen, " clusters: no level of the curve has that many"));
  }
  return absl::OkStatus();
}

// A step of 1, 2 or 5 times a power of ten, near range / 5.
double NiceStep(double range) {
  const double raw = range / 5;
  const double decade = std::pow(10.0, std::floor(std::log10(raw)));
  for (double m : {1.0, 2.0, 5.0}) {
    if (m * decade >= raw) return m * decade;
  }
  return 10 * decade;
}

// "1", "10", "100", "1000", "10k", "100k", "1M", ...
std::string DecadeLabel(int decade) {
  if (decade < 4) return absl::StrCat(static_cast<int>(std::lround(std::pow(10.0, decade))));
  if (decade < 6)
    return absl::StrCat(static_cast<int>(std::lround(std::pow(10.0, decade - 3))), "k");
  return absl::StrCat(static_cast<long>(std::lround(std::pow(10.0, decade - 6))), "M");
}

void ShowText(cairo_t* cr, const std::string& text, double x, double y, double align_x,
              double align_y) {
  cairo_text_extents_t extents;
  cairo_text_extents(cr, text.c_str(), &extents);
  cairo_move_to(cr, x - extents.x_bearing - align_x * extents.width,
                y - extents.y_bearing - align_y * extents.height);
  cairo_show_text(cr, text.c_str());
}

struct SurfaceDeleter {
  void operator()(cairo_surface_t* s) const { cairo_surface_destroy(s); }
};
struct ContextDeleter {
  void operator()(cairo_t* c) const { cairo_destroy(c); }
};

cairo_status_t AppendToString(void* closure, const unsigned char* data, unsigned int length) {
  static_cast<std::string*>(closure)->append(reinterpret_cast<const char*>(data), length);
  return CAIRO_STATUS_SUCCESS;
}

}  // namespace

double EnergyPlotFrame::X(double clusters) const {
  return left + (std::log10(clusters) - log_x_min) / (log_x_max - log_x_min) * (right - left);
}

double EnergyPlotFrame::Y(double energy) const {
  if (log_energy && !(energy > 0)) return bottom;  // 0 on a log axis: its bottom edge
  const double value = log_energy ? std::log10(energy) : energy;
  return bottom - (value - y_min) / (y_max - y_min) * (bottom - top);
}

absl::StatusOr<EnergyPlotFrame> EnergyPlotFrameFor(std::span<const EnergyCurvePoint> curve,
                                                   const EnergyPlotOptions& options) {
  if (absl::Status status = CheckInput(curve, options); !status.ok()) return status;
  EnergyPlotFrame frame;
  frame.left = kMarginLeft;
  frame.right = options.width - kMarginRight;
  frame.top = options.title.empty() ? kMarginTop : kMarginTopWithTitle;
  frame.bottom = options.height - kMarginBottom;
  uint32_t fewest = curve[0].clusters, most = curve[0].clusters;
  double lowest = curve[0].energy, highest = curve[0].energy;
  for (const EnergyCurvePoint& p : curve) {
    fewest = std::min(fewest, p.clusters);
    most = std::max(most, p.clusters);
    lowest = std::min(lowest, p.energy);
    highest = std::max(highest, p.energy);
  }
  frame.log_x_min = std::floor(std::log10(static_cast<double>(fewest)));
  frame.log_x_max = std::ceil(std::log10(static_cast<double>(most)));
  if (frame.log_x_max <= frame.log_x_min) frame.log_x_max = frame.log_x_min + 1;
  // An energy kept incrementally can end a hair below zero where the exact one is 0; that
  // must not add a whole step of negative axis.
  if (lowest < 0 && -lowest <= 1e-6 * (highest - lowest)) lowest = 0;
  using Axis = EnergyPlotOptions::EnergyAxis;
  // A log axis: energies of 0 (a face alone under the CVD energy, a plane under the planar
  // one) lie on its bottom edge; a negative one rules it out.
  double smallest_positive = std::numeric_limits<double>::infinity();
  for (const EnergyCurvePoint& p : curve) {
    if (p.energy > 0) smallest_positive = std::min(smallest_positive, p.energy);
  }
  const bool log_possible = lowest >= 0 && highest > 0;
  if (options.energy_axis == Axis::kLog && !log_possible) {
    return absl::InvalidArgumentError(absl::StrCat(
        "a logarithmic energy axis needs energies of at least 0, one above; they run from ", lowest,
        " to ", highest));
  }
  frame.log_energy =
      options.energy_axis == Axis::kLog ||
      (options.energy_axis == Axis::kAuto && log_possible && highest > 1000 * smallest_positive);
  if (frame.log_energy) {
    frame.y_min = std::floor(std::log10(smallest_positive));
    frame.y_max = std::ceil(std::log10(highest));
    if (frame.y_max <= frame.y_min) frame.y_max = frame.y_min + 1;
    frame.y_step = 1;
    return frame;
  }
  lowest = std::min(lowest, 0.0);
  if (!(highest > lowest)) highest = lowest + 1;
  frame.y_step = NiceStep(highest - lowest);
  frame.y_min = std::floor(lowest / frame.y_step) * frame.y_step;
  frame.y_max = std::ceil(highest / frame.y_step) * frame.y_step;
  if (frame.y_max <= frame.y_min) frame.y_max = frame.y_min + frame.y_step;
  return frame;
}

absl::StatusOr<std::string> RenderEnergyPlotPng(std::span<const EnergyCurvePoint> curve,
                                                const EnergyPlotOptions& options) {
  absl::StatusOr<EnergyPlotFrame> frame_or = EnergyPlotFrameFor(curve, options);
  if (!frame_or.ok()) return frame_or.status();
  const EnergyPlotFrame& frame = *frame_or;

  std::unique_ptr<cairo_surface_t, SurfaceDeleter> surface(
      cairo_image_surface_create(CAIRO_FORMAT_ARGB32, options.width, options.height));
  std::unique_ptr<cairo_t, ContextDeleter> context(cairo_create(surface.get()));
  cairo_t* cr = context.get();
  cairo_set_source_rgb(cr, 1, 1, 1);
  cairo_paint(cr);
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);

  // Grid: decades and their 2..9 subdivisions on x, the rounded steps on y.
  cairo_set_line_width(cr, 1);
  for (int decade = static_cast<int>(frame.log_x_min); decade < frame.log_x_max; ++decade) {
    for (int m = 1; m <= 9; ++m) {
      const double x = std::round(frame.X(m * std::pow(10.0, decade))) + 0.5;
      const double shade = m == 1 ? 0.80 : 0.92;
      cairo_set_source_rgb(cr, shade, shade, shade);
      cairo_move_to(cr, x, frame.top - kAxisGap);
      cairo_line_to(cr, x, frame.bottom + kAxisGap);
      cairo_stroke(cr);
    }
  }
  const double y_step = frame.y_step;
  cairo_set_font_size(cr, 13);
  for (double e = frame.y_min; e <= frame.y_max + y_step / 2; e += y_step) {
    const double y = std::round(frame.log_energy ? frame.Y(std::pow(10.0, e)) : frame.Y(e)) + 0.5;
    cairo_set_source_rgb(cr, 0.88, 0.88, 0.88);
    cairo_move_to(cr, frame.left, y);
    cairo_line_to(cr, frame.right, y);
    cairo_stroke(cr);
    cairo_set_source_rgb(cr, 0.1, 0.1, 0.1);
    const std::string label = frame.log_energy
                                  ? absl::StrFormat("%g", std::pow(10.0, e))
                                  : absl::StrFormat("%.4g", std::abs(e) < y_step * 1e-9 ? 0.0 : e);
    ShowText(cr, label, frame.left - 8, y, 1.0, 0.5);
  }
  for (int decade = static_cast<int>(frame.log_x_min); decade <= frame.log_x_max; ++decade) {
    ShowText(cr, DecadeLabel(decade), frame.X(std::pow(10.0, decade)), frame.bottom + kAxisGap + 8,
             0.5, 0);
  }

  // Axes and their labels.
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_set_line_width(cr, 1.5);
  cairo_move_to(cr, frame.left - kAxisGap, frame.top - kAxisGap);
  cairo_line_to(cr, frame.left - kAxisGap, frame.bottom + kAxisGap);
  cairo_line_to(cr, frame.right + kAxisGap, frame.bottom + kAxisGap);
  cairo_stroke(cr);
  cairo_set_font_size(cr, 15);
  ShowText(cr, "number of clusters (log scale)", (frame.left + frame.right) / 2,
           options.height - 30, 0.5, 0);
  cairo_save(cr);
  cairo_translate(cr, 22, (frame.top + frame.bottom) / 2);
  cairo_rotate(cr, -std::numbers::pi / 2);
  ShowText(cr, frame.log_energy ? "energy (log scale)" : "energy", 0, 0, 0.5, 0);
  cairo_restore(cr);
  if (!options.title.empty()) {
    cairo_set_font_size(cr, 17);
    ShowText(cr, options.title, (frame.left + frame.right) / 2, 15, 0.5, 0);
  }

  // The curve, by number of clusters.
  std::vector<EnergyCurvePoint> sorted(curve.begin(), curve.end());
  std::stable_sort(
      sorted.begin(), sorted.end(),
      [](const EnergyCurvePoint& a, const EnergyCurvePoint& b) { return a.clusters < b.clusters; });
  cairo_rectangle(cr, frame.left - kAxisGap + 1, frame.top - kAxisGap,
                  frame.right - frame.left + 2 * kAxisGap,
                  frame.bottom - frame.top + 2 * kAxisGap - 1);
  cairo_save(cr);
  cairo_clip(cr);
  cairo_set_source_rgb(cr, 0.12, 0.38, 0.80);
  cairo_set_line_width(cr, 2);
  cairo_set_line_join(cr, CAIRO_LINE_JOIN_ROUND);
  for (size_t i = 0; i < sorted.size(); ++i) {
    const double x = frame.X(sorted[i].clusters), y = frame.Y(sorted[i].energy);
    if (i == 0) {
      cairo_move_to(cr, x, y);
    } else {
      cairo_line_to(cr, x, y);
    }
  }
  if (sorted.size() == 1) {
    cairo_arc(cr, frame.X(sorted[0].clusters), frame.Y(sorted[0].energy), 3, 0,
              2 * std::numbers::pi);
    cairo_fill(cr);
  }
  cairo_stroke(cr);

  // Elbows: a dashed line down to the axis, a dot on the curve, the number of clusters.
  cairo_set_font_size(cr, 14);
  for (uint32_t elbow : options.elbows) {
    const auto it = std::find_if(sorted.begin(), sorted.end(),
                                 [&](const EnergyCurvePoint& p) { return p.clusters == elbow; });
    const double x = frame.X(elbow), y = frame.Y(it->energy);
    cairo_set_source_rgb(cr, 0.85, 0.1, 0.1);
    const double dash[] = {5, 4};
    cairo_set_dash(cr, dash, 2, 0);
    cairo_set_line_width(cr, 2);
    cairo_move_to(cr, std::round(x), y);
    cairo_line_to(cr, std::round(x), frame.bottom + kAxisGap);
    cairo_stroke(cr);
    cairo_set_dash(cr, nullptr, 0, 0);
    cairo_arc(cr, x, y, 6, 0, 2 * std::numbers::pi);
    cairo_fill(cr);
    ShowText(cr, absl::StrCat("elbow: ", elbow), x + 9, y - 9, 0, 1);
  }
  // The chosen level: a blue line over the whole height, its count at the top.
  if (options.chosen != 0) {
    const double x = std::round(frame.X(options.chosen));
    cairo_set_source_rgb(cr, 0.1, 0.3, 0.85);
    cairo_set_line_width(cr, 2);
    cairo_move_to(cr, x, frame.top);
    cairo_line_to(cr, x, frame.bottom + kAxisGap);
    cairo_stroke(cr);
    ShowText(cr, absl::StrCat("chosen: ", options.chosen), x + 6, frame.top + 4, 0, 0);
  }
  cairo_restore(cr);

  cairo_surface_flush(surface.get());
  std::string png;
  const cairo_status_t status =
      cairo_surface_write_to_png_stream(surface.get(), AppendToString, &png);
  if (status != CAIRO_STATUS_SUCCESS || cairo_status(cr) != CAIRO_STATUS_SUCCESS) {
    return absl::InternalError(absl::StrCat(
        "cairo could not draw the plot: ",
        cairo_status_to_string(status != CAIRO_STATUS_SUCCESS ? status : cairo_status(cr))));
  }
  return png;
}

absl::Status WriteEnergyPlotPng(std::span<const EnergyCurvePoint> curve,
                                const EnergyPlotOptions& options, const std::string& path) {
  absl::StatusOr<std::string> png = RenderEnergyPlotPng(curve, options);
  if (!png.ok()) return png.status();
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (out) out.write(png->data(), static_cast<std::streamsize>(png->size()));
  if (out) out.close();
  if (!out) {
    const int error = errno;
    const std::string message = absl::StrCat("cannot write the plot to ", path);
    return error != 0 ? absl::ErrnoToStatus(error, message) : absl::UnknownError(message);
  }
  return absl::OkStatus();
}

}  // namespace mlclust::client
