// Repairs a mesh file's non-manifold edges and vertices (core/mesh/repair.h) and says what
// changed: the report's summary, its counts, ValidateMesh before and after, and the time.
//   repair_report FILE [--max-listed N]
#include <cstdio>
#include <string>

#include "bench/bench_util.h"
#include "core/io/mesh_io.h"
#include "core/mesh/repair.h"

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv, "usage: repair_report FILE [--max-listed N]");
  const std::string path = args.Positional(0);
  const size_t max_listed = args.Get<size_t>("max-listed", 5);
  if (!args.Done()) return 2;
  absl::StatusOr<mlclust::TriangleMesh> mesh = mlclust::ReadMeshFile(path);
  if (!mesh.ok()) {
    std::fprintf(stderr, "%s\n", mesh.status().ToString().c_str());
    return 1;
  }
  const absl::Status before = mlclust::ValidateMesh(*mesh);
  const mlclust::bench::Stopwatch watch;
  absl::StatusOr<mlclust::MeshRepairResult> result = mlclust::RepairNonManifold(*mesh);
  const double seconds = watch.Seconds();
  if (!result.ok()) {
    std::fprintf(stderr, "%s\n", result.status().ToString().c_str());
    return 1;
  }
  std::printf("input: %zu vertices, %zu faces; ValidateMesh: %s\n", mesh->num_vertices(),
              mesh->num_faces(), before.ok() ? "OK" : std::string(before.message()).c_str());
  std::printf("repair: %s\n", result->report.Summary(max_listed).c_str());
  std::printf("cut edges %zu, split vertices %zu, vertices added %zu, faces re-indexed %lu\n",
              result->report.cut_edges.size(), result->report.split_vertices.size(),
              result->report.copy_of.size(),
              static_cast<unsigned long>(result->report.faces_changed));
  const absl::Status after = mlclust::ValidateMesh(result->mesh);
  std::printf("output: %zu vertices, %zu faces; ValidateMesh: %s; repair took %.4f s\n",
              result->mesh.num_vertices(), result->mesh.num_faces(),
              after.ok() ? "OK" : std::string(after.message()).c_str(), seconds);
  return 0;
}
