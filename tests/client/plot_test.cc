// The --plot PNG: it decodes, has the size asked for, and the elbows are marked where the
// curve has them.
#include "client/plot.h"

#include <cairo.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "tests/fixtures/files.h"

namespace mlclust::client {
namespace {

struct Rgb {
  int r = 0, g = 0, b = 0;
};

// A decoded PNG: cairo reads it back into an ARGB32 image.
class Image {
 public:
  explicit Image(const std::string& png) : png_(png) {
    surface_ = cairo_image_surface_create_from_png_stream(&Image::Read, this);
  }
  ~Image() { cairo_surface_destroy(surface_); }
  bool ok() const { return cairo_surface_status(surface_) == CAIRO_STATUS_SUCCESS; }
  int width() const { return cairo_image_surface_get_width(surface_); }
  int height() const { return cairo_image_surface_get_height(surface_); }
  Rgb at(double x, double y) const {
    const int column = static_cast<int>(std::lround(x)), row = static_cast<int>(std::lround(y));
    const unsigned char* data = cairo_image_surface_get_data(surface_);
    uint32_t pixel;
    std::memcpy(&pixel, data + row * cairo_image_surface_get_stride(surface_) + 4 * column, 4);
    return {static_cast<int>((pixel >> 16) & 255), static_cast<int>((pixel >> 8) & 255),
            static_cast<int>(pixel & 255)};
  }

 private:
  static cairo_status_t Read(void* closure, unsigned char* data, unsigned int length) {
    Image* image = static_cast<Image*>(closure);
    if (image->offset_ + length > image->png_.size()) return CAIRO_STATUS_READ_ERROR;
    std::memcpy(data, image->png_.data() + image->offset_, length);
    image->offset_ += length;
    return CAIRO_STATUS_SUCCESS;
  }

  std::string png_;
  size_t offset_ = 0;
  cairo_surface_t* surface_ = nullptr;
};

bool IsRed(Rgb c) { return c.r > 180 && c.g < 90 && c.b < 90; }
bool IsBlue(Rgb c) { return c.b > 150 && c.r < 100; }
bool IsWhite(Rgb c) { return c.r > 250 && c.g > 250 && c.b > 250; }

// A cube-like curve: energy 0 from 500 clusters down to 6, then a fast rise to 1.
std::vector<EnergyCurvePoint> CubeCurve() {
  std::vector<EnergyCurvePoint> curve;
  for (uint32_t k = 500; k >= 6; k -= (k > 50 ? 10 : 1)) curve.push_back({k, 0.0});
  for (uint32_t k = 5; k >= 1; --k) curve.push_back({k, (6.0 - k) / 5.0});
  return curve;
}

TEST(PlotTest, PngHasTheSizeAskedForAndMarksTheElbow) {
  const std::vector<EnergyCurvePoint> curve = CubeCurve();
  EnergyPlotOptions options;
  options.width = 700;
  options.height = 450;
  options.title = "cube: planar energy";
  options.elbows = {6};
  absl::StatusOr<std::string> png = RenderEnergyPlotPng(curve, options);
  ASSERT_TRUE(png.ok()) << png.status();
  ASSERT_GE(png->size(), 8u);
  EXPECT_EQ(png->substr(0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
  const Image image(*png);
  ASSERT_TRUE(image.ok());
  EXPECT_EQ(image.width(), 700);
  EXPECT_EQ(image.height(), 450);

  absl::StatusOr<EnergyPlotFrame> frame = EnergyPlotFrameFor(curve, options);
  ASSERT_TRUE(frame.ok());
  // Decades 1 to 1000 on x; energies 0 to 1 on y.
  EXPECT_EQ(frame->log_x_min, 0);
  EXPECT_EQ(frame->log_x_max, 3);
  EXPECT_EQ(frame->y_min, 0);
  EXPECT_EQ(frame->y_max, 1);
  // The elbow's dot is at (6, 0); the dashed line below it is red too, the curve at 100
  // clusters is blue, and the plot area away from both is white.
  EXPECT_TRUE(IsRed(image.at(frame->X(6), frame->Y(0) - 3)));
  EXPECT_TRUE(IsRed(image.at(frame->X(6) + 3, frame->Y(0))));
  EXPECT_TRUE(IsBlue(image.at(frame->X(100), frame->Y(0))));
  EXPECT_TRUE(IsBlue(image.at(frame->X(3), frame->Y(0.6))));
  EXPECT_FALSE(IsRed(image.at(frame->X(100), frame->Y(0) - 3)));
  EXPECT_TRUE(IsWhite(image.at(frame->X(150), frame->Y(0.7))));
  // Nothing is marked where there is no elbow.
  options.elbows = {};
  const Image plain(*RenderEnergyPlotPng(curve, options));
  EXPECT_FALSE(IsRed(plain.at(frame->X(6), frame->Y(0) - 3)));
}

TEST(PlotTest, MarksTheChosenLevelOverTheWholeHeight) {
  const std::vector<EnergyCurvePoint> curve = CubeCurve();
  EnergyPlotOptions options;
  options.chosen = 150;
  const Image image(*RenderEnergyPlotPng(curve, options));
  ASSERT_TRUE(image.ok());
  absl::StatusOr<EnergyPlotFrame> frame = EnergyPlotFrameFor(curve, options);
  ASSERT_TRUE(frame.ok());
  // Blue at 150 clusters (between grid lines) high above the curve (energy 0 there), white beside
  // it.
  EXPECT_TRUE(IsBlue(image.at(std::round(frame->X(150)), frame->Y(0.7))));
  EXPECT_TRUE(IsWhite(image.at(frame->X(170), frame->Y(0.7))));
  options.chosen = 0;
  const Image plain(*RenderEnergyPlotPng(curve, options));
  EXPECT_TRUE(IsWhite(plain.at(std::round(frame->X(150)), frame->Y(0.7))));
  options.chosen = 7000;
  EXPECT_EQ(RenderEnergyPlotPng(curve, options).status().message(),
            "chosen level at 7000 clusters: no level of the curve has that many");
}

TEST(PlotTest, EnergiesOverManyDecadesGetALogAxis) {
  // 1000 clusters at energy 0 (each its own), then 1e-6 .. 1 down to one cluster.
  std::vector<EnergyCurvePoint> curve = {{1000, 0.0}};
  for (uint32_t k = 7; k >= 1; --k) curve.push_back({k, std::pow(10.0, 1.0 - k)});
  absl::StatusOr<EnergyPlotFrame> frame = EnergyPlotFrameFor(curve);
  ASSERT_TRUE(frame.ok()) << frame.status();
  EXPECT_TRUE(frame->log_energy);
  EXPECT_EQ(frame->y_min, -6);
  EXPECT_EQ(frame->y_max, 0);
  EXPECT_DOUBLE_EQ(frame->Y(1e-3), (frame->Y(1e-6) + frame->Y(1)) / 2);  // decades evenly
  EXPECT_EQ(frame->Y(0), frame->bottom);                                 // 0 on the bottom edge
  const Image image(*RenderEnergyPlotPng(curve));
  ASSERT_TRUE(image.ok());
  EXPECT_TRUE(IsBlue(image.at(frame->X(3), frame->Y(0.01))));  // the curve at (3, 1e-2)
  EnergyPlotOptions linear;
  linear.energy_axis = EnergyPlotOptions::EnergyAxis::kLinear;
  EXPECT_FALSE(EnergyPlotFrameFor(curve, linear)->log_energy);
  // The cube's curve (energy 0, then 0.2 .. 1: under 1000 times) stays linear.
  EXPECT_FALSE(EnergyPlotFrameFor(CubeCurve())->log_energy);
  EnergyPlotOptions log;
  log.energy_axis = EnergyPlotOptions::EnergyAxis::kLog;
  EXPECT_TRUE(EnergyPlotFrameFor(CubeCurve(), log)->log_energy);
  curve.push_back({2000, -1.0});
  EXPECT_EQ(EnergyPlotFrameFor(curve, log).status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(PlotTest, MarksEveryElbowOnTheCurve) {
  // Two steps: flat to 40, a rise to 10 clusters, flat, then a rise to 1.
  std::vector<EnergyCurvePoint> curve;
  for (uint32_t k = 2000; k >= 1; k = k > 100 ? k - 50 : k - 1) {
    const double energy = k >= 40 ? 1.0 : k >= 10 ? 2.0 + (40.0 - k) / 30.0 : 3.0 + (10.0 - k);
    curve.push_back({k, energy});
  }
  EnergyPlotOptions options;
  options.elbows = {40, 10};
  absl::StatusOr<std::string> png = RenderEnergyPlotPng(curve, options);
  ASSERT_TRUE(png.ok()) << png.status();
  const Image image(*png);
  ASSERT_TRUE(image.ok());
  EXPECT_EQ(image.width(), 900);
  EXPECT_EQ(image.height(), 560);
  absl::StatusOr<EnergyPlotFrame> frame = EnergyPlotFrameFor(curve, options);
  ASSERT_TRUE(frame.ok());
  EXPECT_EQ(frame->log_x_max, 4);  // 2000 clusters: up to 10^4
  for (auto [k, e] : {std::pair{40.0, 1.0}, std::pair{10.0, 3.0}}) {
    EXPECT_TRUE(IsRed(image.at(frame->X(k), frame->Y(e) + 2))) << k;
    // The dashed line: mostly red between the dot and the axis.
    int red = 0, rows = 0;
    for (double y = frame->Y(e) + 10; y < frame->bottom; y += 1, ++rows) {
      red += IsRed(image.at(std::round(frame->X(k)), y));
    }
    EXPECT_GT(red, rows / 3) << k;
  }
}

// A level whose energy is a rounding error below zero does not open a negative axis, and
// the labelled energies are the frame's steps.
TEST(PlotTest, RoundingBelowZeroKeepsTheAxisAtZero) {
  const std::vector<EnergyCurvePoint> curve = {{1000, -1e-12}, {100, 0.1}, {10, 1.0}, {1, 4.4}};
  absl::StatusOr<EnergyPlotFrame> frame = EnergyPlotFrameFor(curve);
  ASSERT_TRUE(frame.ok());
  EXPECT_EQ(frame->y_min, 0);
  EXPECT_EQ(frame->y_step, 1);
  EXPECT_EQ(frame->y_max, 5);
  const std::vector<EnergyCurvePoint> negative = {{10, -2.0}, {1, 3.0}};
  frame = EnergyPlotFrameFor(negative);
  ASSERT_TRUE(frame.ok());
  EXPECT_EQ(frame->y_min, -2);
}

TEST(PlotTest, RefusesWhatItCannotDraw) {
  std::vector<EnergyCurvePoint> curve = {{10, 1.0}, {5, 2.0}};
  EnergyPlotOptions options;
  EXPECT_EQ(RenderEnergyPlotPng({}, options).status().code(), absl::StatusCode::kInvalidArgument);
  options.elbows = {7};
  EXPECT_NE(RenderEnergyPlotPng(curve, options).status().message().find("elbow at 7"),
            std::string::npos);
  options.elbows = {};
  options.width = 10;
  EXPECT_EQ(RenderEnergyPlotPng(curve, options).status().code(),
            absl::StatusCode::kInvalidArgument);
  options.width = 900;
  curve[1].energy = std::nan("");
  EXPECT_EQ(RenderEnergyPlotPng(curve, options).status().code(),
            absl::StatusCode::kInvalidArgument);
  curve[1] = {0, 1.0};
  EXPECT_EQ(RenderEnergyPlotPng(curve, options).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(PlotTest, WritesTheFileAndNamesAPathItCannotWrite) {
  const std::vector<EnergyCurvePoint> curve = {{100, 0.5}, {10, 1.0}, {1, 4.0}};
  const std::string path = ::testing::TempDir() + "/plot_test.png";
  ASSERT_TRUE(WriteEnergyPlotPng(curve, {}, path).ok());
  EXPECT_EQ(mlclust::testing::ReadFileBytes(path), *RenderEnergyPlotPng(curve, {}));
  std::remove(path.c_str());
  const absl::Status status = WriteEnergyPlotPng(curve, {}, "/nonexistent-dir/plot.png");
  EXPECT_FALSE(status.ok());
  EXPECT_NE(status.message().find("/nonexistent-dir/plot.png"), std::string::npos);
}

}  // namespace
}  // namespace mlclust::client
