// Per-polygon clustering inside the algorithms (MeshProblem::polygons, issue 13) against
// the post-pass the CLI had (cluster the triangles, then each polygon to the cluster of
// most of its area), at the same K: energy, cluster count, pieces (edge-connected parts of
// the clusters: more pieces than clusters means a cluster was cut in two) and time.
//
//   polygon_bench [--grid N] [--k K1,K2,...] [FILE.off ...]
//
// --grid N: an N x N wavy quad grid (tests/client/wiring_cli_test.sh's surface). OFF files
// with quads / n-gons: each polygon of n corners is n - 2 triangles, as the reader splits
// it. ML, EMLO and BB (l-neighbourhood seeds), CVD and planar.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "bench/bench_util.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/multilevel.h"
#include "core/hierarchy/hierarchy.h"
#include "core/io/mesh_io.h"
#include "core/mesh/polygons.h"
#include "tests/fixtures/quad_grid.h"

namespace mlclust::bench {
namespace {

struct Input {
  std::string name;
  PreparedMesh prepared;
  std::vector<uint32_t> counts;
};

Input WavyQuadGrid(int n) {
  absl::StatusOr<PreparedMesh> prepared = PrepareMesh(::mlclust::testing::WavyQuadGrid(n));
  if (!prepared.ok()) std::exit(1);
  return {"quad-grid-" + std::to_string(n), *std::move(prepared),
          std::vector<uint32_t>(static_cast<size_t>(n) * n, 2)};
}

Input ReadOff(const std::string& path) {
  Input input{BaseName(path), PrepareOrDie(path), {}};
  std::ifstream file(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(file, line);) {
    const std::string body = line.substr(0, line.find('#'));
    if (body.find_first_not_of(" \t\r") == std::string::npos) continue;
    lines.push_back(body);
  }
  std::istringstream header(lines[0].size() > 4 ? lines[0].substr(3) : lines[1]);
  size_t vertices = 0, faces = 0;
  header >> vertices >> faces;
  const size_t first = lines[0].size() > 4 ? 1 : 2;
  for (size_t f = 0; f < faces; ++f) {
    std::istringstream face(lines[first + vertices + f]);
    uint32_t corners = 0;
    face >> corners;
    if (corners >= 3) input.counts.push_back(corners - 2);
  }
  return input;
}

struct Measured {
  double energy = 0;
  uint32_t clusters = 0, pieces = 0, split = 0;
};

Measured Measure(const Input& input, const MeshProblem& problem, const MeshPolygons& polygons,
                 std::span<const ClusterId> labels) {
  Measured m;
  m.energy = MeshEnergyOfLabels(problem.energy, input.prepared.mesh, labels);
  std::vector<uint32_t> compact, component;
  m.clusters = CompactClusterIds(labels, compact);
  m.pieces = LabelFaceComponents(input.prepared.adjacency, component, compact);
  for (uint32_t p = 0; p < polygons.num_polygons(); ++p) {
    for (uint32_t f = polygons.first_face[p] + 1; f < polygons.first_face[p + 1]; ++f) {
      if (labels[f] != labels[polygons.first_face[p]]) {
        ++m.split;
        break;
      }
    }
  }
  return m;
}

// Each polygon to the cluster of most of its area (ties to the smaller id).
std::vector<ClusterId> PostPass(const Input& input, const MeshPolygons& polygons,
                                std::span<const ClusterId> labels) {
  std::vector<ClusterId> out(labels.begin(), labels.end());
  std::vector<std::pair<uint32_t, double>> area;
  for (uint32_t p = 0; p < polygons.num_polygons(); ++p) {
    area.clear();
    for (uint32_t f = polygons.first_face[p]; f < polygons.first_face[p + 1]; ++f) {
      size_t i = 0;
      while (i < area.size() && area[i].first != labels[f].value()) ++i;
      if (i == area.size()) area.push_back({labels[f].value(), 0.0});
      area[i].second += input.prepared.measures.area[f];
    }
    auto best = area[0];
    for (const auto& e : area) {
      if (e.second > best.second || (e.second == best.second && e.first < best.first)) best = e;
    }
    for (uint32_t f = polygons.first_face[p]; f < polygons.first_face[p + 1]; ++f) {
      out[f] = ClusterId(best.first);
    }
  }
  return out;
}

void Row(const std::string& mesh, const char* energy, const char* algorithm, uint32_t k,
         const Measured& whole, double whole_s, const Measured& triangles, const Measured& post,
         double triangles_s) {
  std::printf(
      "| %s | %s | %s | %u | %.6g (%u, %u pieces) | %.3f | %.6g (%u, %u pieces) | %.4f | "
      "%u | %.3f |\n",
      mesh.c_str(), energy, algorithm, k, whole.energy, whole.clusters, whole.pieces, whole_s,
      post.energy, post.clusters, post.pieces, whole.energy / post.energy, triangles.split,
      triangles_s);
}

void Run(const Input& input, const std::vector<uint32_t>& ks) {
  absl::StatusOr<MeshPolygons> polygons = MakeMeshPolygons(input.counts, input.prepared.adjacency);
  if (!polygons.ok()) {
    std::fprintf(stderr, "%s: %s\n", input.name.c_str(), polygons.status().ToString().c_str());
    return;
  }
  for (MeshEnergyKind kind : {MeshEnergyKind::kCvd, MeshEnergyKind::kPlanar}) {
    const MeshProblem triangles = MakeMeshProblem(input.prepared, {.kind = kind});
    MeshProblem whole = triangles;
    whole.polygons = &*polygons;
    HierarchyLog on_triangles, on_polygons;
    Stopwatch watch;
    if (!RunMultilevel(triangles, {}, on_triangles).ok()) std::exit(1);
    const double triangles_s = watch.Seconds();
    watch.Restart();
    if (!RunMultilevel(whole, {}, on_polygons).ok()) std::exit(1);
    const double whole_s = watch.Seconds();
    for (uint32_t k : ks) {
      if (k > polygons->num_polygons()) continue;
      const std::vector<ClusterId> t =
          *on_triangles.LabelsAt(*on_triangles.FirstLevelWithAtMost(k));
      const std::vector<ClusterId> w = *on_polygons.LabelsAt(*on_polygons.FirstLevelWithAtMost(k));
      Row(input.name, MeshEnergyName(kind), "ml", k, Measure(input, whole, *polygons, w), whole_s,
          Measure(input, triangles, *polygons, t),
          Measure(input, triangles, *polygons, PostPass(input, *polygons, t)), triangles_s);
    }
    for (const char* algorithm : {"emlo", "bb"}) {
      for (uint32_t k : ks) {
        if (k > polygons->num_polygons()) continue;
        SeedOptions seeds;
        seeds.clusters = k;
        auto optimise = [&](const MeshProblem& problem, std::vector<ClusterId>& labels) {
          return std::string(algorithm) == "emlo" ? OptimizeEmlo(problem, labels).ok()
                                                  : OptimizeBoundaryBased(problem, labels).ok();
        };
        watch.Restart();
        absl::StatusOr<std::vector<ClusterId>> t = InitialClusters(triangles, seeds);
        if (!t.ok() || !optimise(triangles, *t)) std::exit(1);
        const double t_s = watch.Seconds();
        watch.Restart();
        absl::StatusOr<std::vector<ClusterId>> w = InitialClusters(whole, seeds);
        if (!w.ok() || !optimise(whole, *w)) std::exit(1);
        const double w_s = watch.Seconds();
        Row(input.name, MeshEnergyName(kind), algorithm, k, Measure(input, whole, *polygons, *w),
            w_s, Measure(input, triangles, *polygons, *t),
            Measure(input, triangles, *polygons, PostPass(input, *polygons, *t)), t_s);
      }
    }
  }
}

}  // namespace
}  // namespace mlclust::bench

int main(int argc, char** argv) {
  using namespace mlclust::bench;
  std::vector<uint32_t> ks = {10, 50, 200};
  std::vector<Input> inputs;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--grid" && i + 1 < argc) {
      inputs.push_back(WavyQuadGrid(std::atoi(argv[++i])));
    } else if (arg == "--k" && i + 1 < argc) {
      ks.clear();
      for (absl::string_view k : absl::StrSplit(argv[++i], ',')) {
        uint32_t value = 0;
        if (absl::SimpleAtoi(k, &value)) ks.push_back(value);
      }
    } else {
      inputs.push_back(ReadOff(arg));
    }
  }
  std::printf(
      "| mesh | energy | algorithm | K | polygons in the algorithm: energy (clusters, pieces) "
      "| s | post-pass: energy (clusters, pieces) | ratio | polygons split on triangles | "
      "triangles s |\n|---|---|---|---|---|---|---|---|---|---|\n");
  for (const Input& input : inputs) Run(input, ks);
  return 0;
}
