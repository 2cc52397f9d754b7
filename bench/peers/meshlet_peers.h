// What the meshlet benches share (meshlets_bench.cc, meshlets_caps_bench.cc): timing, the
// shape of a partition into meshlets, and the peers' calls (meshoptimizer, METIS), each
// compiled in only where its Debian package was found (bench/peers/meshlets.cmake).
#ifndef MLCLUST_BENCH_PEERS_MESHLET_PEERS_H_
#define MLCLUST_BENCH_PEERS_MESHLET_PEERS_H_

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <ctime>
#include <limits>
#include <span>
#include <vector>

#include "absl/strings/str_split.h"
#include "absl/strings/string_view.h"
#include "bench/bench_util.h"
#include "core/mesh/prepared_mesh.h"

#ifdef MLCLUST_HAVE_MESHOPTIMIZER
#include <meshoptimizer.h>
#endif
#ifdef MLCLUST_HAVE_METIS
#include <metis.h>
#endif

namespace mlclust::bench {

inline double ProcessCpuSeconds() {
  timespec now{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &now);
  return static_cast<double>(now.tv_sec) + 1e-9 * static_cast<double>(now.tv_nsec);
}

// Whether the comma-separated `list` ("meshoptimizer,metis") names `name`.
inline bool ListHas(absl::string_view list, absl::string_view name) {
  for (absl::string_view item : absl::StrSplit(list, ',')) {
    if (item == name) return true;
  }
  return false;
}

// Best of `repeats` runs of `run` (returning whether it worked) in wall-clock and in CPU
// time into row.seconds and row.cpu_seconds; false if a run failed. On a shared machine
// the CPU time is the steadier figure; the wall clock is what a caller waits.
template <typename Row, typename Run>
bool TimeBest(int repeats, Run&& run, Row& row) {
  row.seconds = row.cpu_seconds = std::numeric_limits<double>::infinity();
  for (int r = 0; r < repeats; ++r) {
    const double cpu = ProcessCpuSeconds();
    Stopwatch watch;
    if (!run()) return false;
    row.seconds = std::min(row.seconds, watch.Seconds());
    row.cpu_seconds = std::min(row.cpu_seconds, ProcessCpuSeconds() - cpu);
  }
  return true;
}

// Per part of a face partition (labels: one part per face): its faces, its distinct
// vertices and its edge-connected pieces (floods across the prepared mesh's edges).
struct PartShapes {
  std::vector<uint32_t> faces, vertices, pieces;
};

inline PartShapes MeasureParts(const PreparedMesh& prepared, std::span<const uint32_t> labels) {
  const size_t n = labels.size();
  uint32_t k = 0;
  for (uint32_t c : labels) k = std::max(k, c + 1);
  PartShapes shapes;
  shapes.faces.assign(k, 0);
  shapes.vertices.assign(k, 0);
  shapes.pieces.assign(k, 0);
  for (uint32_t c : labels) ++shapes.faces[c];
  std::vector<uint8_t> seen(n, 0);
  std::vector<uint32_t> stack;
  for (uint32_t f = 0; f < n; ++f) {
    if (seen[f]) continue;
    const uint32_t c = labels[f];
    ++shapes.pieces[c];
    seen[f] = 1;
    stack.assign(1, f);
    while (!stack.empty()) {
      const uint32_t g = stack.back();
      stack.pop_back();
      for (FaceId h : prepared.adjacency.neighbours[g]) {
        if (h.valid() && !seen[h.value()] && labels[h.value()] == c) {
          seen[h.value()] = 1;
          stack.push_back(h.value());
        }
      }
    }
  }
  // Distinct vertices per part: faces bucketed by part, a stamp per vertex.
  std::vector<uint32_t> start(k + 1, 0), order(n);
  for (uint32_t c : labels) ++start[c + 1];
  for (uint32_t c = 0; c < k; ++c) start[c + 1] += start[c];
  std::vector<uint32_t> fill(start.begin(), start.end() - 1);
  for (uint32_t f = 0; f < n; ++f) order[fill[labels[f]]++] = f;
  std::vector<uint32_t> stamp(prepared.mesh.num_vertices(), UINT32_MAX);
  for (uint32_t c = 0; c < k; ++c) {
    for (uint32_t i = start[c]; i < start[c + 1]; ++i) {
      for (int corner = 0; corner < 3; ++corner) {
        const uint32_t v = prepared.mesh.indices[3 * size_t{order[i]} + corner];
        if (stamp[v] != c) {
          stamp[v] = c;
          ++shapes.vertices[c];
        }
      }
    }
  }
  return shapes;
}

#ifdef MLCLUST_HAVE_MESHOPTIMIZER
// meshopt_buildMeshlets' meshlets as face labels: each meshlet triangle's face is found
// among the faces around its first vertex (a face already labelled is skipped, so that
// duplicate faces each get one). False, with a message, if a face is in no meshlet.
inline bool MeshoptFaceLabels(const TriangleMesh& mesh, std::span<const meshopt_Meshlet> meshlets,
                              std::span<const unsigned int> meshlet_vertices,
                              std::span<const unsigned char> meshlet_triangles,
                              std::vector<uint32_t>& labels) {
  const VertexFaceTable table = BuildVertexFaceTable(mesh);
  labels.assign(mesh.num_faces(), UINT32_MAX);
  for (uint32_t m = 0; m < meshlets.size(); ++m) {
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
        if (same && labels[f] == UINT32_MAX) {
          labels[f] = m;
          break;
        }
      }
    }
  }
  for (uint32_t m : labels) {
    if (m == UINT32_MAX) {
      std::fprintf(stderr, "meshoptimizer: a face is in no meshlet\n");
      return false;
    }
  }
  return true;
}
#endif

#ifdef MLCLUST_HAVE_METIS
// The face dual graph (edge neighbours) in METIS's CSR form.
struct DualGraph {
  std::vector<idx_t> xadj, adjncy;
};

inline DualGraph FaceDualGraph(const PreparedMesh& prepared) {
  const size_t n = prepared.mesh.num_faces();
  DualGraph graph;
  graph.xadj.assign(n + 1, 0);
  graph.adjncy.reserve(3 * n);
  for (size_t f = 0; f < n; ++f) {
    for (FaceId g : prepared.adjacency.neighbours[f]) {
      if (g.valid()) graph.adjncy.push_back(static_cast<idx_t>(g.value()));
    }
    graph.xadj[f + 1] = static_cast<idx_t>(graph.adjncy.size());
  }
  return graph;
}

// METIS_PartGraphKway into k parts with METIS_OPTION_CONTIG; false, with a message, if
// METIS fails.
inline bool MetisKway(DualGraph& graph, uint32_t k, std::vector<uint32_t>& part) {
  const size_t n = graph.xadj.size() - 1;
  std::vector<idx_t> parts_of(n, 0);
  idx_t vertices = static_cast<idx_t>(n), constraints = 1, parts = static_cast<idx_t>(k);
  idx_t cut = 0;
  idx_t options[METIS_NOPTIONS];
  METIS_SetDefaultOptions(options);
  options[METIS_OPTION_CONTIG] = 1;
  const int status = METIS_PartGraphKway(&vertices, &constraints, graph.xadj.data(),
                                         graph.adjncy.data(), nullptr, nullptr, nullptr, &parts,
                                         nullptr, nullptr, options, &cut, parts_of.data());
  if (status != METIS_OK) {
    std::fprintf(stderr, "metis: status %d\n", status);
    return false;
  }
  part.resize(n);
  for (size_t f = 0; f < n; ++f) part[f] = static_cast<uint32_t>(parts_of[f]);
  return true;
}
#endif

}  // namespace mlclust::bench

#endif  // MLCLUST_BENCH_PEERS_MESHLET_PEERS_H_
