// Fingerprints of the multilevel engine's output, to show that a change of structure
// leaves every result as it was: per job one line with the number of levels, the final
// energy, the energy at the first level with at most 1000 / 200 / 50 clusters (%.17g) and
// a 64-bit FNV-1a hash over every level's cluster count, energy bits and triplets (so the
// labels of every level are covered). Two builds' outputs compared with `diff`.
//
//   engine_golden [--meshes DIR] [--threads T] [--quick]
//
// Meshes: fandisk and bunny00 from DIR (default data/bench), CVD and planar; HC, ML,
// ML with BB, p% (sweep and hc-first), PML (both pair rules, to the end and then ML).
// Points: Gaussian blob sets (tests/fixtures/test_points.h); HC, ML, PML.
#include <cinttypes>
#include <cstdio>
#include <functional>
#include <string>
#include <vector>

#include "absl/time/clock.h"
#include "bench/bench_util.h"
#include "bench/level_hash.h"
#include "core/cluster/multilevel.h"
#include "core/cluster/point_clustering.h"
#include "tests/fixtures/test_points.h"

namespace {

using mlclust::LevelMoves;

// Hashes every level and keeps the energy at the first level at or below each k.
class FingerprintSink : public mlclust::LevelSink {
 public:
  absl::Status OnStart(std::span<const mlclust::ClusterId> labels, uint32_t cluster_count,
                       double energy) override {
    hash_.Start(labels, cluster_count, energy);
    Note(cluster_count, energy);
    return absl::OkStatus();
  }
  absl::Status OnLevel(const LevelMoves& level) override {
    ++levels_;
    hash_.Level(level);
    Note(level.cluster_count, level.energy);
    last_energy_ = level.energy;
    last_count_ = level.cluster_count;
    return absl::OkStatus();
  }
  std::string Line() const {
    char buffer[512];
    std::snprintf(buffer, sizeof buffer,
                  "levels=%u final=%u energy=%.17g e1000=%.17g e200=%.17g e50=%.17g "
                  "hash=%016" PRIx64,
                  levels_ + 1, last_count_, last_energy_, at_[0], at_[1], at_[2], hash_.value());
    return buffer;
  }

 private:
  void Note(uint32_t count, double energy) {
    const uint32_t ks[3] = {1000, 200, 50};
    for (int i = 0; i < 3; ++i) {
      if (!seen_[i] && count <= ks[i]) {
        seen_[i] = true;
        at_[i] = energy;
      }
    }
  }
  mlclust::bench::LevelHash hash_;
  uint32_t levels_ = 0, last_count_ = 0;
  double last_energy_ = 0;
  bool seen_[3] = {false, false, false};
  double at_[3] = {0, 0, 0};
};

void Report(const std::string& name, const absl::Status& status, const FingerprintSink& sink,
            double seconds) {
  if (!status.ok()) {
    std::printf("%s ERROR %s\n", name.c_str(), status.ToString().c_str());
  } else {
    std::printf("%s %s\n", name.c_str(), sink.Line().c_str());
  }
  std::fprintf(stderr, "%s %.3f s\n", name.c_str(), seconds);
  std::fflush(stdout);
}

}  // namespace

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv,
                            "usage: engine_golden [--meshes DIR] [--threads T] [--quick]");
  const bool quick = args.Flag("quick");
  const std::string dir = args.Get<std::string>("meshes", "data/bench");
  const int threads = args.Get<int>("threads", 0);
  if (!args.Done()) return 2;

  using mlclust::MultilevelOptions;
  struct MeshJob {
    std::string name;
    std::function<void(MultilevelOptions&)> set;
  };
  const std::vector<MeshJob> mesh_jobs = {
      {"hc", [](MultilevelOptions& o) { o.optimizer = MultilevelOptions::Optimizer::kNone; }},
      {"ml", [](MultilevelOptions&) {}},
      {"ml-bb",
       [](MultilevelOptions& o) { o.optimizer = MultilevelOptions::Optimizer::kBoundaryBased; }},
      {"ml-sizeties", [](MultilevelOptions& o) { o.ties_to_fewest_faces = false; }},
      {"p50-sweep", [](MultilevelOptions& o) { o.p_percent = 50; }},
      {"p50-hcfirst",
       [](MultilevelOptions& o) {
         o.p_percent = 50;
         o.p_percent_rule = MultilevelOptions::PPercentRule::kHcFirst;
       }},
      {"pml-half", [](MultilevelOptions& o) { o.parallel = true; }},
      {"pml-all",
       [](MultilevelOptions& o) {
         o.parallel = true;
         o.pml_pairs = mlclust::PmlPairRule::kAll;
       }},
      {"pml-half-until1000",
       [](MultilevelOptions& o) {
         o.parallel = true;
         o.pml_until = 1000;
       }},
      {"pml-all-hc",
       [](MultilevelOptions& o) {
         o.parallel = true;
         o.pml_pairs = mlclust::PmlPairRule::kAll;
         o.optimizer = MultilevelOptions::Optimizer::kNone;
       }},
      // Opt-in: parallel_optimisation (ours), face-order and independent application.
      {"pml-half-until1000-rounds",
       [](MultilevelOptions& o) {
         o.parallel = true;
         o.pml_until = 1000;
         o.parallel_optimisation = true;
       }},
      {"pml-half-until1000-independent",
       [](MultilevelOptions& o) {
         o.parallel = true;
         o.pml_until = 1000;
         o.parallel_optimisation = true;
         o.independent_moves = true;
       }},
  };
  const std::vector<std::string> meshes =
      quick ? std::vector<std::string>{"fandisk"} : std::vector<std::string>{"fandisk", "bunny00"};
  for (const std::string& mesh_name : meshes) {
    const mlclust::PreparedMesh prepared =
        mlclust::bench::PrepareOrDie(dir + "/" + mesh_name + ".off");
    for (const char* energy_name : {"cvd", "planar"}) {
      mlclust::MeshEnergyOptions energy;
      energy.kind = std::string(energy_name) == "cvd" ? mlclust::MeshEnergyKind::kCvd
                                                      : mlclust::MeshEnergyKind::kPlanar;
      const mlclust::MeshProblem problem = mlclust::MakeMeshProblem(prepared, energy);
      for (const MeshJob& job : mesh_jobs) {
        MultilevelOptions options;
        options.threads = threads;
        job.set(options);
        FingerprintSink sink;
        const absl::Time start = absl::Now();
        absl::StatusOr<mlclust::MultilevelSummary> summary =
            mlclust::RunMultilevel(problem, options, sink);
        Report(mesh_name + "." + energy_name + "." + job.name, summary.status(), sink,
               absl::ToDoubleSeconds(absl::Now() - start));
      }
    }
  }

  using mlclust::PointMultilevelOptions;
  struct PointJob {
    std::string name;
    std::function<void(PointMultilevelOptions&)> set;
  };
  const std::vector<PointJob> point_jobs = {
      {"hc",
       [](PointMultilevelOptions& o) { o.optimizer = PointMultilevelOptions::Optimizer::kNone; }},
      {"ml", [](PointMultilevelOptions&) {}},
      {"pml-half", [](PointMultilevelOptions& o) { o.parallel = true; }},
      {"pml-all",
       [](PointMultilevelOptions& o) {
         o.parallel = true;
         o.pml_pairs = mlclust::PmlPairRule::kAll;
       }},
      {"pml-half-until100",
       [](PointMultilevelOptions& o) {
         o.parallel = true;
         o.pml_until = 100;
       }},
  };
  struct BlobSet {
    uint32_t clusters, per_cluster;
    double separation;
    uint64_t seed;
    bool shuffle;
  };
  const std::vector<BlobSet> blob_sets =
      quick ? std::vector<BlobSet>{{20, 200, 6, 1, false}}
            : std::vector<BlobSet>{
                  {20, 200, 6, 1, false}, {100, 300, 4, 7, true}, {300, 100, 2, 11, true}};
  for (const BlobSet& set : blob_sets) {
    const mlclust::testing::Blobs blobs = mlclust::testing::GaussianBlobs(
        set.clusters, set.per_cluster, set.separation, set.seed, set.shuffle);
    const std::string set_name = "blobs" + std::to_string(set.clusters) + "x" +
                                 std::to_string(set.per_cluster) + "s" + std::to_string(set.seed);
    for (const PointJob& job : point_jobs) {
      PointMultilevelOptions options;
      options.threads = threads;
      job.set(options);
      FingerprintSink sink;
      const absl::Time start = absl::Now();
      absl::StatusOr<mlclust::PointMultilevelSummary> summary =
          mlclust::RunPointMultilevel(blobs.points, options, sink);
      Report(set_name + "." + job.name, summary.status(), sink,
             absl::ToDoubleSeconds(absl::Now() - start));
    }
  }
  return 0;
}
