// The progress a job command shows on stderr (mesh, points, watch): on a terminal a bar
// with the share done and the time left, redrawn in place at most every 100 ms; elsewhere
// nothing, unless asked (--progress), then a plain line at every tenth done. --quiet: none.
#ifndef MLCLUST_CLIENT_PROGRESS_BAR_H_
#define MLCLUST_CLIENT_PROGRESS_BAR_H_

#include <cstdint>
#include <cstdio>
#include <string>

#include "absl/time/clock.h"
#include "absl/time/time.h"
#include "mlclust/v1/mlclust.pb.h"

namespace mlclust::client {

struct ProgressBarOptions {
  enum class Mode { kOff, kTerminal, kLines };
  Mode mode = Mode::kOff;
  // The cluster count the hierarchy ends at (JobSpec.clusters, levels_low, or 1): the share
  // done is how far the levels' count has come from the first level's towards it.
  uint32_t final_clusters = 1;
  int bar_width = 24;
};

// kTerminal where `quiet` is not set and `stream` is a terminal; kLines where `asked`
// (--progress) and it is not one; else kOff.
ProgressBarOptions::Mode ProgressModeFor(std::FILE* stream, bool quiet, bool asked);

// "[#########---------------]  37%" and so on: the bar of `fraction` (0..1) in `width`
// characters, and the share in percent.
std::string ProgressBarText(double fraction, int width);

// "0:07", "12:03", "1:02:03": a duration of whole seconds.
std::string ClockText(absl::Duration duration);

// Reads a job's events and draws them. The share done is the larger of the server's
// Progress.fraction ("cluster" stage) and the levels' own (cluster counts received), so a
// single-level algorithm's iterations and a hierarchy's levels both move it; the time
// left is the time since the first progress times (1 - share) / share.
class ProgressBar {
 public:
  ProgressBar(std::FILE* out, const ProgressBarOptions& options);
  void Update(const v1::JobEvent& event, absl::Time now = absl::Now());
  // What the last update drew (for tests; also kept with mode kOff).
  const std::string& last_line() const { return line_; }
  double fraction() const { return fraction_; }

 private:
  void Draw(absl::Time now, bool final);

  std::FILE* out_;
  ProgressBarOptions options_;
  std::string stage_ = "queued";
  uint32_t first_level_ = 0, levels_ = 0, clusters_ = 0, first_clusters_ = 0;
  double fraction_ = 0;
  int lines_printed_tenths_ = -1;  // kLines: the last tenth printed
  absl::Time started_ = absl::InfinitePast(), drawn_ = absl::InfinitePast();
  std::string line_;
};

}  // namespace mlclust::client

#endif  // MLCLUST_CLIENT_PROGRESS_BAR_H_
