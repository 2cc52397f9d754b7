// The energy-versus-clusters plot of a hierarchy (`--plot FILE.png`, issue 13): the energy
// of every received level against its number of clusters on a logarithmic axis, the way
// the dissertation draws its energy curves (Figs. 4.15-4.25), with the elbows (section
// 4.4, core/hierarchy/elbow.h) marked by a red dot on the curve, a dashed red line down to
// the axis and the elbow's number of clusters, and the chosen level by a blue line.
//
// Drawn with cairo (libcairo2-dev); text with cairo's own fonts through fontconfig (a sans
// serif font such as fonts-dejavu-core must be installed for the labels to appear).
#ifndef MLCLUST_CLIENT_PLOT_H_
#define MLCLUST_CLIENT_PLOT_H_

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace mlclust::client {

// One level: its number of clusters (>= 1) and its energy (finite).
struct EnergyCurvePoint {
  uint32_t clusters = 0;
  double energy = 0;
};

struct EnergyPlotOptions {
  // Image size in pixels, each in [200, 8000].
  int width = 900;
  int height = 560;
  // Above the plot, e.g. "bunny00.off: ML, CVD energy". May be empty.
  std::string title;
  // Cluster counts to mark as elbows; each must be the count of some point of the curve.
  std::vector<uint32_t> elbows;
  // The energy axis: linear from 0, or logarithmic (decades), which keeps the many levels
  // of small energy from lying flat on the axis (energies of 0 then lie on its bottom edge).
  // kAuto: logarithmic where no energy is below 0 and the largest is over 1000 times the
  // smallest above 0, else linear.
  enum class EnergyAxis { kAuto, kLinear, kLog };
  EnergyAxis energy_axis = EnergyAxis::kAuto;
  // The chosen level's count (what --clusters K or --auto-k wrote), marked by a blue line
  // from top to bottom and "chosen: K"; 0 = none. Must be the count of some point.
  uint32_t chosen = 0;
};

// Where things are drawn, in pixels from the top left corner: the data area (the axes stand
// a few pixels outside it) and the maps from data to pixels. x is log10(clusters) from a whole
// decade below the fewest clusters to one at or above the most; y runs from 0 (or the lowest
// energy, if negative) to a rounded-up largest energy, or (log_energy) from the decade at
// or below the smallest energy to the one at or above the largest.
struct EnergyPlotFrame {
  double left = 0, right = 0, top = 0, bottom = 0;  // the plot area
  double log_x_min = 0, log_x_max = 1;              // decades at left and right
  double y_min = 0, y_max = 1;                      // energies at bottom and top
  double y_step = 1;  // between labelled energies: 1, 2 or 5 times a power of ten
  // A logarithmic energy axis: y_min and y_max are then decades (log10 of the energies at
  // bottom and top) and y_step 1 (a label at each decade).
  bool log_energy = false;

  double X(double clusters) const;  // pixel column of a number of clusters
  double Y(double energy) const;    // pixel row of an energy
};

// The frame a curve is drawn in (for tests, and for callers that annotate the image).
// Errors as RenderEnergyPlotPng.
absl::StatusOr<EnergyPlotFrame> EnergyPlotFrameFor(std::span<const EnergyCurvePoint> curve,
                                                   const EnergyPlotOptions& options = {});

// The plot as PNG bytes (8-bit RGB with alpha, options.width x options.height). The curve's
// points may come in any order (they are drawn by number of clusters; levels sharing a
// count are drawn as received). INVALID_ARGUMENT naming the problem for an empty curve, a
// point with 0 clusters or a non-finite energy, a size out of range, or an elbow that is no
// point's count; INTERNAL if cairo fails.
absl::StatusOr<std::string> RenderEnergyPlotPng(std::span<const EnergyCurvePoint> curve,
                                                const EnergyPlotOptions& options = {});

// RenderEnergyPlotPng written to `path` (replaced if it exists). Its errors, and the
// errno-derived code naming the path if the file cannot be written.
absl::Status WriteEnergyPlotPng(std::span<const EnergyCurvePoint> curve,
                                const EnergyPlotOptions& options, const std::string& path);

}  // namespace mlclust::client

#endif  // MLCLUST_CLIENT_PLOT_H_
