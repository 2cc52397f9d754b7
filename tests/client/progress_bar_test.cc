// The job commands' progress (client/progress_bar.h): the share done from the server's
// fraction and from the levels, levels counted by level, the time left, the modes.
#include "client/progress_bar.h"

#include <gtest/gtest.h>

#include <cstdio>
#include <string>

namespace mlclust::client {
namespace {

v1::JobEvent Snapshot(uint32_t clusters) {
  v1::JobEvent event;
  event.mutable_snapshot()->set_level(0);
  event.mutable_snapshot()->set_cluster_count(clusters);
  return event;
}

v1::JobEvent Levels(uint32_t first_level, std::initializer_list<uint32_t> counts,
                    bool continues = false) {
  v1::JobEvent event;
  event.mutable_levels()->set_first_level(first_level);
  for (uint32_t count : counts) event.mutable_levels()->add_cluster_count(count);
  event.mutable_levels()->set_last_level_continues(continues);
  return event;
}

v1::JobEvent Stage(const std::string& stage, double fraction) {
  v1::JobEvent event;
  event.mutable_progress()->set_stage(stage);
  event.mutable_progress()->set_fraction(fraction);
  return event;
}

TEST(ProgressBarTest, TextsOfTheBarAndTheClock) {
  EXPECT_EQ(ProgressBarText(0.5, 10), "[#####-----]  50%");
  EXPECT_EQ(ProgressBarText(0.999, 10), "[#########-]  99%");
  EXPECT_EQ(ProgressBarText(2, 4), "[####] 100%");
  EXPECT_EQ(ProgressBarText(-1, 4), "[----]   0%");
  EXPECT_EQ(ClockText(absl::Seconds(7.9)), "0:07");
  EXPECT_EQ(ClockText(absl::Seconds(723)), "12:03");
  EXPECT_EQ(ClockText(absl::Seconds(3723)), "1:02:03");
}

TEST(ProgressBarTest, LevelsGiveTheShareAndTheTimeLeft) {
  ProgressBarOptions options;
  options.final_clusters = 1;
  options.bar_width = 10;
  ProgressBar bar(nullptr, options);  // kOff: draws into last_line() only
  const absl::Time t0 = absl::FromUnixSeconds(1000);
  bar.Update(Stage("cluster", 0), t0);
  bar.Update(Snapshot(101), t0);
  // 100 merges to go; a level split over two batches counts once.
  bar.Update(Levels(1, {100, 99, 98}, /*continues=*/true), t0 + absl::Seconds(2));
  bar.Update(Levels(3, {98, 97, 96}), t0 + absl::Seconds(3));
  EXPECT_DOUBLE_EQ(bar.fraction(), 0.05);
  bar.Update(Levels(6, {91}), t0 + absl::Seconds(5));  // 10 of 100 in 5 s: 45 s left
  EXPECT_EQ(bar.last_line(),
            "mlclust: cluster [#---------]  10%  7 levels, 91 clusters  0:45 left");
  // The server's fraction moves it where the levels do not (a single-level algorithm).
  bar.Update(Stage("cluster", 0.5), t0 + absl::Seconds(6));
  EXPECT_DOUBLE_EQ(bar.fraction(), 0.5);
  v1::JobEvent done;
  done.mutable_done();
  done.set_final(true);
  bar.Update(done, t0 + absl::Seconds(8));
  EXPECT_EQ(bar.last_line(), "mlclust: cluster [##########] 100%  7 levels, 91 clusters  0:08");
}

TEST(ProgressBarTest, TheStopAtJobSpecClustersIsTheWholeWay) {
  ProgressBarOptions options;
  options.final_clusters = 51;
  ProgressBar bar(nullptr, options);
  bar.Update(Snapshot(101));
  bar.Update(Levels(1, {76}));
  EXPECT_DOUBLE_EQ(bar.fraction(), 0.5);
}

TEST(ProgressBarTest, ModesByStreamAndFlags) {
  std::FILE* file = std::tmpfile();
  ASSERT_NE(file, nullptr);
  EXPECT_EQ(ProgressModeFor(file, false, false), ProgressBarOptions::Mode::kOff);
  EXPECT_EQ(ProgressModeFor(file, false, true), ProgressBarOptions::Mode::kLines);
  EXPECT_EQ(ProgressModeFor(file, true, true), ProgressBarOptions::Mode::kOff);
  // kLines: a line at each tenth reached, and the last.
  ProgressBarOptions options;
  options.mode = ProgressBarOptions::Mode::kLines;
  options.bar_width = 4;
  ProgressBar bar(file, options);
  bar.Update(Snapshot(11));
  bar.Update(Levels(1, {10}));
  bar.Update(Levels(2, {9}));
  bar.Update(Levels(3, {4, 3}));
  std::rewind(file);
  char text[512] = {};
  const size_t n = std::fread(text, 1, sizeof(text) - 1, file);
  std::fclose(file);
  EXPECT_EQ(std::string(text, n),
            "mlclust: queued [----]   0%  1 levels, 11 clusters\n"
            "mlclust: queued [----]  10%  2 levels, 10 clusters\n"
            "mlclust: queued [----]  20%  3 levels, 9 clusters\n"
            "mlclust: queued [###-]  80%  5 levels, 3 clusters\n");
}

}  // namespace
}  // namespace mlclust::client
