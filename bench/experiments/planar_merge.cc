// Planar Δ_merging (core/cluster/planar_merging.h) of a labelling that `mlclust mesh
// --labels FILE` wrote (one cluster per input face, one per line).
//   planar_merge MESH LABELS [--angle DEGREES] [--out LABELS_OUT]
// Prints "input_clusters,output_clusters,merges,seconds" and optionally writes the merged
// labels, one per line.
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/time/clock.h"
#include "core/cluster/planar_merging.h"
#include "core/io/mesh_io.h"

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: planar_merge MESH LABELS [--angle DEGREES] [--out FILE]\n");
    return 2;
  }
  mlclust::PlanarMergingOptions options;
  std::string out;
  for (int i = 3; i + 1 < argc; i += 2) {
    const std::string arg = argv[i];
    if (arg == "--angle" && absl::SimpleAtod(argv[i + 1], &options.max_angle_degrees)) continue;
    if (arg == "--out") {
      out = argv[i + 1];
      continue;
    }
    std::fprintf(stderr, "bad argument %s\n", arg.c_str());
    return 2;
  }
  absl::StatusOr<mlclust::TriangleMesh> mesh = mlclust::ReadMeshFile(argv[1]);
  if (!mesh.ok()) {
    std::fprintf(stderr, "%s\n", mesh.status().ToString().c_str());
    return 1;
  }
  std::vector<mlclust::ClusterId> labels;
  std::ifstream in(argv[2]);
  for (uint32_t label; in >> label;) labels.push_back(mlclust::ClusterId(label));
  const absl::Time start = absl::Now();
  absl::StatusOr<mlclust::PlanarMergingResult> result =
      mlclust::MergePlanarClusters(*mesh, labels, options);
  const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
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
