// How far the energies an algorithm reports are from the energies of its labels (issue 26
// item 7): runs (algorithm, energy) pairs through the registry's run functions, rebuilds
// the labels of every level from the stream, and compares each level's reported energy
// with the energy of those labels from scratch (cluster sums from the faces, the form
// registry_test checks, or the points'
// sums of squares, in one pass over the elements).
//
//   energy_drift (--mesh FILE | --points FILE) [--algos ml,emlo,...] [--energies cvd,...]
//                [--k K] [--options name=value,...] [--seed S]
//
// --algos / --energies: comma lists (default: every algorithm of the input kind, every
// energy each runs); --k: K of single-level algorithms and the lowest level of the
// hierarchies (default 200; 0 = down to one cluster); --options: the algorithm and energy
// options of every run (a pair that refuses one is reported as an error row).
// Prints one CSV row per pair:
//   input,algo,energy,options,levels,max_relative_error,at_level,clusters_there,
//   max_error_of_scale,seconds,checks_seconds
// With E_max the largest energy from labels of the run: max_relative_error = max over the
// levels whose energy is at least 1e-9 E_max of |reported - from labels| / |from labels|;
// max_error_of_scale = max over all levels of |reported - from labels| / E_max (a level of
// single faces, or of flat clusters for planar, has an energy of 0 that sums give as a
// rounding residue, of either sign after the clamp: relative errors there say nothing).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "absl/time/clock.h"
#include "bench/bench_util.h"
#include "core/cluster/point_clustering.h"
#include "core/cluster/registry.h"
#include "core/energy/energies.h"
#include "core/io/points_io.h"
#include "core/io/prepare_mesh.h"
#include "core/plan/device_policy.h"

namespace {

using mlclust::ClusterId;

// Keeps the current labels and checks every level's energy against them.
class DriftSink : public mlclust::LevelSink {
 public:
  explicit DriftSink(std::function<double(const std::vector<ClusterId>&)> energy_of)
      : energy_of_(std::move(energy_of)) {}
  absl::Status OnStart(std::span<const ClusterId> labels, uint32_t cluster_count,
                       double energy) override {
    labels_.assign(labels.begin(), labels.end());
    Check(0, cluster_count, energy);
    return absl::OkStatus();
  }
  absl::Status OnLevel(const mlclust::LevelMoves& level) override {
    for (size_t i = 0; i < level.element.size(); ++i) {
      labels_[level.element[i]] = ClusterId(level.to_cluster[i]);
    }
    Check(level.level, level.cluster_count, level.energy);
    return absl::OkStatus();
  }
  // Fills max_error, at_level and clusters_there from the levels seen.
  void Finish() {
    double scale = 0;
    for (const Seen& seen : seen_) scale = std::max(scale, std::abs(seen.exact));
    for (const Seen& seen : seen_) {
      const double difference = std::abs(seen.reported - seen.exact);
      if (scale > 0) max_error_of_scale = std::max(max_error_of_scale, difference / scale);
      if (std::abs(seen.exact) < 1e-9 * scale || seen.exact == 0) continue;
      const double error = difference / std::abs(seen.exact);
      if (error > max_error) {
        max_error = error;
        at_level = seen.level;
        clusters_there = seen.clusters;
      }
    }
  }
  double max_error = 0, max_error_of_scale = 0;
  uint32_t at_level = 0, clusters_there = 0;
  double check_seconds = 0;
  size_t levels() const { return seen_.size(); }

 private:
  struct Seen {
    uint32_t level, clusters;
    double reported, exact;
  };
  void Check(uint32_t level, uint32_t clusters, double reported) {
    const absl::Time start = absl::Now();
    const double exact = energy_of_(labels_);
    check_seconds += absl::ToDoubleSeconds(absl::Now() - start);
    seen_.push_back({level, clusters, reported, exact});
  }
  std::vector<Seen> seen_;
  std::function<double(const std::vector<ClusterId>&)> energy_of_;
  std::vector<ClusterId> labels_;
};

}  // namespace

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv,
                            "usage: energy_drift (--mesh FILE | --points FILE) [--algos a,b] "
                            "[--energies e,f] [--k K] [--options name=value,...] [--seed S]");
  const std::string mesh_path = args.Get<std::string>("mesh", "");
  const std::string points_path = args.Get<std::string>("points", "");
  const std::string algos = args.Get<std::string>("algos", "");
  const std::string energies = args.Get<std::string>("energies", "");
  const uint32_t k = args.Get<uint32_t>("k", 200);
  const std::string options_text = args.Get<std::string>("options", "");
  const uint64_t seed = args.Get<uint64_t>("seed", 1);
  if (!args.Done()) return 2;
  if (mesh_path.empty() == points_path.empty()) {
    std::fprintf(stderr, "give one of --mesh and --points\n");
    return 2;
  }
  const mlclust::InputKind input =
      mesh_path.empty() ? mlclust::InputKind::kPoints : mlclust::InputKind::kMesh;
  std::vector<std::pair<std::string, std::string>> options;
  for (absl::string_view item : absl::StrSplit(options_text, ',', absl::SkipEmpty())) {
    std::pair<std::string, std::string> option = absl::StrSplit(item, absl::MaxSplits('=', 1));
    options.push_back(option);
  }
  const std::vector<std::string> algo_list = absl::StrSplit(algos, ',', absl::SkipEmpty());
  const std::vector<std::string> energy_list = absl::StrSplit(energies, ',', absl::SkipEmpty());
  auto listed = [](const std::vector<std::string>& list, const std::string& name) {
    return list.empty() || std::find(list.begin(), list.end(), name) != list.end();
  };

  absl::StatusOr<mlclust::PreparedMesh> mesh;
  absl::StatusOr<mlclust::PointSet> points;
  if (input == mlclust::InputKind::kMesh) {
    mesh = mlclust::PrepareMeshFile(mesh_path);
    if (!mesh.ok()) {
      std::fprintf(stderr, "%s\n", mesh.status().ToString().c_str());
      return 1;
    }
  } else {
    points = mlclust::ReadPointsFile(points_path, {});
    if (!points.ok()) {
      std::fprintf(stderr, "%s\n", points.status().ToString().c_str());
      return 1;
    }
  }
  std::printf(
      "input,algo,energy,options,levels,max_relative_error,at_level,clusters_there,"
      "max_error_of_scale,seconds,checks_seconds\n");
  const std::string input_name = input == mlclust::InputKind::kMesh ? mesh_path : points_path;
  const std::string options_column = absl::StrJoin(
      options, " ", [](std::string* out, const auto& o) { *out += o.first + "=" + o.second; });
  for (const mlclust::AlgorithmInfo& algorithm : mlclust::Algorithms()) {
    if (algorithm.input != input || !listed(algo_list, algorithm.name)) continue;
    for (const std::string& energy_name : algorithm.energies) {
      if (!listed(energy_list, energy_name)) continue;
      mlclust::JobRequest request;
      request.algorithm = &algorithm;
      request.energy = mlclust::FindEnergy(input, energy_name);
      request.clusters = k;
      request.seed = seed;
      request.options = options;
      absl::StatusOr<mlclust::JobPlan> plan = mlclust::PlanJob(request);
      absl::Status status = plan.status();
      if (status.ok()) status = mlclust::PlanDevices(mlclust::DeviceCaps{}, *plan);
      if (!status.ok()) {
        std::printf("%s,%s,%s,%s,ERROR %s\n", input_name.c_str(), algorithm.name.c_str(),
                    energy_name.c_str(), options_column.c_str(),
                    std::string(status.message()).c_str());
        continue;
      }
      const absl::Time start = absl::Now();
      double check_seconds = 0;
      DriftSink* result = nullptr;
      std::unique_ptr<DriftSink> sink;
      if (input == mlclust::InputKind::kMesh) {
        status = mlclust::WithMeshEnergy(
            plan->mesh_energy, mesh->mesh, mesh->measures, [&](const auto& energy) {
              sink = std::make_unique<DriftSink>([&energy](const std::vector<ClusterId>& labels) {
                return mlclust::EnergyFromSums(energy, labels);
              });
              const mlclust::MeshProblem problem{&mesh->mesh, &mesh->adjacency, &mesh->measures,
                                                 plan->mesh_energy};
              return algorithm.run_mesh(problem, *plan, *sink, {}).status();
            });
      } else {
        sink = std::make_unique<DriftSink>([&](const std::vector<ClusterId>& labels) {
          return mlclust::PointEnergy(*points, labels);
        });
        status = algorithm.run_points(*points, *plan, *sink, {}).status();
      }
      result = sink.get();
      result->Finish();
      check_seconds = result->check_seconds;
      const double seconds = absl::ToDoubleSeconds(absl::Now() - start) - check_seconds;
      if (!status.ok()) {
        std::printf("%s,%s,%s,%s,ERROR %s\n", input_name.c_str(), algorithm.name.c_str(),
                    energy_name.c_str(), options_column.c_str(), status.ToString().c_str());
        continue;
      }
      std::printf("%s,%s,%s,%s,%zu,%.3g,%u,%u,%.3g,%.3f,%.3f\n", input_name.c_str(),
                  algorithm.name.c_str(), energy_name.c_str(), options_column.c_str(),
                  result->levels(), result->max_error, result->at_level, result->clusters_there,
                  result->max_error_of_scale, seconds, check_seconds);
      std::fflush(stdout);
    }
  }
  return 0;
}
