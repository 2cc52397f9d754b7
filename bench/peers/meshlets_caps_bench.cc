// Capped meshlets: ours (core/meshlets/meshlets.h) against meshoptimizer's
// meshopt_buildMeshlets at the same caps, and METIS k-way on the face dual graph.
//
//   meshlets_caps_bench MESH... [--repeats R] [--max-vertices 64] [--max-triangles 124]
//                       [--cone-weights 0,0.25] [--ours-cone-weights 0,0.25]
//                       [--peers meshoptimizer,metis|none] [--header]
//
// One CSV row per mesh and method (best of R timings; the meshlets of the last run):
//   mesh,faces,method,cone_weight,meshlets,fill,vertices_per_triangle,mean_radius,
//   mean_cone_cutoff,disconnected,over_cap,max_vertices,max_triangles,seconds,cpu_seconds
// fill: mean triangles per meshlet; vertices_per_triangle: meshlet vertex entries over
// faces (what the vertex runs cost); mean_radius, mean_cone_cutoff: means over meshlets of
// meshopt_computeMeshletBounds' radius and cone_cutoff (lower is tighter); disconnected:
// meshlets whose faces are not one edge-connected piece; over_cap: meshlets above either
// cap. seconds: wall clock of the build *with* the bounds of every meshlet; cpu_seconds:
// the process's CPU time over all threads (the steadier figure on a shared machine).
// methods:
//   meshoptimizer  meshopt_buildMeshlets (output buffers allocated before the timing) and
//                  meshopt_computeMeshletBounds per meshlet.
//   ours           BuildMeshlets (bounds included: it calls meshopt_computeMeshletBounds).
//   metis          METIS_PartGraphKway, METIS_OPTION_CONTIG, on the face dual graph (edge
//                  neighbours; the CSR graph built before the timing), K = meshoptimizer's
//                  count at the first cone weight; parts are not capped, so over_cap
//                  counts them, and no bounds (meshoptimizer's take at most 512 triangles).
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <limits>
#include <string>
#include <vector>

#include "absl/strings/str_split.h"
#include "bench/bench_util.h"
#include "bench/peers/meshlet_peers.h"
#include "core/mesh/prepared_mesh.h"
#include "core/meshlets/meshlets.h"

namespace mlclust {
namespace {

struct Row {
  std::string method;
  float cone_weight = 0;
  double seconds = std::numeric_limits<double>::infinity();
  double cpu_seconds = std::numeric_limits<double>::infinity();
  std::vector<uint32_t> labels;  // each face's meshlet
  std::vector<float> radius, cutoff;
};

template <typename Run>
bool Time(int repeats, Run&& run, Row& row) {
  return bench::TimeBest(repeats, run, row);
}

void PrintRow(const std::string& mesh_name, const PreparedMesh& prepared, const Row& row,
              uint32_t max_vertices, uint32_t max_triangles) {
  const size_t n = prepared.mesh.num_faces();
  const bench::PartShapes shapes = bench::MeasureParts(prepared, row.labels);
  const auto k = static_cast<uint32_t>(shapes.faces.size());
  const std::vector<uint32_t>& triangles = shapes.faces;
  const std::vector<uint32_t>& vertices = shapes.vertices;
  uint32_t meshlets = 0, disconnected = 0, over_cap = 0, most_vertices = 0, most_triangles = 0;
  uint64_t vertex_entries = 0;
  for (uint32_t m = 0; m < k; ++m) {
    if (triangles[m] == 0) continue;
    ++meshlets;
    vertex_entries += vertices[m];
    if (shapes.pieces[m] > 1) ++disconnected;
    if (vertices[m] > max_vertices || triangles[m] > max_triangles) ++over_cap;
    most_vertices = std::max(most_vertices, vertices[m]);
    most_triangles = std::max(most_triangles, triangles[m]);
  }
  if (std::getenv("MESHLETS_HISTOGRAM") != nullptr) {
    std::vector<uint32_t> by_triangles(14, 0), full_vertices(14, 0);
    for (uint32_t m = 0; m < k; ++m) {
      if (triangles[m] == 0) continue;
      ++by_triangles[std::min<uint32_t>(triangles[m] / 10, 13)];
      if (vertices[m] == max_vertices) ++full_vertices[std::min<uint32_t>(triangles[m] / 10, 13)];
    }
    std::fprintf(stderr,
                 "%s %s: triangles/10 histogram (of which at the vertex cap):", mesh_name.c_str(),
                 row.method.c_str());
    for (int b = 0; b < 14; ++b)
      std::fprintf(stderr, " %d:%u(%u)", b, by_triangles[b], full_vertices[b]);
    std::fprintf(stderr, "\n");
  }
  double radius = 0, cutoff = 0;
  for (float r : row.radius) radius += r;
  for (float c : row.cutoff) cutoff += c;
  const double bounded = static_cast<double>(std::max<size_t>(row.radius.size(), 1));
  std::string radius_text, cutoff_text;
  if (!row.radius.empty()) {
    radius_text = absl::StrCat(radius / bounded);
    cutoff_text = absl::StrCat(cutoff / bounded);
  }
  std::printf("%s,%zu,%s,%g,%u,%.2f,%.4f,%s,%s,%u,%u,%u,%u,%.4f,%.4f\n", mesh_name.c_str(), n,
              row.method.c_str(), row.cone_weight, meshlets,
              static_cast<double>(n) / std::max(meshlets, 1u),
              static_cast<double>(vertex_entries) / static_cast<double>(n), radius_text.c_str(),
              cutoff_text.c_str(), disconnected, over_cap, most_vertices, most_triangles,
              row.seconds, row.cpu_seconds);
  std::fflush(stdout);
}

#ifdef MLCLUST_HAVE_MESHOPTIMIZER
// meshopt_buildMeshlets with its bounds; its meshlets as face labels (each meshlet
// triangle's face found among the faces around its first vertex, outside the timing).
bool RunMeshoptimizer(const PreparedMesh& prepared, uint32_t max_vertices, uint32_t max_triangles,
                      float cone_weight, int repeats, Row& row) {
  const TriangleMesh& mesh = prepared.mesh;
  const size_t index_count = mesh.indices.size();
  const size_t bound = meshopt_buildMeshletsBound(index_count, max_vertices, max_triangles);
  std::vector<meshopt_Meshlet> meshlets(bound);
  std::vector<unsigned int> meshlet_vertices(bound * max_vertices);
  std::vector<unsigned char> meshlet_triangles(bound * max_triangles * 3);
  size_t count = 0;
  row.method = "meshoptimizer";
  row.cone_weight = cone_weight;
  const bool ok = Time(
      repeats,
      [&] {
        count = meshopt_buildMeshlets(meshlets.data(), meshlet_vertices.data(),
                                      meshlet_triangles.data(), mesh.indices.data(), index_count,
                                      mesh.positions.data(), mesh.num_vertices(), 3 * sizeof(float),
                                      max_vertices, max_triangles, cone_weight);
        row.radius.resize(count);
        row.cutoff.resize(count);
        for (size_t m = 0; m < count; ++m) {
          const meshopt_Meshlet& meshlet = meshlets[m];
          const meshopt_Bounds bounds = meshopt_computeMeshletBounds(
              &meshlet_vertices[meshlet.vertex_offset], &meshlet_triangles[meshlet.triangle_offset],
              meshlet.triangle_count, mesh.positions.data(), mesh.num_vertices(),
              3 * sizeof(float));
          row.radius[m] = bounds.radius;
          row.cutoff[m] = bounds.cone_cutoff;
        }
        return count > 0;
      },
      row);
  if (!ok) return false;
  return bench::MeshoptFaceLabels(mesh, {meshlets.data(), count}, meshlet_vertices,
                                  meshlet_triangles, row.labels);
}
#endif

#ifdef MLCLUST_HAVE_METIS
bool RunMetis(const PreparedMesh& prepared, uint32_t k, int repeats, Row& row) {
  bench::DualGraph graph = bench::FaceDualGraph(prepared);
  row.method = "metis";
  return Time(
      repeats, [&] { return bench::MetisKway(graph, k, row.labels); }, row);
}
#endif

int Run(int argc, char** argv) {
  bench::Args args(argc, argv,
                   "usage: meshlets_caps_bench MESH... [--repeats R] [--max-vertices 64] "
                   "[--max-triangles 124] [--cone-weights 0,0.25] [--ours-cone-weights 0,0.25] "
                   "[--peers meshoptimizer,metis|none] [--header]");
  const bool header = args.Flag("header");
  const int repeats = args.Get<int>("repeats", 5);
  const auto max_vertices = args.Get<uint32_t>("max-vertices", 64);
  const auto max_triangles = args.Get<uint32_t>("max-triangles", 124);
  const std::vector<double> cone_weights = args.GetList<double>("cone-weights", "0,0.25");
  const std::vector<double> ours_cone_weights = args.GetList<double>("ours-cone-weights", "0,0.25");
  const std::string peers = args.Get<std::string>("peers", "meshoptimizer,metis");
  if (!args.Done()) return 2;
  auto with_peer = [&](absl::string_view name) { return bench::ListHas(peers, name); };
  if (header) {
    std::printf(
        "mesh,faces,method,cone_weight,meshlets,fill,vertices_per_triangle,mean_radius,"
        "mean_cone_cutoff,disconnected,over_cap,max_vertices,max_triangles,seconds,"
        "cpu_seconds\n");
  }
  for (size_t i = 0; i < args.num_positional(); ++i) {
    const std::string path = args.Positional(i);
    const std::string name = bench::BaseName(path);
    const PreparedMesh prepared = bench::PrepareOrDie(path);
    uint32_t peer_count = 0;
#ifdef MLCLUST_HAVE_MESHOPTIMIZER
    if (with_peer("meshoptimizer")) {
      for (double weight : cone_weights) {
        Row row;
        if (!RunMeshoptimizer(prepared, max_vertices, max_triangles, static_cast<float>(weight),
                              repeats, row)) {
          return 1;
        }
        if (peer_count == 0) {
          for (uint32_t m : row.labels) peer_count = std::max(peer_count, m + 1);
        }
        PrintRow(name, prepared, row, max_vertices, max_triangles);
      }
    }
#endif
    for (double weight : ours_cone_weights) {
      MeshletOptions options;
      options.max_vertices = max_vertices;
      options.max_triangles = max_triangles;
      options.cone_weight = static_cast<float>(weight);
      Row row;
      row.method = "ours";
      row.cone_weight = options.cone_weight;
      MeshletResult result;
      const bool ok = Time(
          repeats,
          [&] {
            absl::StatusOr<MeshletResult> built = BuildMeshlets(prepared.mesh, options);
            if (!built.ok()) {
              std::fprintf(stderr, "%s\n", built.status().ToString().c_str());
              return false;
            }
            result = *std::move(built);
            return true;
          },
          row);
      if (!ok) return 1;
      const absl::Status layout =
          CheckMeshletLayout(result, max_vertices, max_triangles, &prepared.mesh);
      if (!layout.ok()) {
        std::fprintf(stderr, "ours: %s\n", layout.ToString().c_str());
        return 1;
      }
      row.labels = result.face_meshlet;
      for (const MeshletBounds& b : result.bounds) {
        row.radius.push_back(b.radius);
        row.cutoff.push_back(b.cone_cutoff);
      }
      PrintRow(name, prepared, row, max_vertices, max_triangles);
    }
#ifdef MLCLUST_HAVE_METIS
    if (with_peer("metis") && peer_count > 1) {
      Row row;
      if (!RunMetis(prepared, peer_count, repeats, row)) return 1;
      PrintRow(name, prepared, row, max_vertices, max_triangles);
    }
#endif
  }
  return 0;
}

}  // namespace
}  // namespace mlclust

int main(int argc, char** argv) { return mlclust::Run(argc, argv); }
