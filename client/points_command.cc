// `mlclust points`: reads a point set, sends it (float32), receives every level and writes
// the outputs of the level chosen (--clusters K or --auto-k).
#include <cstdio>
#include <filesystem>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "client/commands.h"
#include "client/job_cli.h"
#include "core/io/points_io.h"

namespace mlclust::cli {
namespace {

int RunPoints(const Arguments& args) {
  if (args.positional().size() != 1) {
    return Fail(absl::InvalidArgumentError("points: give exactly one INPUT file"));
  }
  const std::string& input_path = args.positional()[0];
  absl::StatusOr<uint64_t> clusters = args.GetUint("clusters", 0, UINT32_MAX);
  absl::StatusOr<uint64_t> dims = args.GetUint("dims", 0);
  absl::StatusOr<uint64_t> seed = args.GetUint("seed", 1);
  for (const auto* value : {&clusters, &dims, &seed}) {
    if (!value->ok()) return Fail(value->status());
  }
  absl::StatusOr<const AlgorithmInfo*> algorithm = GetAlgorithm(args, InputKind::kPoints);
  if (!algorithm.ok()) return Fail(algorithm.status());
  const std::string algo = (*algorithm)->name;
  const bool hierarchy = (*algorithm)->hierarchy;
  const std::string auto_k = args.get("auto-k", "");
  if (!auto_k.empty() && auto_k != "bic" && auto_k != "bic-first-decrease" && auto_k != "elbow") {
    return Fail(absl::InvalidArgumentError("--auto-k must be bic, bic-first-decrease or elbow"));
  }
  if (!auto_k.empty() && !hierarchy) {
    return Fail(
        absl::InvalidArgumentError("--auto-k needs a hierarchy: --algo ml, pml, hc or bisecting"));
  }
  // Bisecting k-means: a hierarchy whose top, K, is --clusters. X-means: --clusters is k_min
  // and the result (the last level) has the K it found.
  const bool divisive = (*algorithm)->divisive;
  const bool chooses_k = (*algorithm)->chooses_k;
  // LN k-means or k-means from the voxel grid: one cluster per occupied cell, no K.
  const bool grid_start =
      (algo == "lnkmeans" || algo == "kmeans") && args.get("init", "") == "grid";
  if (grid_start && *clusters != 0) {
    return Fail(absl::InvalidArgumentError(
        "--clusters: --init grid starts from one cluster per occupied voxel (--grid A)"));
  }
  if ((!hierarchy || divisive) && !grid_start && *clusters == 0) {
    return Fail(absl::InvalidArgumentError(
        absl::StrCat("--clusters: ", algo, " needs K >= 1", chooses_k ? " (k_min)" : "")));
  }
  if (args.has("labels") && *clusters == 0 && auto_k.empty() && !grid_start) {
    return Fail(absl::InvalidArgumentError("--labels needs --clusters K or --auto-k"));
  }
  if (*dims > 4096) return Fail(absl::InvalidArgumentError("--dims: over 4096"));

  PointReadOptions read;
  read.dims = static_cast<uint32_t>(*dims);
  absl::StatusOr<PointSet> points = ReadPointsFile(input_path, read);
  if (!points.ok()) return Fail(points.status());
  if (*clusters > points->num_points()) {
    return Fail(absl::InvalidArgumentError(absl::StrCat(
        "--clusters: ", *clusters, " is more than the ", points->num_points(), " points")));
  }

  v1::JobSpec spec;
  spec.set_input_kind(v1::INPUT_KIND_POINTS_F32);
  spec.set_point_dims(points->dims);
  spec.set_algorithm(static_cast<v1::Algorithm>((*algorithm)->wire));
  spec.set_energy(v1::ENERGY_VARIANCE);
  spec.set_label(input_path);
  spec.set_seed(*seed);
  spec.set_device(args.get("device", "auto"));
  if (!hierarchy || divisive) spec.set_clusters(static_cast<uint32_t>(*clusters));
  if (absl::Status status = SetLevels(args, hierarchy, spec); !status.ok()) return Fail(status);
  SetOptions(args, InputKind::kPoints, spec);
  const std::string payload(reinterpret_cast<const char*>(points->values.data()),
                            points->values.size() * sizeof(float));
  if (args.has("detach")) return Detach(args, spec, payload);
  double seconds = 0;
  absl::StatusOr<client::JobResult> result = RunOnServer(
      args, spec, payload, &seconds, nullptr,
      auto_k.empty() && !grid_start && !chooses_k ? static_cast<uint32_t>(*clusters) : 0);
  if (!result.ok()) return Fail(result.status());
  const HierarchyLog& log = result->hierarchy;
  if (absl::Status s =
          WriteLevelOutputs(args, *result, points->num_points(), "points",
                            absl::StrCat(std::filesystem::path(input_path).filename().string(),
                                         ": ", algo, ", variance"));
      !s.ok()) {
    return Fail(s);
  }
  // The level to write: --clusters K, or the one --auto-k chooses.
  std::optional<size_t> level;
  std::string chosen;
  if (auto_k == "elbow") {
    if (result->done.elbow_cluster_counts().empty()) {
      return Fail(absl::NotFoundError(
          "--auto-k elbow: the energy curve has no jump (ours for points; try --auto-k bic)"));
    }
    const uint32_t k = result->done.elbow_cluster_counts(0);
    level = log.LastLevelWith(k);
    chosen = absl::StrCat("; elbow at ", k, " clusters");
  } else if (auto_k == "bic") {
    // The server scores every level of the hierarchy (Done's BIC fields).
    const uint32_t k = result->done.bic_best_cluster_count();
    if (k == 0) return Fail(absl::NotFoundError("--auto-k bic: the server sent no BIC"));
    level = log.LastLevelWith(k);
    if (!level.has_value()) {
      return Fail(
          absl::NotFoundError(absl::StrCat("--auto-k bic: the BIC is highest at ", k,
                                           " clusters, a level outside the range that was sent")));
    }
    chosen = absl::StrCat("; BIC highest at ", k, " clusters, first decrease after ",
                          result->done.bic_first_decrease_cluster_count());
  } else if (auto_k == "bic-first-decrease") {
    // Section 6.6's rule: the level before the BIC first falls as the hierarchy merges.
    const uint32_t k = result->done.bic_merging_first_decrease_cluster_count();
    if (k == 0) {
      return Fail(absl::NotFoundError("--auto-k bic-first-decrease: the server sent no BIC"));
    }
    level = log.LastLevelWith(k);
    if (!level.has_value()) {
      return Fail(absl::NotFoundError(
          absl::StrCat("--auto-k bic-first-decrease: the BIC first falls after ", k,
                       " clusters, a level outside the range that was sent")));
    }
    chosen = absl::StrCat("; merging stops where the BIC first falls (section 6.6): ", k,
                          " clusters; BIC highest at ", result->done.bic_best_cluster_count());
  } else if (grid_start || chooses_k) {
    level = log.num_levels() - 1;
  } else if (*clusters > 0) {
    absl::StatusOr<size_t> by_k = ChooseLevel(log, static_cast<uint32_t>(*clusters));
    if (!by_k.ok()) return Fail(by_k.status());
    level = *by_k;
  }
  std::string level_note;
  if (level.has_value()) {
    absl::StatusOr<std::vector<ClusterId>> labels = LabelsOfLevel(*result, *level);
    if (!labels.ok()) return Fail(labels.status());
    if (args.has("labels")) {
      if (absl::Status s = WriteLabels(args.get("labels"), client::CompactLabels(*labels));
          !s.ok()) {
        return Fail(s);
      }
    }
    level_note = absl::StrFormat("; level %zu: %u clusters, energy %.10g", *level,
                                 log.cluster_count(*level), log.energy(*level));
  }
  if (args.has("json")) {
    std::printf("%s\n", SummaryJson(args, input_path, "points", points->num_points(), **algorithm,
                                    spec, log, seconds, result->done, level, auto_k)
                            .c_str());
    return 0;
  }
  std::printf("%s: %zu points in %u dimensions, %zu levels, %zu triplets in %.3f s (%s)%s%s%s\n",
              input_path.c_str(), points->num_points(), points->dims, log.num_levels(),
              log.num_moves(), seconds, args.has("server") ? "remote" : "embedded",
              level_note.c_str(), chosen.c_str(), ElbowNote(result->done).c_str());
  return 0;
}

}  // namespace

Command PointsCommand() {
  const std::vector<Flag> own = {
      {"dims", "D", "raw float32 input (.f32/.bin/.raw): the number of coordinates per point"},
      {"clusters", "K",
       "single-level algorithms: K; bisecting: the top of its hierarchy; xmeans: k_min, and "
       "--labels writes the K it found; hierarchies: the level written by --labels",
       'k'},
      {"auto-k", "bic|bic-first-decrease|elbow",
       "hierarchies: --labels writes the level with the highest BIC, "
       "the level where merging stops as the BIC first falls (section 6.6 offers both; the "
       "stopping rule of l. 2798), or the first elbow"},
      {"labels", "FILE", "one line per point: its cluster (0..K-1) at that level", 'o'},
      {"levels-csv", "FILE", "a row \"clusters,energy\" per level received"},
      {"plot", "FILE.png",
       "the energy of every level against its clusters (log axes; the energy's linear where it "
       "spans under three decades), the elbows and the level written marked"}};
  return {{"points",
           "INPUT [--dims D] [--server ADDR] [--algo ALGO] [--clusters K | --auto-k bic|...]\n"
           "                       [--labels FILE] [--levels-csv FILE] [--seed S] [--levels "
           "K_HI:K_LO]\n"
           "                       [--device auto|gpu|cpu] [--quiet] [--json] [algorithm options]",
           "Clusters the points of INPUT: .npy (float32/float64, m x d), .csv/.txt, or raw "
           "float32 (.f32/.bin/.raw, with --dims D). Hierarchies give every level from the "
           "voxel-grid start to one cluster; single-level algorithms one K.",
           JobFlagGroups(InputKind::kPoints, own)},
          RunPoints};
}

}  // namespace mlclust::cli
