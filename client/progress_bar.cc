#include "client/progress_bar.h"

#include <unistd.h>

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"

namespace mlclust::client {

ProgressBarOptions::Mode ProgressModeFor(std::FILE* stream, bool quiet, bool asked) {
  if (quiet) return ProgressBarOptions::Mode::kOff;
  if (isatty(fileno(stream)) != 0) return ProgressBarOptions::Mode::kTerminal;
  return asked ? ProgressBarOptions::Mode::kLines : ProgressBarOptions::Mode::kOff;
}

std::string ProgressBarText(double fraction, int width) {
  fraction = std::clamp(fraction, 0.0, 1.0);
  const int filled = static_cast<int>(std::floor(fraction * width));
  return absl::StrFormat("[%s%s] %3d%%", std::string(filled, '#'), std::string(width - filled, '-'),
                         static_cast<int>(std::floor(fraction * 100)));
}

std::string ClockText(absl::Duration duration) {
  const int64_t seconds = std::max<int64_t>(0, absl::ToInt64Seconds(duration));
  if (seconds >= 3600) {
    return absl::StrFormat("%d:%02d:%02d", seconds / 3600, seconds / 60 % 60, seconds % 60);
  }
  return absl::StrFormat("%d:%02d", seconds / 60, seconds % 60);
}

ProgressBar::ProgressBar(std::FILE* out, const ProgressBarOptions& options)
    : out_(out), options_(options) {}

void ProgressBar::Update(const v1::JobEvent& event, absl::Time now) {
  if (event.has_accepted()) {
    stage_ = absl::StrCat("queued, ", event.accepted().queue_position(), " ahead");
  } else if (event.has_progress()) {
    stage_ = event.progress().stage();
    if (stage_ == "cluster") fraction_ = std::max(fraction_, event.progress().fraction());
  } else if (event.has_snapshot()) {
    first_level_ = event.snapshot().level();
    levels_ = 1;
    clusters_ = first_clusters_ = event.snapshot().cluster_count();
  } else if (event.has_levels() && event.levels().cluster_count_size() > 0) {
    const v1::LevelBatch& batch = event.levels();
    // Levels by their number, not by message: a level split across two batches (its
    // second starts at the same first_level) is counted once.
    levels_ = batch.first_level() + batch.cluster_count_size() - first_level_;
    clusters_ = batch.cluster_count(batch.cluster_count_size() - 1);
    if (first_clusters_ > options_.final_clusters) {
      const uint32_t reached = std::max(clusters_, options_.final_clusters);
      fraction_ = std::max(fraction_, static_cast<double>(first_clusters_ - reached) /
                                          (first_clusters_ - options_.final_clusters));
    }
  }
  if (started_ == absl::InfinitePast() &&
      (event.has_progress() || event.has_levels() || event.has_snapshot())) {
    started_ = now;
  }
  if (event.has_done()) fraction_ = 1;
  const bool final = event.final();
  if (options_.mode == ProgressBarOptions::Mode::kTerminal && !final &&
      now - drawn_ < absl::Milliseconds(100)) {
    return;
  }
  Draw(now, final);
}

void ProgressBar::Draw(absl::Time now, bool final) {
  drawn_ = now;
  std::string line =
      absl::StrCat("mlclust: ", stage_, " ", ProgressBarText(fraction_, options_.bar_width));
  if (levels_ > 0) absl::StrAppend(&line, "  ", levels_, " levels, ", clusters_, " clusters");
  const absl::Duration elapsed = now - started_;
  if (final) {
    absl::StrAppend(&line, "  ", ClockText(elapsed));
  } else if (fraction_ >= 0.02 && elapsed >= absl::Seconds(1)) {
    absl::StrAppend(&line, "  ", ClockText(elapsed * ((1 - fraction_) / fraction_)), " left");
  }
  line_ = line;
  switch (options_.mode) {
    case ProgressBarOptions::Mode::kOff:
      return;
    case ProgressBarOptions::Mode::kTerminal:
      std::fprintf(out_, "\r\033[K%s%s", line.c_str(), final ? "\n" : "");
      std::fflush(out_);
      return;
    case ProgressBarOptions::Mode::kLines: {
      const int tenths = static_cast<int>(std::floor(fraction_ * 10));
      if (tenths > lines_printed_tenths_ || final) {
        lines_printed_tenths_ = tenths;
        std::fprintf(out_, "%s\n", line.c_str());
        std::fflush(out_);
      }
      return;
    }
  }
}

}  // namespace mlclust::client
