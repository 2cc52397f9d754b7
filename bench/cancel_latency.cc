// How quickly each long call returns CANCELLED once its cancel flag is set.
//
//   cancel_latency MESH [--after S] [--k K] [--repeats R] [--only NAME] [--header]
//
// For every step (set-up, seeding, EMLO, BB, VSA, coarsening, k-means over the mesh's
// vertices): runs it once to completion (solo_s), then R times with another thread setting
// the flag S seconds into the call (default: half the solo time, so the flag lands in the
// middle of the work) and reports the worst time from setting the flag to the call's
// return. A call that finishes before the flag is set counts as "finished" instead.
// Prints CSV: step,faces,solo_s,after_s,worst_latency_s,mean_latency_s,cancelled,finished
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "bench/bench_util.h"
#include "bench/cancel_timer.h"
#include "core/cluster/kmeans.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/vsa.h"
#include "core/coarsening/coarsening.h"
#include "core/io/mesh_io.h"
#include "core/io/prepare_mesh.h"
#include "core/points/points.h"

namespace mlclust {
namespace {

struct Step {
  std::string name;
  // Runs the step with the given flag; OK when it finished, CANCELLED when it stopped.
  std::function<absl::Status(const std::atomic<bool>*)> run;
};

struct Latency {
  double worst = 0, sum = 0;
  int cancelled = 0, finished = 0, failed = 0;
};

Latency Measure(const Step& step, double after, int repeats) {
  Latency latency;
  for (int r = 0; r < repeats; ++r) {
    bench::CancelTimer timer(after);
    const absl::Status status = step.run(timer.flag());
    const bench::CancelTimer::Outcome outcome = timer.Finish();
    if (status.ok()) {
      ++latency.finished;
    } else if (absl::IsCancelled(status) && outcome.flag_set) {
      ++latency.cancelled;
      latency.worst = std::max(latency.worst, outcome.latency_s);
      latency.sum += outcome.latency_s;
    } else {
      ++latency.failed;
      std::fprintf(stderr, "%s: %s\n", step.name.c_str(), status.ToString().c_str());
    }
  }
  return latency;
}

}  // namespace
}  // namespace mlclust

int main(int argc, char** argv) {
  using namespace mlclust;
  bench::Args args(argc, argv,
                   "usage: cancel_latency MESH [--after S] [--k K] [--repeats R] [--only NAME] "
                   "[--header]");
  const bool header = args.Flag("header");
  const std::string path = args.Positional(0);
  const double after_option = args.Get<double>("after", 0);
  const uint32_t k = args.Get<uint32_t>("k", 1000);
  const int repeats = args.Get<int>("repeats", 3);
  const std::string only = args.Get<std::string>("only", "");
  if (!args.Done()) return 2;
  if (header) {
    std::printf("step,faces,solo_s,after_s,worst_latency_s,mean_latency_s,cancelled,finished\n");
  }

  absl::StatusOr<TriangleMesh> raw = ReadMeshFile(path);
  if (!raw.ok()) {
    std::fprintf(stderr, "%s\n", raw.status().ToString().c_str());
    return 1;
  }
  const PreparedMesh prepared = bench::PrepareOrDie(path);
  const size_t faces = prepared.mesh.num_faces();
  MeshEnergyOptions cvd, planar;
  planar.kind = MeshEnergyKind::kPlanar;
  const MeshProblem problem = MakeMeshProblem(prepared, cvd);
  SeedOptions seeds;
  seeds.clusters = k;
  // The starts of EMLO, BB and coarsening, computed when first needed (--only skips them).
  std::vector<ClusterId> start, optimised;
  auto start_labels = [&]() -> const std::vector<ClusterId>& {
    if (start.empty()) start = *InitialClusters(problem, seeds);
    return start;
  };
  auto optimised_labels = [&]() -> const std::vector<ClusterId>& {
    if (optimised.empty()) {
      optimised = start_labels();
      (void)OptimizeEmlo(problem, optimised);
    }
    return optimised;
  };

  std::vector<Step> steps;
  steps.push_back({"prepare", [&](const std::atomic<bool>* cancel) {
                     return PrepareMesh(*raw, {cancel}).status();
                   }});
  steps.push_back({"seeds-lneigh", [&](const std::atomic<bool>* cancel) {
                     SeedOptions options = seeds;
                     options.cancel = cancel;
                     return InitialClusters(problem, options).status();
                   }});
  steps.push_back({"seeds-random", [&](const std::atomic<bool>* cancel) {
                     SeedOptions options = seeds;
                     options.method = SeedOptions::Method::kRandom;
                     options.cancel = cancel;
                     return InitialClusters(problem, options).status();
                   }});
  steps.push_back({"emlo", [&](const std::atomic<bool>* cancel) {
                     std::vector<ClusterId> labels = start_labels();
                     EmloOptions options;
                     options.cancel = cancel;
                     return OptimizeEmlo(problem, labels, options).status();
                   }});
  steps.push_back({"bb", [&](const std::atomic<bool>* cancel) {
                     std::vector<ClusterId> labels = start_labels();
                     BoundaryBasedOptions options;
                     options.cancel = cancel;
                     return OptimizeBoundaryBased(problem, labels, options).status();
                   }});

  steps.push_back({"vsa", [&](const std::atomic<bool>* cancel) {
                     VsaOptions options;
                     options.clusters = k;
                     options.cancel = cancel;
                     return RunVsa(MakeMeshProblem(prepared, planar), options).status();
                   }});
  steps.push_back({"coarsening", [&](const std::atomic<bool>* cancel) {
                     CoarseningOptions options;
                     options.cancel = cancel;
                     return CoarsenMesh(prepared.mesh, prepared.adjacency, optimised_labels(),
                                        options)
                         .status();
                   }});
  PointSet vertices;
  vertices.dims = 3;
  vertices.values = prepared.mesh.positions;
  steps.push_back({"kmeans", [&](const std::atomic<bool>* cancel) {
                     KmeansOptions options;
                     options.clusters = k;
                     options.cancel = cancel;
                     return RunKmeans(vertices, options).status();
                   }});

  for (const Step& step : steps) {
    if (!only.empty() && step.name != only) continue;
    // Their starting labels, outside the timed calls.
    if (step.name == "emlo" || step.name == "bb") start_labels();
    if (step.name == "coarsening") optimised_labels();
    bench::Stopwatch watch;
    const absl::Status solo = step.run(nullptr);
    const double solo_s = watch.Seconds();
    if (!solo.ok()) {
      std::fprintf(stderr, "%s: %s\n", step.name.c_str(), solo.ToString().c_str());
      continue;
    }
    const double after = after_option > 0 ? after_option : solo_s / 2;
    const Latency latency = Measure(step, after, repeats);
    std::printf("%s,%zu,%.3f,%.3f,%.4f,%.4f,%d,%d\n", step.name.c_str(), faces, solo_s, after,
                latency.worst, latency.cancelled ? latency.sum / latency.cancelled : 0.0,
                latency.cancelled, latency.finished);
    std::fflush(stdout);
  }
  return 0;
}
