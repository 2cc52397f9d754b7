// Planar Δ_merging (core/cluster/planar_merging.h) of a labelling that `mlclust mesh
// --labels FILE` wrote (one cluster per input face, one per line).
//   planar_merge MESH LABELS [--angle DEGREES] [--out LABELS_OUT]
// Prints "input_clusters,output_clusters,merges,seconds" and optionally writes the merged
// labels, one per line.
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "bench/bench_util.h"
#include "core/cluster/planar_merging.h"
#include "core/io/mesh_io.h"

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv,
                            "usage: planar_merge MESH LABELS [--angle DEGREES] [--out FILE]");
  mlclust::PlanarMergingOptions options;
  const std::string mesh_path = args.Positional(0);
  const std::string labels_path = args.Positional(1);
  options.max_angle_degrees = args.Get("angle", options.max_angle_degrees);
  const std::string out = args.Get<std::string>("out", "");
  if (!args.Done()) return 2;
  absl::StatusOr<mlclust::TriangleMesh> mesh = mlclust::ReadMeshFile(mesh_path);
  if (!mesh.ok()) {
    std::fprintf(stderr, "%s\n", mesh.status().ToString().c_str());
    return 1;
  }
  std::vector<mlclust::ClusterId> labels;
  std::ifstream in(labels_path);
  for (uint32_t label; in >> label;) labels.push_back(mlclust::ClusterId(label));
  const mlclust::bench::Stopwatch watch;
  absl::StatusOr<mlclust::PlanarMergingResult> result =
      mlclust::MergePlanarClusters(*mesh, labels, options);
  const double seconds = watch.Seconds();
  if (!result.ok()) {
    std::fprintf(stderr, "%s\n", result.status().ToString().c_str());
    return 1;
  }
  std::printf("%u,%u,%zu,%.4f\n", result->input_clusters, result->output_clusters,
              result->merges.size(), seconds);
  if (!out.empty()) {
    std::ofstream file(out);
    for (mlclust::ClusterId label : result->labels) file << label.value() << "\n";
  }
  return 0;
}
