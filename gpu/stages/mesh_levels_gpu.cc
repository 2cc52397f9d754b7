#include "gpu/stages/mesh_levels_gpu.h"

#include "gpu/stages/gpu_level_sink.h"

namespace mlclust::gpu {

std::vector<CvdSums> CvdFaceSums(const CvdEnergy& energy, uint32_t num_faces) {
  std::vector<CvdSums> sums(num_faces);
  for (uint32_t f = 0; f < num_faces; ++f) sums[f] = energy.face_sums(f);
  return sums;
}

absl::Status ReportStartLevel(LevelSink& sink, uint32_t num_faces) {
  std::vector<ClusterId> start(num_faces);
  for (uint32_t f = 0; f < num_faces; ++f) start[f] = ClusterId(f);
  return sink.OnStart(start, num_faces, 0.0);
}

absl::Status MergeLevelReporter::Start(uint32_t num_faces) {
  summary_ = MultilevelSummary();
  summary_.levels = 1;
  summary_.final_clusters = num_faces;
  return ReportStartLevel(sink_, num_faces);
}

absl::Status MergeLevelReporter::Report(uint32_t clusters, std::span<const uint32_t> element,
                                        std::span<const uint32_t> to,
                                        std::span<const uint32_t> from) {
  MLCLUST_RETURN_IF_ERROR(
      SendGpuLevel(element, to, from, summary_.levels, clusters, energy_.value(), sink_));
  summary_.moves += element.size();
  summary_.final_clusters = clusters;
  ++summary_.levels;
  return absl::OkStatus();
}

MultilevelSummary MergeLevelReporter::Finish() {
  summary_.final_energy = energy_.value();
  return summary_;
}

}  // namespace mlclust::gpu
