// Meshlet-sized patches: ours (core/cluster/patches.h) against meshoptimizer's
// meshopt_buildMeshlets and METIS k-way on the face dual graph, at K = faces / 124.
//
//   meshlets_bench MESH... [--repeats R] [--sweeps S[,S...]] [--reseeds L] [--growth free|flood]
//                  [--threads T] [--peers meshoptimizer,metis|none] [--ml] [--emlo]
//                  [--header]
//
// One CSV row per mesh and method (best of R timings; the partition of the last run):
//   mesh,faces,method,k,seconds,cpu_seconds,energy,energy_over_ml,patches,disconnected,
//   max_faces,max_vertices
// seconds: wall clock; cpu_seconds: the process's CPU time over all its threads (the
// steadier figure on a shared machine; above the wall clock where ours runs in parallel).
// methods:
//   meshoptimizer   meshopt_buildMeshlets, 64 vertices / 124 triangles, cone weight 0; its
//                   meshlets are the patches (their count is its own, not K). Timed: the
//                   call alone (output buffers allocated before).
//   metis           METIS_PartGraphKway on the face dual graph (edge neighbours), K parts,
//                   METIS_OPTION_CONTIG. Timed: the call alone (the CSR graph built before).
//   ours-sS         BuildPatches with S BB sweeps at most (S = 0: spread seeds grown) and L
//                   Lloyd steps on the seeds (--reseeds, default 1; --sweeps default 6: the
//                   defaults of PatchOptions and of BB's preset patches).
//                   Timed: the call (spread seeds, growth, sweeps), on a prepared mesh.
//   emlo            InitialClusters (l-neighbourhood seeds, flood) + OptimizeEmlo, the
//                   dissertation's single-level route (--emlo).
//   ml              the ML hierarchy (Alg. 4.1) down to K, once (--ml); its energy at K is
//                   what energy_over_ml divides by (at meshoptimizer's own count for its row).
// energy: CVD (eq. 3.7) of the partition; disconnected: patches whose faces are not one
// edge-connected piece; max_vertices: the most distinct vertices in one patch.
// meshoptimizer and METIS are compiled in where Debian's libmeshoptimizer-dev and
// libmetis-dev were found (bench/peers/meshlets.cmake); their rows are missing otherwise.
#include <algorithm>
#include <cstdio>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "absl/strings/str_split.h"
#include "bench/bench_util.h"
#include "bench/peers/meshlet_peers.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/multilevel.h"
#include "core/cluster/patches.h"
#include "core/hierarchy/hierarchy.h"

namespace mlclust {
namespace {

constexpr uint32_t kTrianglesPerMeshlet = 124;
constexpr uint32_t kVerticesPerMeshlet = 64;

struct Shape {
  uint32_t patches = 0, disconnected = 0, max_faces = 0, max_vertices = 0;
};

// Patch count, patches in more than one edge-connected piece, largest patch in faces and
// in distinct vertices.
Shape MeasureShape(const PreparedMesh& prepared, std::span<const ClusterId> labels) {
  std::vector<uint32_t> parts(labels.size());
  for (size_t f = 0; f < labels.size(); ++f) parts[f] = labels[f].value();
  const bench::PartShapes parts_shape = bench::MeasureParts(prepared, parts);
  Shape shape;
  for (size_t c = 0; c < parts_shape.faces.size(); ++c) {
    if (parts_shape.faces[c] == 0) continue;
    ++shape.patches;
    if (parts_shape.pieces[c] > 1) ++shape.disconnected;
    shape.max_faces = std::max(shape.max_faces, parts_shape.faces[c]);
    shape.max_vertices = std::max(shape.max_vertices, parts_shape.vertices[c]);
  }
  return shape;
}

// Every level's (cluster count, energy) of an ML run.
class EnergyBySize : public LevelSink {
 public:
  absl::Status OnStart(std::span<const ClusterId> /*labels*/, uint32_t cluster_count,
                       double energy) override {
    energy_[cluster_count] = energy;
    return absl::OkStatus();
  }
  absl::Status OnLevel(const LevelMoves& level) override {
    energy_[level.cluster_count] = level.energy;
    return absl::OkStatus();
  }
  // The energy of the first level with at most `clusters` clusters (0 if none).
  double At(uint32_t clusters) const {
    auto it = energy_.upper_bound(clusters);
    if (it == energy_.begin()) return 0;
    return std::prev(it)->second;
  }

 private:
  std::map<uint32_t, double> energy_;
};

struct Row {
  std::string method;
  uint32_t k = 0;
  double seconds = 0;      // wall clock, best of the repeats
  double cpu_seconds = 0;  // the process's CPU time (all threads), best of the repeats
  std::vector<ClusterId> labels;
};

template <typename Run>
bool Time(int repeats, Run&& run, Row& row) {
  return bench::TimeBest(repeats, run, row);
}

#ifdef MLCLUST_HAVE_MESHOPTIMIZER
// meshopt_buildMeshlets' meshlets as face labels: each meshlet triangle's face is found
// among the faces around its first vertex (outside the timing).
bool RunMeshoptimizer(const PreparedMesh& prepared, int repeats, Row& row) {
  const TriangleMesh& mesh = prepared.mesh;
  const size_t index_count = mesh.indices.size();
  const size_t bound =
      meshopt_buildMeshletsBound(index_count, kVerticesPerMeshlet, kTrianglesPerMeshlet);
  std::vector<meshopt_Meshlet> meshlets(bound);
  std::vector<unsigned int> meshlet_vertices(bound * kVerticesPerMeshlet);
  std::vector<unsigned char> meshlet_triangles(bound * kTrianglesPerMeshlet * 3);
  size_t count = 0;
  row.method = "meshoptimizer";
  const bool ok = Time(
      repeats,
      [&] {
        count = meshopt_buildMeshlets(meshlets.data(), meshlet_vertices.data(),
                                      meshlet_triangles.data(), mesh.indices.data(), index_count,
                                      mesh.positions.data(), mesh.num_vertices(), 3 * sizeof(float),
                                      kVerticesPerMeshlet, kTrianglesPerMeshlet, 0.0f);
        return count > 0;
      },
      row);
  if (!ok) return false;
  std::vector<uint32_t> labels;
  if (!bench::MeshoptFaceLabels(mesh, {meshlets.data(), count}, meshlet_vertices, meshlet_triangles,
                                labels)) {
    return false;
  }
  row.labels.clear();
  for (uint32_t m : labels) row.labels.push_back(ClusterId(m));
  row.k = static_cast<uint32_t>(count);
  return true;
}
#endif

#ifdef MLCLUST_HAVE_METIS
bool RunMetis(const PreparedMesh& prepared, uint32_t k, int repeats, Row& row) {
  bench::DualGraph graph = bench::FaceDualGraph(prepared);
  row.method = "metis";
  row.k = k;
  return Time(
      repeats,
      [&] {
        std::vector<uint32_t> part;
        if (!bench::MetisKway(graph, k, part)) return false;
        row.labels.clear();
        for (uint32_t p : part) row.labels.push_back(ClusterId(p));
        return true;
      },
      row);
}
#endif

int Run(int argc, char** argv) {
  bench::Args args(argc, argv,
                   "usage: meshlets_bench MESH... [--repeats R] [--sweeps S[,S...]] [--reseeds L] "
                   "[--growth free|flood] [--threads T] [--peers meshoptimizer,metis] [--ml] "
                   "[--emlo] [--header]");
  const bool header = args.Flag("header");
  const bool with_ml = args.Flag("ml");
  const bool with_emlo = args.Flag("emlo");
  const int repeats = args.Get<int>("repeats", 5);
  const std::vector<uint32_t> sweep_counts = args.GetList<uint32_t>("sweeps", "6");
  const std::string growth = args.Get<std::string>("growth", "free");
  const int threads = args.Get<int>("threads", 0);
  const uint32_t reseeds = args.Get<uint32_t>("reseeds", 1);
  const std::string peers = args.Get<std::string>("peers", "meshoptimizer,metis");
  if (!args.Done()) return 2;
  auto with_peer = [&](absl::string_view name) { return bench::ListHas(peers, name); };
  if (header) {
    std::printf(
        "mesh,faces,method,k,seconds,cpu_seconds,energy,energy_over_ml,patches,disconnected,"
        "max_faces,max_vertices\n");
  }
  for (size_t i = 0; i < args.num_positional(); ++i) {
    const std::string path = args.Positional(i);
    const PreparedMesh prepared = bench::PrepareOrDie(path);
    const MeshProblem problem = MakeMeshProblem(prepared);
    const uint32_t faces = static_cast<uint32_t>(prepared.mesh.num_faces());
    const uint32_t k = std::max(1u, faces / kTrianglesPerMeshlet);
    std::vector<Row> rows;
#ifdef MLCLUST_HAVE_MESHOPTIMIZER
    if (with_peer("meshoptimizer")) {
      Row row;
      if (!RunMeshoptimizer(prepared, repeats, row)) return 1;
      rows.push_back(std::move(row));
    }
#endif
#ifdef MLCLUST_HAVE_METIS
    if (with_peer("metis")) {
      Row row;
      if (!RunMetis(prepared, k, repeats, row)) return 1;
      rows.push_back(std::move(row));
    }
#endif
    for (uint32_t sweeps : sweep_counts) {
      PatchOptions options;
      options.clusters = k;
      options.sweeps = sweeps;
      options.reseeds = reseeds;
      options.threads = threads;
      options.growth = growth == "flood" ? SeedOptions::Growth::kEnergyOrdered
                                         : SeedOptions::Growth::kEnergyFree;
      Row row;
      row.method = "ours-s" + std::to_string(sweeps);
      row.k = k;
      const bool ok = Time(
          repeats,
          [&] {
            absl::StatusOr<PatchResult> result = BuildPatches(problem, options);
            if (!result.ok()) {
              std::fprintf(stderr, "%s\n", result.status().ToString().c_str());
              return false;
            }
            row.labels = std::move(result->labels);
            return true;
          },
          row);
      if (!ok) return 1;
      rows.push_back(std::move(row));
    }
    if (with_emlo) {
      Row row;
      row.method = "emlo";
      row.k = k;
      const bool ok = Time(
          repeats,
          [&] {
            SeedOptions seeds;
            seeds.clusters = k;
            absl::StatusOr<std::vector<ClusterId>> labels = InitialClusters(problem, seeds);
            if (!labels.ok() || !OptimizeEmlo(problem, *labels).ok()) return false;
            row.labels = *std::move(labels);
            return true;
          },
          row);
      if (!ok) return 1;
      rows.push_back(std::move(row));
    }
    EnergyBySize ml;
    if (with_ml) {
      MultilevelOptions options;
      // Down to K: the levels pass through meshoptimizer's count too (at least K, as its
      // meshlets hold at most 124 triangles).
      options.min_clusters = k;
      const double cpu = bench::ProcessCpuSeconds();
      bench::Stopwatch watch;
      absl::StatusOr<MultilevelSummary> summary = RunMultilevel(problem, options, ml);
      if (!summary.ok()) {
        std::fprintf(stderr, "%s\n", summary.status().ToString().c_str());
        return 1;
      }
      std::printf("%s,%u,ml,%u,%.4f,%.4f,%.10g,1,,,,\n", bench::BaseName(path).c_str(), faces, k,
                  watch.Seconds(), bench::ProcessCpuSeconds() - cpu, ml.At(k));
    }
    for (const Row& row : rows) {
      const double energy = MeshEnergyOfLabels(problem.energy, prepared.mesh, row.labels);
      const double reference = ml.At(row.k);
      const Shape shape = MeasureShape(prepared, row.labels);
      std::printf("%s,%u,%s,%u,%.4f,%.4f,%.10g,%s,%u,%u,%u,%u\n", bench::BaseName(path).c_str(),
                  faces, row.method.c_str(), row.k, row.seconds, row.cpu_seconds, energy,
                  reference > 0 ? absl::StrCat(energy / reference).c_str() : "", shape.patches,
                  shape.disconnected, shape.max_faces, shape.max_vertices);
      std::fflush(stdout);
    }
  }
  return 0;
}

}  // namespace
}  // namespace mlclust

int main(int argc, char** argv) { return mlclust::Run(argc, argv); }
