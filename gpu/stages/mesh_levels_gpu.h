// What the GPU's mesh hierarchies share (HC: hierarchy_gpu.h; PML and ML:
// multilevel_gpu.h): the problem's checks before the first level, the CVD energy they run
// on, the start (one cluster per face, energy 0), and the levels of merges only (HC, PML
// with optimizer none) as the CPU engine reports them.
#ifndef MLCLUST_GPU_STAGES_MESH_LEVELS_GPU_H_
#define MLCLUST_GPU_STAGES_MESH_LEVELS_GPU_H_

#include <cstdint>
#include <span>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "core/base/cancel.h"
#include "core/base/compensated_sum.h"
#include "core/base/status_macros.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/multilevel.h"
#include "core/energy/energies.h"
#include "core/hierarchy/hierarchy.h"

namespace mlclust::gpu {

// RunMultilevel's checks (the problem's parts, the energy's options, at least 1 cluster),
// then UNIMPLEMENTED "<what> on the GPU: <unsupported>" where `unsupported` is not empty or
// the problem has polygons (problem.polygons: per-polygon clustering; nothing reported), CANCELLED
// if options.cancel is set, and `run(const CvdEnergy&)` for the CVD energies (UNIMPLEMENTED for the
// others).
template <typename Run>
absl::StatusOr<MultilevelSummary> WithCvdLevelsProblem(const MeshProblem& problem,
                                                       const MultilevelOptions& options,
                                                       absl::string_view what,
                                                       const std::string& unsupported, Run&& run) {
  if (problem.mesh == nullptr || problem.adjacency == nullptr || problem.measures == nullptr) {
    return absl::InvalidArgumentError("mesh problem without mesh, adjacency or measures");
  }
  MLCLUST_RETURN_IF_ERROR(ValidateMeshEnergyOptions(problem.energy));
  if (options.min_clusters < 1) {
    return absl::InvalidArgumentError("clusters: the lowest level must have at least 1");
  }
  if (!unsupported.empty()) {
    return absl::UnimplementedError(absl::StrCat(what, " on the GPU: ", unsupported));
  }
  if (problem.polygons != nullptr) {
    return absl::UnimplementedError(absl::StrCat(what, " on the GPU: polygons stay on the CPU"));
  }
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, absl::StrCat(what, " set-up")));
  return WithMeshEnergy(
      problem.energy, *problem.mesh, *problem.measures,
      [&](const auto& energy) -> absl::StatusOr<MultilevelSummary> {
        using Energy = std::decay_t<decltype(energy)>;
        if constexpr (!std::is_same_v<Energy, CvdEnergy>) {
          return absl::UnimplementedError(absl::StrCat(what, " on the GPU: not a CVD energy"));
        } else {
          return std::forward<Run>(run)(energy);
        }
      });
}

// Every face's sums (CvdEnergy::face_sums), the GPU levels' input.
std::vector<CvdSums> CvdFaceSums(const CvdEnergy& energy, uint32_t num_faces);

// Level 0 to `sink`: one cluster per face, energy 0.
absl::Status ReportStartLevel(LevelSink& sink, uint32_t num_faces);

// Levels of merges only to a sink as the CPU engine reports them: level 0 at construction
// (Start), then per level its triplets and the energy, a compensated sum of every merge's
// changes (E after - E before of the kept and the gone cluster) in the order added.
class MergeLevelReporter {
 public:
  explicit MergeLevelReporter(LevelSink& sink) : sink_(sink) { energy_.Reset(0); }

  absl::Status Start(uint32_t num_faces);
  // Adds a merge's energy changes to the running energy (before its Report).
  void AddChange(double change) { energy_.Add(change); }
  // The next level: `clusters` left after it, its triplets (element, to, from).
  absl::Status Report(uint32_t clusters, std::span<const uint32_t> element,
                      std::span<const uint32_t> to, std::span<const uint32_t> from);
  // The number the next Report gives its level (1 after Start): for cancellation messages.
  uint32_t next_level() const { return summary_.levels; }
  // The summary after the last level.
  MultilevelSummary Finish();

 private:
  LevelSink& sink_;
  ::mlclust::detail::CompensatedSum energy_;
  MultilevelSummary summary_;
};

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_STAGES_MESH_LEVELS_GPU_H_
