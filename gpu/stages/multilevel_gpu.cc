#include "gpu/stages/multilevel_gpu.h"

#include <algorithm>
#include <array>
#include <functional>
#include <span>
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
#include "gpu/stages/hierarchy_gpu.h"
#include "gpu/stages/mesh_levels_gpu.h"

namespace mlclust::gpu {
namespace {

// BB sweeps after a level's merges at most (a PML level, or an ML step: the same driver,
// RunLevelsWithBoundaryBased). Alg. 5.4 sweeps until no face moves; on fandisk (PML `all`
// to 20 clusters) a cap of 8, the CPU engine's local BB's, ended 10% above the CPU
// engine's energy, 32 1% above, 64 and 100 3% below, 1000 the same as 100 (measured with
// PML only).
constexpr uint32_t kPmlBbMaxSweeps = 64;

// The GPU's labels at `level` to options.inspect_level (tests), if set.
absl::Status InspectGpuLabels(const MultilevelOptions& options, PmlLevelsGpu& levels,
                              size_t level) {
  if (!options.inspect_level) return absl::OkStatus();
  MLCLUST_ASSIGN_OR_RETURN(const std::vector<uint32_t> labels, levels.Labels());
  options.inspect_level(level, labels);
  return absl::OkStatus();
}

// One level's merges on the GPU (PML's mutual pairs, or ML's one cheapest pair) at
// `clusters` clusters: false where none is left.
using MergeLevel = std::function<absl::StatusOr<bool>(PmlLevelsGpu& levels, uint32_t clusters,
                                                      PmlLevelGpu& level)>;

// Alg. 5.7 and 5.6: levels of merges on the GPU (PML's, or ML's one collapse), each
// followed by BB sweeps (Alg. 5.4) whose decide runs on the GPU and whose conflict rule and
// moves are the CPU stage's own (boundary_based::ResolveConflicts, ApplyMoves, UndoMoves)
// on a host Partition that mirrors the GPU's labels, sizes and sums; the level's moves go
// through the CPU engine's LevelRecorder, so the triplets and the energy are kept as the
// CPU engine keeps them.
absl::StatusOr<MultilevelSummary> RunLevelsWithBoundaryBased(
    GlContext& context, const MeshProblem& problem, const MultilevelOptions& options,
    const CvdEnergy& energy, const MergeLevel& merge_level, LevelSink& sink) {
  const FaceAdjacency& adjacency = *problem.adjacency;
  const uint32_t n = static_cast<uint32_t>(problem.mesh->num_faces());
  std::vector<PointAndWeight> points(n);
  for (uint32_t f = 0; f < n; ++f) points[f] = ProxyPointForm<CvdEnergy>::Face(energy, f);
  MLCLUST_ASSIGN_OR_RETURN(PmlLevelsGpu levels,
                           PmlLevelsGpu::Create(context, CvdFaceSums(energy, n), adjacency));
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
  MLCLUST_RETURN_IF_ERROR(ReportStartLevel(sink, n));
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
    MLCLUST_ASSIGN_OR_RETURN(const bool merged, merge_level(levels, clusters, level));
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
        return absl::InternalError(absl::StrCat("the GPU's level ", summary.levels, " merges ",
                                                members.size(), " faces of cluster ", gone, " (",
                                                partition.size(gone), " on the host) into ", keep));
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

absl::StatusOr<MultilevelSummary> RunParallelMultilevelGpu(GlContext& context,
                                                           const MeshProblem& problem,
                                                           const MultilevelOptions& options,
                                                           LevelSink& sink) {
  return WithCvdLevelsProblem(
      problem, options, "PML", PmlGpuUnsupported(options, problem.energy.kind),
      [&](const CvdEnergy& energy) -> absl::StatusOr<MultilevelSummary> {
        if (options.optimizer == MultilevelOptions::Optimizer::kBoundaryBased) {
          const MergeLevel pml_level = [&](PmlLevelsGpu& levels, uint32_t clusters,
                                           PmlLevelGpu& level) {
            return levels.Level(options.pml_pairs, clusters, options.min_clusters, level);
          };
          return RunLevelsWithBoundaryBased(context, problem, options, energy, pml_level, sink);
        }
        const uint32_t n = static_cast<uint32_t>(problem.mesh->num_faces());
        MLCLUST_ASSIGN_OR_RETURN(
            PmlLevelsGpu levels,
            PmlLevelsGpu::Create(context, CvdFaceSums(energy, n), *problem.adjacency));
        MergeLevelReporter reporter(sink);
        MLCLUST_RETURN_IF_ERROR(reporter.Start(n));
        uint32_t clusters = n;
        PmlLevelGpu level;
        while (clusters > options.min_clusters) {
          MLCLUST_RETURN_IF_ERROR(
              CheckCancelled(options.cancel, absl::StrCat("level ", reporter.next_level())));
          MLCLUST_ASSIGN_OR_RETURN(const bool merged, levels.Level(options.pml_pairs, clusters,
                                                                   options.min_clusters, level));
          if (!merged) break;  // one cluster per component
          clusters -= level.merged;
          reporter.AddChange(level.energy_change);
          MLCLUST_RETURN_IF_ERROR(
              reporter.Report(clusters, level.element, level.to_cluster, level.from_cluster));
        }
        return reporter.Finish();
      });
}

absl::StatusOr<MultilevelSummary> RunMultilevelGpu(GlContext& context, const MeshProblem& problem,
                                                   const MultilevelOptions& options,
                                                   LevelSink& sink) {
  if (options.optimizer == MultilevelOptions::Optimizer::kNone) {
    return RunHierarchyGpu(context, problem, options, sink);  // HC's steps: the same levels
  }
  return WithCvdLevelsProblem(
      problem, options, "ML", MlGpuUnsupported(options, problem.energy.kind),
      [&](const CvdEnergy& energy) {
        // One merge per level, down to options.min_clusters (the driver stops there).
        const MergeLevel ml_step = [&](PmlLevelsGpu& levels, uint32_t /*clusters*/,
                                       PmlLevelGpu& level) {
          return levels.Step(options.ties_to_fewest_faces, level);
        };
        return RunLevelsWithBoundaryBased(context, problem, options, energy, ml_step, sink);
      });
}

}  // namespace mlclust::gpu
