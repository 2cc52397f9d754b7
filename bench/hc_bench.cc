// Times the stages of an HC run on a mesh file: read, validate, adjacency, measures, HC.
//   hc_bench MESH [REPEATS]
#include <cstdio>
#include <string>

#include "bench/bench_util.h"
#include "core/cluster/multilevel.h"
#include "core/io/mesh_io.h"
#include "core/mesh/face_measures.h"

namespace {

// Counts levels without storing them: the algorithm alone.
class CountingSink : public mlclust::LevelSink {
 public:
  absl::Status OnStart(std::span<const mlclust::ClusterId>, uint32_t, double) override {
    return absl::OkStatus();
  }
  absl::Status OnLevel(const mlclust::LevelMoves& level) override {
    moves += level.element.size();
    return absl::OkStatus();
  }
  uint64_t moves = 0;
};

template <typename F>
double Seconds(F&& f) {
  const mlclust::bench::Stopwatch watch;
  f();
  return watch.Seconds();
}

}  // namespace

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv, "usage: hc_bench MESH [REPEATS]");
  const std::string path = args.Positional(0);
  const int repeats = args.Positional<int>(1, 3);
  if (!args.Done()) return 2;
  absl::StatusOr<mlclust::TriangleMesh> mesh;
  const double read = Seconds([&] { mesh = mlclust::ReadMeshFile(path); });
  if (!mesh.ok()) {
    std::fprintf(stderr, "%s\n", mesh.status().ToString().c_str());
    return 1;
  }
  absl::Status valid;
  const double validate = Seconds([&] { valid = mlclust::ValidateMesh(*mesh); });
  if (!valid.ok()) {
    std::fprintf(stderr, "%s\n", valid.ToString().c_str());
    return 1;
  }
  absl::StatusOr<mlclust::FaceAdjacency> adjacency;
  const double adjacency_s = Seconds([&] { adjacency = mlclust::BuildFaceAdjacency(*mesh); });
  mlclust::FaceMeasures measures;
  const double measures_s = Seconds([&] { measures = mlclust::ComputeFaceMeasures(*mesh); });
  std::printf("%s: %zu faces, %zu vertices\n", path.c_str(), mesh->num_faces(),
              mesh->num_vertices());
  std::printf("read %.3f s, validate %.3f s, adjacency %.3f s, measures %.3f s\n", read, validate,
              adjacency_s, measures_s);
  const mlclust::MeshProblem problem{&*mesh, &*adjacency, &measures, {}};
  mlclust::MultilevelOptions hc;
  hc.optimizer = mlclust::MultilevelOptions::Optimizer::kNone;
  double best_count = 1e30, best_log = 1e30;
  uint64_t moves = 0;
  size_t log_bytes = 0;
  for (int r = 0; r < repeats; ++r) {
    CountingSink counting;
    best_count = std::min(best_count, Seconds([&] {
                            auto s = mlclust::RunMultilevel(problem, hc, counting);
                            if (!s.ok()) std::abort();
                          }));
    moves = counting.moves;
    mlclust::HierarchyLog log;
    best_log = std::min(best_log, Seconds([&] {
                          auto s = mlclust::RunMultilevel(problem, hc, log);
                          if (!s.ok()) std::abort();
                        }));
    log_bytes = log.num_moves() * 12 + log.num_levels() * 20;
  }
  std::printf(
      "HC full hierarchy: %.3f s (levels counted only), %.3f s (into a HierarchyLog, "
      "~%.1f MB); %llu triplets; best of %d\n",
      best_count, best_log, log_bytes / 1e6, static_cast<unsigned long long>(moves), repeats);
  return 0;
}
