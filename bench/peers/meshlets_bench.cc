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
#include <ctime>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "absl/strings/str_split.h"
#include "bench/bench_util.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/multilevel.h"
#include "core/cluster/patches.h"
#include "core/hierarchy/hierarchy.h"

#ifdef MLCLUST_HAVE_MESHOPTIMIZER
#include <meshoptimizer.h>
#endif
#ifdef MLCLUST_HAVE_METIS
#include <metis.h>
#endif

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
  const size_t n = labels.size();
  uint32_t k = 0;
  for (ClusterId c : labels) k = std::max(k, c.value() + 1);
  Shape shape;
  std::vector<uint32_t> faces_in(k, 0), pieces(k, 0);
  for (ClusterId c : labels) ++faces_in[c.value()];
  std::vector<uint8_t> seen(n, 0);
  std::vector<uint32_t> stack;
  for (uint32_t f = 0; f < n; ++f) {
    if (seen[f]) continue;
    const uint32_t c = labels[f].value();
    ++pieces[c];
    seen[f] = 1;
    stack.assign(1, f);
    while (!stack.empty()) {
      const uint32_t g = stack.back();
      stack.pop_back();
      for (FaceId h : prepared.adjacency.neighbours[g]) {
        if (h.valid() && !seen[h.value()] && labels[h.value()].value() == c) {
          seen[h.value()] = 1;
          stack.push_back(h.value());
        }
      }
    }
  }
  // Distinct vertices per patch: faces bucketed by patch, a stamp per vertex.
  std::vector<uint32_t> start(k + 1, 0), order(n);
  for (ClusterId c : labels) ++start[c.value() + 1];
  for (uint32_t c = 0; c < k; ++c) start[c + 1] += start[c];
  std::vector<uint32_t> fill(start.begin(), start.end() - 1);
  for (uint32_t f = 0; f < n; ++f) order[fill[labels[f].value()]++] = f;
  std::vector<uint32_t> stamp(prepared.mesh.num_vertices(), UINT32_MAX);
  for (uint32_t c = 0; c < k; ++c) {
    if (faces_in[c] == 0) continue;
    ++shape.patches;
    if (pieces[c] > 1) ++shape.disconnected;
    shape.max_faces = std::max(shape.max_faces, faces_in[c]);
    uint32_t vertices = 0;
    for (uint32_t i = start[c]; i < start[c + 1]; ++i) {
      for (int corner = 0; corner < 3; ++corner) {
        const uint32_t v = prepared.mesh.indices[3 * size_t{order[i]} + corner];
        if (stamp[v] != c) {
          stamp[v] = c;
          ++vertices;
        }
      }
    }
    shape.max_vertices = std::max(shape.max_vertices, vertices);
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

double ProcessCpuSeconds() {
  timespec now{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec);
}

// Best of `repeats` runs of `run` (returning whether it worked) in wall-clock and in CPU
// time into row; false if a run failed. On a shared machine the CPU time is the steadier
// figure; the wall clock is what a caller waits.
template <typename Run>
bool Time(int repeats, Run&& run, Row& row) {
  row.seconds = row.cpu_seconds = std::numeric_limits<double>::infinity();
  for (int r = 0; r < repeats; ++r) {
    const double cpu = ProcessCpuSeconds();
    bench::Stopwatch watch;
    if (!run()) return false;
    row.seconds = std::min(row.seconds, watch.Seconds());
    row.cpu_seconds = std::min(row.cpu_seconds, ProcessCpuSeconds() - cpu);
  }
  return true;
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
  const VertexFaceTable table = BuildVertexFaceTable(mesh);
  row.labels.assign(mesh.num_faces(), ClusterId::Invalid());
  for (uint32_t m = 0; m < count; ++m) {
    const meshopt_Meshlet& meshlet = meshlets[m];
    for (uint32_t t = 0; t < meshlet.triangle_count; ++t) {
      uint32_t v[3];
      for (int corner = 0; corner < 3; ++corner) {
        v[corner] = meshlet_vertices[meshlet.vertex_offset +
                                     meshlet_triangles[meshlet.triangle_offset + 3 * t + corner]];
      }
      for (uint32_t f : table.faces_around(v[0])) {
        const uint32_t* w = &mesh.indices[3 * size_t{f}];
        const bool same = (w[0] == v[0] || w[0] == v[1] || w[0] == v[2]) &&
                          (w[1] == v[0] || w[1] == v[1] || w[1] == v[2]) &&
                          (w[2] == v[0] || w[2] == v[1] || w[2] == v[2]);
        if (same) {
          row.labels[f] = ClusterId(m);
          break;
        }
      }
    }
  }
  row.k = static_cast<uint32_t>(count);
  for (ClusterId c : row.labels) {
    if (!c.valid()) {
      std::fprintf(stderr, "meshoptimizer: a face is in no meshlet\n");
      return false;
    }
  }
  return true;
}
#endif

#ifdef MLCLUST_HAVE_METIS
bool RunMetis(const PreparedMesh& prepared, uint32_t k, int repeats, Row& row) {
  const size_t n = prepared.mesh.num_faces();
  std::vector<idx_t> xadj(n + 1, 0), adjncy;
  adjncy.reserve(3 * n);
  for (size_t f = 0; f < n; ++f) {
    for (FaceId g : prepared.adjacency.neighbours[f]) {
      if (g.valid()) adjncy.push_back(static_cast<idx_t>(g.value()));
    }
    xadj[f + 1] = static_cast<idx_t>(adjncy.size());
  }
  std::vector<idx_t> part(n, 0);
  row.method = "metis";
  row.k = k;
  return Time(
      repeats,
      [&] {
        idx_t vertices = static_cast<idx_t>(n), constraints = 1, parts = static_cast<idx_t>(k);
        idx_t cut = 0;
        idx_t options[METIS_NOPTIONS];
        METIS_SetDefaultOptions(options);
        options[METIS_OPTION_CONTIG] = 1;
        const int status = METIS_PartGraphKway(&vertices, &constraints, xadj.data(), adjncy.data(),
                                               nullptr, nullptr, nullptr, &parts, nullptr, nullptr,
                                               options, &cut, part.data());
        if (status != METIS_OK) std::fprintf(stderr, "metis: status %d\n", status);
        if (status != METIS_OK) return false;
        row.labels.resize(n);
        for (size_t f = 0; f < n; ++f) row.labels[f] = ClusterId(static_cast<uint32_t>(part[f]));
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
  auto with_peer = [&](absl::string_view name) {
    for (absl::string_view p : absl::StrSplit(peers, ',')) {
      if (p == name) return true;
    }
    return false;
  };
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
      const double cpu = ProcessCpuSeconds();
      bench::Stopwatch watch;
      absl::StatusOr<MultilevelSummary> summary = RunMultilevel(problem, options, ml);
      if (!summary.ok()) {
        std::fprintf(stderr, "%s\n", summary.status().ToString().c_str());
        return 1;
      }
      std::printf("%s,%u,ml,%u,%.4f,%.4f,%.10g,1,,,,\n", bench::BaseName(path).c_str(), faces, k,
                  watch.Seconds(), ProcessCpuSeconds() - cpu, ml.At(k));
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
