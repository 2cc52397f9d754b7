#include "gpu/stages/multilevel_gpu.h"

#include <algorithm>
#include <array>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/compensated_sum.h"
#include "core/base/status_macros.h"
#include "core/cluster/boundary_based.h"
#include "core/cluster/partition.h"
#include "core/hierarchy/level_recorder.h"
#include "core/mesh/connectivity_guard.h"
#include "gpu/kernels/bb_decide.h"
#include "gpu/kernels/pml_levels.h"
#include "gpu/stages/gpu_level_sink.h"

namespace mlclust::gpu {
namespace {

// BB sweeps after a PML level at most. Alg. 5.4 sweeps until no face moves; on fandisk
// (PML `all` to 20 clusters) a cap of 8, the CPU engine's local BB's, ended 10% above the
// CPU engine's energy, 32 1% above, 64 and 100 3% below, 1000 the same as 100.
constexpr uint32_t kPmlBbMaxSweeps = 64;

// The GPU's labels at `level` to options.inspect_level (tests), if set.
absl::Status InspectGpuLabels(const MultilevelOptions& options, PmlLevelsGpu& levels,
                              size_t level) {
  if (!options.inspect_level) return absl::OkStatus();
  MLCLUST_ASSIGN_OR_RETURN(const std::vector<uint32_t> labels, levels.Labels());
  options.inspect_level(level, labels);
  return absl::OkStatus();
}

// Alg. 5.7: PML levels on the GPU, each followed by BB sweeps (Alg. 5.4) whose decide
// runs on the GPU and whose conflict rule and moves are the CPU stage's own
// (boundary_based::ResolveConflicts, ApplyMoves, UndoMoves) on a host Partition that
// mirrors the GPU's labels, sizes and sums; the level's moves go through the CPU engine's
// LevelRecorder, so the triplets and the energy are kept as the CPU engine keeps them.
absl::StatusOr<MultilevelSummary> RunPmlWithBoundaryBased(GlContext& context,
                                                          const MeshProblem& problem,
                                                          const MultilevelOptions& options,
                                                          const CvdEnergy& energy,
                                                          LevelSink& sink) {
  const FaceAdjacency& adjacency = *problem.adjacency;
  const uint32_t n = static_cast<uint32_t>(problem.mesh->num_faces());
  std::vector<CvdSums> face_sums(n);
  std::vector<PointAndWeight> points(n);
  for (uint32_t f = 0; f < n; ++f) {
    face_sums[f] = energy.face_sums(f);
    points[f] = ProxyPointForm<CvdEnergy>::Face(energy, f);
  }
  MLCLUST_ASSIGN_OR_RETURN(PmlLevelsGpu levels,
                           PmlLevelsGpu::Create(context, face_sums, adjacency));
  MLCLUST_RETURN_IF_ERROR(levels.EnableBoundaryOptimisation(adjacency, points));
  // The ring structure always: the conflict rule reads it whatever the guard (as
  // OptimizeBoundaryBased).
  MLCLUST_ASSIGN_OR_RETURN(const ConnectivityGuard guard,
                           ConnectivityGuard::Build(*problem.mesh, adjacency, options.cancel));
  const bool check_connectivity =
      options.connectivity_guard && options.guard == ConnectivityGuardKind::kRingTest;
  const boundary_based::StageThreads threads(options.threads);
  std::vector<uint32_t> identity(n);
  for (uint32_t f = 0; f < n; ++f) identity[f] = f;
  Partition<CvdEnergy> partition(energy, identity, n);
  LevelRecorder recorder(n, n);
  recorder.Reset(0.0);
  auto energy_of = [&](uint32_t c) { return partition.cluster_energy(c); };
  {
    std::vector<ClusterId> start(n);
    for (uint32_t f = 0; f < n; ++f) start[f] = ClusterId(f);
    MLCLUST_RETURN_IF_ERROR(sink.OnStart(start, n, 0.0));
  }
  MLCLUST_RETURN_IF_ERROR(InspectGpuLabels(options, levels, 0));
  MultilevelSummary summary;
  summary.levels = 1;
  uint32_t clusters = n;
  PmlLevelGpu level;
  std::vector<std::array<uint32_t, 3>> gone_faces;  // (gone, face, keep)
  std::vector<uint32_t> members;
  std::vector<PmlFaceMove> proposals, moved;
  std::vector<uint32_t> target(n, boundary_based::kNoMove), accepted, swept;
  std::vector<uint8_t> swept_mark(n, 0);
  std::vector<double> swept_before;
  std::vector<boundary_based::AppliedMove> applied;
  std::vector<PmlClusterChange> changes;
  boundary_based::ConflictScratch scratch;
  while (clusters > options.min_clusters) {
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, absl::StrCat("level ", summary.levels)));
    MLCLUST_ASSIGN_OR_RETURN(
        const bool merged, levels.Level(options.pml_pairs, clusters, options.min_clusters, level));
    if (!merged) break;  // one cluster per component
    clusters -= level.merged;
    // The level's merges on the host, recorded as the CPU engine records them: the faces
    // of each gone cluster (the GPU's triplets: face, keep, gone) into its kept cluster.
    gone_faces.resize(level.element.size());
    for (size_t i = 0; i < level.element.size(); ++i) {
      gone_faces[i] = {level.from_cluster[i], level.element[i], level.to_cluster[i]};
    }
    std::sort(gone_faces.begin(), gone_faces.end());
    uint32_t pairs = 0;
    for (size_t i = 0; i < gone_faces.size();) {
      const uint32_t gone = gone_faces[i][0], keep = gone_faces[i][2];
      members.clear();
      for (; i < gone_faces.size() && gone_faces[i][0] == gone; ++i) {
        members.push_back(gone_faces[i][1]);
        recorder.RecordMove(gone_faces[i][1], gone);
      }
      recorder.Touch(keep, energy_of);
      recorder.Touch(gone, energy_of);
      if (members.size() != partition.size(gone) || partition.size(keep) == 0) {
        return absl::InternalError(absl::StrCat(
            "PML on the GPU: level ", summary.levels, " merges ", members.size(),
            " faces of cluster ", gone, " (", partition.size(gone), " on the host) into ", keep));
      }
      partition.MergeUncounted(keep, gone, members);
      ++pairs;
    }
    partition.CountMerges(pairs);
    // minimizeEnergy() (Alg. 5.4): BB sweeps over every face, each the CPU stage's
    // resolve and apply on the GPU's decisions, until none moves (at most kPmlBbMaxSweeps).
    bool moved_any = false;
    for (uint32_t sweep = 0; sweep < kPmlBbMaxSweeps; ++sweep) {
      MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "BB decide moves"));
      MLCLUST_RETURN_IF_ERROR(levels.Decide(proposals));
      if (proposals.empty()) break;
      for (const auto& [face, to] : proposals) target[face] = to;
      boundary_based::ResolveConflicts(guard, check_connectivity, partition.labels(),
                                       partition.sizes(), target, threads, scratch, accepted);
      // The clusters the sweep may change, with their energies before it.
      swept.clear();
      swept_before.clear();
      auto note = [&](uint32_t c) {
        if (swept_mark[c]) return;
        swept_mark[c] = 1;
        swept.push_back(c);
        swept_before.push_back(partition.cluster_energy(c));
      };
      for (const uint32_t f : accepted) {
        note(partition.label(f));
        note(target[f]);
      }
      for (const uint32_t c : swept) recorder.Touch(c, energy_of);
      boundary_based::ApplyMoves(partition, accepted, target, applied);
      for (const auto& [face, to] : proposals) target[face] = boundary_based::kNoMove;
      for (const uint32_t c : swept) swept_mark[c] = 0;
      if (applied.empty()) break;
      // A sweep that raises the energy is undone and ends the optimisation (as
      // RunBoundaryBased; with fitted CVD proxies only rounding can do it).
      ::mlclust::detail::CompensatedSum change;
      change.Reset(0);
      for (size_t i = 0; i < swept.size(); ++i) {
        change.Add(partition.cluster_energy(swept[i]) - swept_before[i]);
      }
      if (change.value() > 0) {
        boundary_based::UndoMoves(partition, std::span<const boundary_based::AppliedMove>(applied));
        break;
      }
      moved.clear();
      for (const boundary_based::AppliedMove& move : applied) {
        recorder.RecordMove(move.face, move.from);
        moved.push_back({move.face, partition.label(move.face)});
      }
      changes.clear();
      for (const uint32_t c : swept) {
        changes.push_back({c, partition.size(c), partition.sums(c)});
      }
      MLCLUST_RETURN_IF_ERROR(levels.ApplyMoves(moved, changes));
      summary.optimisation_moves += applied.size();
      moved_any = true;
    }
    if (moved_any) MLCLUST_RETURN_IF_ERROR(levels.RebuildEdges());
    recorder.Squash(
        energy_of, [&](uint32_t f) { return partition.label(f); }, [](uint32_t f) { return f; });
    MLCLUST_RETURN_IF_ERROR(recorder.Emit(sink, summary.levels, clusters));
    MLCLUST_RETURN_IF_ERROR(InspectGpuLabels(options, levels, summary.levels));
    ++summary.levels;
  }
  summary.moves = recorder.moves();
  summary.final_clusters = clusters;
  summary.final_energy = recorder.energy();
  return summary;
}

}  // namespace

std::string PmlGpuUnsupported(const MultilevelOptions& options, MeshEnergyKind energy) {
  if (!options.parallel) return "only PML (parallel levels) runs on the GPU";
  if (energy != MeshEnergyKind::kCvd && energy != MeshEnergyKind::kCvdAdaptive) {
    return "the GPU has the merge cost of cvd and cvd-adaptive only";
  }
  if (options.optimizer == MultilevelOptions::Optimizer::kEmlo) {
    return "the GPU's PML optimises with BB (optimizer bb) or not at all (none), not EMLO";
  }
  if (options.optimizer == MultilevelOptions::Optimizer::kBoundaryBased &&
      options.connectivity_guard &&
      options.guard == ConnectivityGuardKind::kVertexBoundaryEdgeCount) {
    return "the GPU's PML with BB checks moves with the ring test or not at all, not "
           "vertex-count";
  }
  if (options.p_percent != 0) return "p-percent is not on the GPU";
  if (options.pml_until != 0) return "pml-until (the switch to ML) is not on the GPU";
  return "";
}

absl::StatusOr<MultilevelSummary> RunParallelMultilevelGpu(GlContext& context,
                                                           const MeshProblem& problem,
                                                           const MultilevelOptions& options,
                                                           LevelSink& sink) {
  if (problem.mesh == nullptr || problem.adjacency == nullptr || problem.measures == nullptr) {
    return absl::InvalidArgumentError("mesh problem without mesh, adjacency or measures");
  }
  MLCLUST_RETURN_IF_ERROR(ValidateMeshEnergyOptions(problem.energy));
  if (options.min_clusters < 1) {
    return absl::InvalidArgumentError("clusters: the lowest level must have at least 1");
  }
  const std::string unsupported = PmlGpuUnsupported(options, problem.energy.kind);
  if (!unsupported.empty())
    return absl::UnimplementedError(absl::StrCat("PML on the GPU: ", unsupported));
  MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "PML set-up"));
  return WithMeshEnergy(
      problem.energy, *problem.mesh, *problem.measures,
      [&](const auto& energy) -> absl::StatusOr<MultilevelSummary> {
        using Energy = std::decay_t<decltype(energy)>;
        if constexpr (!std::is_same_v<Energy, CvdEnergy>) {
          return absl::UnimplementedError("PML on the GPU: not a CVD energy");
        } else if (options.optimizer == MultilevelOptions::Optimizer::kBoundaryBased) {
          return RunPmlWithBoundaryBased(context, problem, options, energy, sink);
        } else {
          const uint32_t n = static_cast<uint32_t>(problem.mesh->num_faces());
          std::vector<CvdSums> face_sums(n);
          for (uint32_t f = 0; f < n; ++f) face_sums[f] = energy.face_sums(f);
          MLCLUST_ASSIGN_OR_RETURN(PmlLevelsGpu levels,
                                   PmlLevelsGpu::Create(context, face_sums, *problem.adjacency));
          std::vector<ClusterId> start(n);
          for (uint32_t f = 0; f < n; ++f) start[f] = ClusterId(f);
          MLCLUST_RETURN_IF_ERROR(sink.OnStart(start, n, 0.0));
          MultilevelSummary summary;
          summary.levels = 1;
          ::mlclust::detail::CompensatedSum energy_sum;
          energy_sum.Reset(0);
          uint32_t clusters = n;
          PmlLevelGpu level;
          while (clusters > options.min_clusters) {
            MLCLUST_RETURN_IF_ERROR(
                CheckCancelled(options.cancel, absl::StrCat("level ", summary.levels)));
            MLCLUST_ASSIGN_OR_RETURN(const bool merged, levels.Level(options.pml_pairs, clusters,
                                                                     options.min_clusters, level));
            if (!merged) break;  // one cluster per component
            clusters -= level.merged;
            energy_sum.Add(level.energy_change);
            MLCLUST_RETURN_IF_ERROR(
                SendGpuLevel(level, summary.levels, clusters, energy_sum.value(), sink));
            summary.moves += level.element.size();
            ++summary.levels;
          }
          summary.final_clusters = clusters;
          summary.final_energy = energy_sum.value();
          return summary;
        }
      });
}

}  // namespace mlclust::gpu
