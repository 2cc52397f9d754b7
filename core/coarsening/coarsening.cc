#include "core/coarsening/coarsening.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <numeric>
#include <string>

#include "absl/container/flat_hash_map.h"
#include "absl/container/flat_hash_set.h"
#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/renumber.h"
#include "core/base/status_macros.h"
#include "core/base/vec3.h"
#include "core/mesh/face_measures.h"

namespace mlclust {
namespace {

constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
// Loops over vertices look at the cancel flag once per this many.
constexpr uint32_t kVerticesPerCancelCheck = 32768;

// Clusters renumbered 0..k-1 in order of first appearance; coarse vertex i is cluster i.
// dense[face] is the face's dense cluster, original[cluster] the caller's label.
using DenseClusters = Renumbering<ClusterId>;

absl::Status CheckInputs(const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                         std::span<const ClusterId> labels) {
  const size_t num_faces = mesh.num_faces();
  if (labels.size() != num_faces) {
    return absl::InvalidArgumentError(absl::StrCat("labels hold ", labels.size(),
                                                   " entries; the mesh has ", num_faces,
                                                   " faces (one label per face)"));
  }
  if (adjacency.num_faces() != num_faces) {
    return absl::InvalidArgumentError(absl::StrCat("the adjacency covers ", adjacency.num_faces(),
                                                   " faces; the mesh has ", num_faces));
  }
  if (num_faces == 0) return absl::InvalidArgumentError("empty mesh: it has no faces");
  MLCLUST_RETURN_IF_ERROR(CheckVertexIndices(mesh));
  for (size_t face = 0; face < num_faces; ++face) {
    if (!labels[face].valid()) {
      return absl::InvalidArgumentError(
          absl::StrCat("face ", face, " has no cluster (its label is ClusterId::Invalid())"));
    }
    for (int edge = 0; edge < 3; ++edge) {
      const FaceId neighbour = adjacency.neighbours[face][edge];
      if (neighbour.valid() && (neighbour.value() >= num_faces || neighbour.value() == face)) {
        return absl::InvalidArgumentError(
            absl::StrCat("face ", face, " edge ", edge, ": neighbour ", neighbour.value(),
                         neighbour.value() == face ? " is the face itself" : " is out of range"));
      }
    }
  }
  return absl::OkStatus();
}

int CornerOf(const TriangleMesh& mesh, uint32_t face, uint32_t vertex) {
  for (int corner = 0; corner < 3; ++corner) {
    if (mesh.indices[3 * size_t{face} + corner] == vertex) return corner;
  }
  return -1;
}

uint32_t VertexAt(const TriangleMesh& mesh, uint32_t face, int corner) {
  return mesh.indices[3 * size_t{face} + corner];
}

uint64_t EdgeKey(uint32_t a, uint32_t b) { return (uint64_t{a} << 32) | b; }
uint64_t UndirectedKey(uint32_t a, uint32_t b) { return a < b ? EdgeKey(a, b) : EdgeKey(b, a); }

// The boundary loops of the mesh. Each boundary edge is named by the corner index 3f + e of
// the face f that holds it as its edge e (from corner e to corner e + 1).
struct BoundaryLoops {
  std::vector<uint32_t> loop_of_vertex;  // kNone for a vertex off the boundary
  std::vector<uint32_t> offset;          // edges of loop l: edge[offset[l] .. offset[l + 1])
  std::vector<uint32_t> edge;

  uint32_t size() const { return static_cast<uint32_t>(offset.size() - 1); }
};

absl::StatusOr<BoundaryLoops> FindBoundaryLoops(const TriangleMesh& mesh,
                                                const FaceAdjacency& adjacency) {
  BoundaryLoops loops;
  loops.loop_of_vertex.assign(mesh.num_vertices(), kNone);
  loops.offset.push_back(0);
  std::vector<uint32_t> edge_from(mesh.num_vertices(), kNone);
  size_t boundary_edges = 0;
  for (uint32_t face = 0; face < mesh.num_faces(); ++face) {
    for (int e = 0; e < 3; ++e) {
      if (adjacency.neighbours[face][e].valid()) continue;
      const uint32_t from = VertexAt(mesh, face, e);
      if (edge_from[from] != kNone) {
        return absl::InvalidArgumentError(
            absl::StrCat("vertex ", from,
                         " starts two boundary edges (a non-manifold vertex; run ValidateMesh)"));
      }
      edge_from[from] = 3 * face + e;
      ++boundary_edges;
    }
  }
  for (uint32_t start = 0; start < mesh.num_vertices(); ++start) {
    if (edge_from[start] == kNone || loops.loop_of_vertex[start] != kNone) continue;
    const uint32_t loop = loops.size();
    uint32_t vertex = start;
    do {
      if (loops.edge.size() >= boundary_edges || edge_from[vertex] == kNone ||
          loops.loop_of_vertex[vertex] != kNone) {
        return absl::InvalidArgumentError(
            absl::StrCat("the boundary edges through vertex ", vertex,
                         " do not form closed loops (a non-manifold vertex; run ValidateMesh)"));
      }
      loops.loop_of_vertex[vertex] = loop;
      const uint32_t edge = edge_from[vertex];
      loops.edge.push_back(edge);
      vertex = VertexAt(mesh, edge / 3, (edge % 3 + 1) % 3);
    } while (vertex != start);
    loops.offset.push_back(static_cast<uint32_t>(loops.edge.size()));
  }
  return loops;
}

// The regions met around each mesh vertex, walking its face fan counter-clockwise, with runs
// of faces of one cluster merged into one entry (cyclically). Around a boundary vertex the
// gap outside the mesh is one more entry, the boundary loop's virtual region k + loop, so
// that every vertex sees a cyclic sequence: the capped surface, in which each boundary loop
// is closed by one virtual face. Entry i's transition is the mesh vertex at the other end of
// the edge that separates entry i from entry i + 1 (the border crossed going on).
struct VertexFans {
  std::vector<uint32_t> offset;  // entries of vertex v: [offset[v], offset[v + 1])
  std::vector<uint32_t> entry;
  std::vector<uint32_t> transition;

  uint32_t size(uint32_t vertex) const { return offset[vertex + 1] - offset[vertex]; }
  std::span<const uint32_t> entries(uint32_t vertex) const {
    return std::span<const uint32_t>(entry).subspan(offset[vertex], size(vertex));
  }
  // The entry after global entry index `at` around its vertex.
  uint32_t next(uint32_t vertex, uint32_t at) const {
    return at + 1 == offset[vertex + 1] ? offset[vertex] : at + 1;
  }
};

// Steps from `face` to `next`, its neighbour across the edge between `vertex` and `other`.
// With consistent orientation the shared edge runs the other way in `next`: `other` follows
// `vertex` in `next` when `other_follows` is true. Returns the corner of `vertex` in `next`.
absl::StatusOr<int> StepAround(const TriangleMesh& mesh, uint32_t face, uint32_t next,
                               uint32_t vertex, uint32_t other, bool other_follows) {
  const int corner = CornerOf(mesh, next, vertex);
  const int other_corner = CornerOf(mesh, next, other);
  if (corner < 0 || other_corner < 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "the adjacency does not match the mesh: face ", next, " is given as the neighbour of face ",
        face, " across the edge (", vertex, ", ", other, ") but does not hold that edge"));
  }
  if (other_corner != (other_follows ? (corner + 1) % 3 : (corner + 2) % 3)) {
    return absl::FailedPreconditionError(
        absl::StrCat("faces ", face, " and ", next,
                     " are oriented inconsistently across their shared edge (vertices ", vertex,
                     " and ", other, "): coarsening needs a consistently oriented mesh"));
  }
  return corner;
}

absl::Status NotOneFan(uint32_t vertex) {
  return absl::InvalidArgumentError(
      absl::StrCat("the faces around vertex ", vertex, " do not form one fan (run ValidateMesh)"));
}

absl::StatusOr<VertexFans> BuildVertexFans(const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                                           const BoundaryLoops& loops,
                                           const std::vector<uint32_t>& cluster_of_face, uint32_t k,
                                           const std::atomic<bool>* cancel) {
  const size_t num_vertices = mesh.num_vertices();
  std::vector<uint32_t> valence(num_vertices, 0);
  std::vector<uint32_t> first_corner(num_vertices, kNone);
  for (size_t i = 0; i < mesh.indices.size(); ++i) {
    const uint32_t vertex = mesh.indices[i];
    if (valence[vertex]++ == 0) first_corner[vertex] = static_cast<uint32_t>(i);
  }
  VertexFans fans;
  fans.offset.assign(num_vertices + 1, 0);
  fans.entry.reserve(mesh.indices.size() / 2);
  fans.transition.reserve(mesh.indices.size() / 2);
  for (uint32_t vertex = 0; vertex < num_vertices; ++vertex) {
    if (vertex % kVerticesPerCancelCheck == 0) {
      MLCLUST_RETURN_IF_ERROR(CheckCancelled(cancel, "coarsening (vertex fans)"));
    }
    fans.offset[vertex] = static_cast<uint32_t>(fans.entry.size());
    if (valence[vertex] == 0) continue;
    uint32_t face = first_corner[vertex] / 3;
    int corner = static_cast<int>(first_corner[vertex] % 3);
    // Clockwise to the first face after the boundary gap, or once around.
    const uint32_t seed = face;
    bool boundary = false;
    for (uint32_t steps = 0;; ++steps) {
      const FaceId previous = adjacency.neighbours[face][corner];  // across vertex -> next
      if (!previous.valid()) {
        boundary = true;
        break;
      }
      if (previous.value() == seed) break;
      if (steps >= valence[vertex]) return NotOneFan(vertex);
      absl::StatusOr<int> step =
          StepAround(mesh, face, previous.value(), vertex, VertexAt(mesh, face, (corner + 1) % 3),
                     /*other_follows=*/false);
      if (!step.ok()) return step.status();
      face = previous.value();
      corner = *step;
    }
    if (boundary && loops.loop_of_vertex[vertex] == kNone) return NotOneFan(vertex);
    // Counter-clockwise over the whole fan.
    const uint32_t start = face;
    const uint32_t after_gap = VertexAt(mesh, face, (corner + 1) % 3);
    fans.entry.push_back(cluster_of_face[face]);
    fans.transition.push_back(kNone);
    for (uint32_t visited = 1;; ++visited) {
      if (visited > valence[vertex]) return NotOneFan(vertex);
      const FaceId next = adjacency.neighbours[face][(corner + 2) % 3];  // across prev -> vertex
      const uint32_t previous_vertex = VertexAt(mesh, face, (corner + 2) % 3);
      if (!next.valid() || next.value() == start) {
        if (next.valid() == boundary || visited != valence[vertex]) return NotOneFan(vertex);
        if (boundary) {
          fans.transition.back() = previous_vertex;  // the boundary edge into the vertex
          fans.entry.push_back(k + loops.loop_of_vertex[vertex]);
          fans.transition.push_back(after_gap);  // the boundary edge out of the vertex
        } else if (cluster_of_face[start] != cluster_of_face[face]) {
          fans.transition.back() = previous_vertex;
        } else if (fans.entry.size() - fans.offset[vertex] > 1) {
          fans.entry.pop_back();  // the last run continues the first one
          fans.transition.pop_back();
        }
        break;
      }
      absl::StatusOr<int> step =
          StepAround(mesh, face, next.value(), vertex, previous_vertex, /*other_follows=*/true);
      if (!step.ok()) return step.status();
      if (cluster_of_face[next.value()] != cluster_of_face[face]) {
        fans.transition.back() = previous_vertex;
        fans.entry.push_back(cluster_of_face[next.value()]);
        fans.transition.push_back(kNone);
      }
      face = next.value();
      corner = *step;
    }
  }
  fans.offset[num_vertices] = static_cast<uint32_t>(fans.entry.size());
  return fans;
}

// A cluster that the coarse mesh cannot show as one manifold vertex as it stands.
struct ClusterProblem {
  uint32_t cluster = 0;
  std::string message;
};

// Finds the clusters that are not discs. A cluster must be one edge-connected piece with
// Euler characteristic V - E + F = 1 over its own faces, edges and vertices, counting each
// boundary loop of the mesh that lies wholly inside it as filled (the coarse mesh closes it
// over). A cluster that touches itself at a vertex, has a handle or surrounds other
// clusters has a smaller characteristic; one that is a whole component a larger one.
std::vector<ClusterProblem> FindClusterProblems(const TriangleMesh& mesh,
                                                const FaceAdjacency& adjacency,
                                                const BoundaryLoops& loops,
                                                const std::vector<uint32_t>& cluster_of_face,
                                                const VertexFans& fans,
                                                const DenseClusters& dense) {
  const uint32_t k = dense.size();
  const uint32_t num_faces = static_cast<uint32_t>(mesh.num_faces());
  std::vector<int64_t> faces(k, 0), border_sides(k, 0), vertices(k, 0), filled_loops(k, 0);
  std::vector<uint32_t> first_face(k, kNone), second_piece(k, kNone), pinch(k, kNone);
  // Pieces: the edge-connected components within the clusters; a piece is met first at its
  // smallest face.
  std::vector<uint32_t> piece;
  const uint32_t num_pieces = LabelFaceComponents(adjacency, piece, cluster_of_face);
  std::vector<uint8_t> seen(num_pieces, 0);
  for (uint32_t face = 0; face < num_faces; ++face) {
    const uint32_t cluster = cluster_of_face[face];
    ++faces[cluster];
    for (FaceId neighbour : adjacency.neighbours[face]) {
      if (!neighbour.valid() || cluster_of_face[neighbour.value()] != cluster) {
        ++border_sides[cluster];
      }
    }
    if (seen[piece[face]]) continue;
    seen[piece[face]] = 1;
    if (first_face[cluster] == kNone) {
      first_face[cluster] = face;
    } else if (second_piece[cluster] == kNone) {
      second_piece[cluster] = face;
    }
  }
  std::vector<uint32_t> last_seen_at(k, kNone);
  for (uint32_t vertex = 0; vertex < mesh.num_vertices(); ++vertex) {
    for (uint32_t cluster : fans.entries(vertex)) {
      if (cluster >= k) continue;  // the boundary gap
      if (last_seen_at[cluster] == vertex) {
        if (pinch[cluster] == kNone) pinch[cluster] = vertex;
        continue;
      }
      last_seen_at[cluster] = vertex;
      ++vertices[cluster];
    }
  }
  for (uint32_t loop = 0; loop < loops.size(); ++loop) {
    const uint32_t cluster = cluster_of_face[loops.edge[loops.offset[loop]] / 3];
    bool one_cluster = true;
    for (uint32_t i = loops.offset[loop]; i < loops.offset[loop + 1] && one_cluster; ++i) {
      one_cluster = cluster_of_face[loops.edge[i] / 3] == cluster;
    }
    if (one_cluster) ++filled_loops[cluster];
  }
  std::vector<ClusterProblem> problems;
  for (uint32_t cluster = 0; cluster < k; ++cluster) {
    const uint32_t label = dense.original[cluster].value();
    if (second_piece[cluster] != kNone) {
      problems.push_back(
          {cluster, absl::StrCat("cluster ", label, " is not one edge-connected piece: faces ",
                                 first_face[cluster], " and ", second_piece[cluster],
                                 " belong to it but are not connected through "
                                 "its faces")});
      continue;
    }
    const int64_t edges = (3 * faces[cluster] + border_sides[cluster]) / 2;
    const int64_t euler = vertices[cluster] - edges + faces[cluster];
    const int64_t filled = euler + filled_loops[cluster];
    if (filled == 1) continue;
    if (pinch[cluster] != kNone) {
      problems.push_back(
          {cluster, absl::StrCat("cluster ", label, " is not a disc: it touches itself at vertex ",
                                 pinch[cluster], " (its faces there form more than one wedge)")});
    } else if (filled > 1) {
      problems.push_back(
          {cluster, absl::StrCat("cluster ", label,
                                 " covers a whole connected component of the mesh: no other "
                                 "cluster meets it")});
    } else {
      problems.push_back(
          {cluster,
           absl::StrCat("cluster ", label, " is not a disc (Euler characteristic ", euler,
                        filled_loops[cluster] > 0 ? absl::StrCat(" with ", filled_loops[cluster],
                                                                 " boundary loops filled")
                                                  : "",
                        "): it has a handle, or it surrounds other clusters or a tube")});
    }
  }
  return problems;
}

// True if adding `face` to cluster `cluster` (a disc) leaves it a disc: the face meets the
// cluster along one connected arc of its boundary. With one shared edge the opposite
// corner must not touch the cluster already (that would close a ring or pinch it).
bool IsSimpleAddition(const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                      const VertexFaceTable& vertex_faces,
                      const std::vector<uint32_t>& cluster_of_face, uint32_t face,
                      uint32_t cluster) {
  int shared = 0, shared_edge = 0;
  for (int e = 0; e < 3; ++e) {
    const FaceId neighbour = adjacency.neighbours[face][e];
    if (neighbour.valid() && cluster_of_face[neighbour.value()] == cluster) {
      ++shared;
      shared_edge = e;
    }
  }
  if (shared != 1) return shared > 1;
  const uint32_t opposite = VertexAt(mesh, face, (shared_edge + 2) % 3);
  for (uint32_t other : vertex_faces.faces_around(opposite)) {
    if (other != face && cluster_of_face[other] == cluster) return false;
  }
  return true;
}

// Grows `cluster` over `territory` (faces currently unassigned, kNone) from `seed`, taking
// only faces that keep it a disc; then gives the faces it cannot take to the neighbouring
// clusters that can take them as discs, or, where none can, to the one with most shared
// edges (forced). Returns the number of forced faces.
uint32_t GrowFromSeed(const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                      const VertexFaceTable& vertex_faces, std::vector<uint32_t>& cluster_of_face,
                      const std::vector<uint32_t>& territory, uint32_t seed, uint32_t cluster) {
  cluster_of_face[seed] = cluster;
  auto push_free_neighbours = [&](uint32_t face, std::vector<uint32_t>& to) {
    for (FaceId neighbour : adjacency.neighbours[face]) {
      if (neighbour.valid() && cluster_of_face[neighbour.value()] == kNone) {
        to.push_back(neighbour.value());
      }
    }
  };
  // The cluster first, as far as it stays a disc. A face it refuses now is tried again
  // whenever one of its edge neighbours joins.
  std::vector<uint32_t> queue;
  push_free_neighbours(seed, queue);
  for (size_t head = 0; head < queue.size(); ++head) {
    const uint32_t face = queue[head];
    if (cluster_of_face[face] != kNone ||
        !IsSimpleAddition(mesh, adjacency, vertex_faces, cluster_of_face, face, cluster)) {
      continue;
    }
    cluster_of_face[face] = cluster;
    push_free_neighbours(face, queue);
  }
  // Then the neighbours.
  auto give_away = [&](uint32_t face, bool force) {
    uint32_t best = kNone;
    int best_shared = 0;
    for (int e = 0; e < 3; ++e) {
      const FaceId neighbour = adjacency.neighbours[face][e];
      if (!neighbour.valid()) continue;
      const uint32_t other = cluster_of_face[neighbour.value()];
      if (other == kNone || other == best || (other == cluster && !force)) continue;
      if (!force &&
          !IsSimpleAddition(mesh, adjacency, vertex_faces, cluster_of_face, face, other)) {
        continue;
      }
      int shared = 0;
      for (FaceId n : adjacency.neighbours[face]) {
        shared += n.valid() && cluster_of_face[n.value()] == other;
      }
      if (shared > best_shared || (shared == best_shared && other < best)) {
        best = other;
        best_shared = shared;
      }
    }
    if (best == kNone) return false;
    cluster_of_face[face] = best;
    return true;
  };
  queue.clear();
  for (uint32_t face : territory) {
    if (cluster_of_face[face] == kNone) queue.push_back(face);
  }
  std::vector<uint32_t> waiting;
  size_t next_waiting = 0;
  uint32_t forced = 0;
  for (;;) {
    for (size_t head = 0; head < queue.size(); ++head) {
      const uint32_t face = queue[head];
      if (cluster_of_face[face] != kNone) continue;
      if (give_away(face, /*force=*/false)) {
        push_free_neighbours(face, queue);
      } else {
        waiting.push_back(face);
      }
    }
    queue.clear();
    // Nothing more moves as a disc: force the first waiting face that has a neighbour.
    bool moved = false;
    for (; next_waiting < waiting.size() && !moved; ++next_waiting) {
      const uint32_t face = waiting[next_waiting];
      if (cluster_of_face[face] == kNone && give_away(face, /*force=*/true)) {
        push_free_neighbours(face, queue);
        moved = true;
        ++forced;
      }
    }
    if (!moved) break;
  }
  for (uint32_t face : territory) {
    if (cluster_of_face[face] == kNone) {
      cluster_of_face[face] = cluster;  // no neighbour reaches it
      ++forced;
    }
  }
  return forced;
}

// Repairs a cluster that is not a disc, for the coarse connectivity only: its faces are
// re-grown from a seed face as far as it stays a disc, and the rest go to its neighbours
// (GrowFromSeed). Where the cluster was a ring around a tube, the faces that would close the
// ring end up as a strip of a neighbour across the tube. Where the strip would close a ring
// of that neighbour instead, another seed moves the gap: seeds are tried in farthest-first
// order (the most interior face first) until one needs no forced face. `territory` holds
// the cluster's faces. Returns the number of faces that changed cluster.
uint32_t RegrowCluster(const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                       const VertexFaceTable& vertex_faces, std::vector<uint32_t>& cluster_of_face,
                       const std::vector<uint32_t>& territory, uint32_t cluster) {
  constexpr int kSeeds = 8;
  absl::flat_hash_map<uint32_t, uint32_t> index;  // face -> position in territory
  for (uint32_t i = 0; i < territory.size(); ++i) index[territory[i]] = i;
  // Distances in face steps inside the territory from `sources`, lowered in `distance`.
  std::vector<uint32_t> queue;
  auto lower_distances = [&](std::vector<uint32_t>& distance) {
    for (size_t head = 0; head < queue.size(); ++head) {
      const uint32_t face = queue[head];
      const uint32_t next = distance[index[face]] + 1;
      for (FaceId neighbour : adjacency.neighbours[face]) {
        if (!neighbour.valid()) continue;
        auto it = index.find(neighbour.value());
        if (it != index.end() && distance[it->second] > next) {
          distance[it->second] = next;
          queue.push_back(neighbour.value());
        }
      }
    }
    queue.clear();
  };
  // The first seed is the face farthest from the territory's border.
  std::vector<uint32_t> distance(territory.size(), kNone);
  for (uint32_t i = 0; i < territory.size(); ++i) {
    for (FaceId neighbour : adjacency.neighbours[territory[i]]) {
      if (!neighbour.valid() || !index.contains(neighbour.value())) {
        distance[i] = 0;
        queue.push_back(territory[i]);
        break;
      }
    }
  }
  lower_distances(distance);
  std::vector<uint32_t> best_assignment;
  uint32_t best_forced = kNone;
  for (int attempt = 0; attempt < kSeeds && best_forced > 0; ++attempt) {
    uint32_t seed = 0;
    for (uint32_t i = 1; i < territory.size(); ++i) {
      if (distance[i] != kNone && (distance[seed] == kNone || distance[i] > distance[seed])) {
        seed = i;
      }
    }
    if (attempt > 0 && distance[seed] == 0) break;  // every face was a seed already
    for (uint32_t face : territory) cluster_of_face[face] = kNone;
    const uint32_t forced = GrowFromSeed(mesh, adjacency, vertex_faces, cluster_of_face, territory,
                                         territory[seed], cluster);
    if (forced < best_forced) {
      best_forced = forced;
      best_assignment.clear();
      for (uint32_t face : territory) best_assignment.push_back(cluster_of_face[face]);
    }
    // The next seed: the face farthest from the seeds so far.
    if (attempt == 0) distance.assign(territory.size(), kNone);
    distance[seed] = 0;
    queue.push_back(territory[seed]);
    lower_distances(distance);
  }
  uint32_t moved = 0;
  for (uint32_t i = 0; i < territory.size(); ++i) {
    cluster_of_face[territory[i]] = best_assignment[i];
    moved += best_assignment[i] != cluster;
  }
  return moved;
}

// Eigen-decomposition of a symmetric 3x3 matrix by cyclic Jacobi rotations: on return
// `a` is diagonal (the eigenvalues) and the columns of `v` are the eigenvectors.
void SymmetricEigen3(double a[3][3], double v[3][3]) {
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) v[i][j] = i == j ? 1 : 0;
  }
  for (int sweep = 0; sweep < 32; ++sweep) {
    const double off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
    const double diagonal = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
    if (off <= 1e-30 * diagonal || off == 0) return;
    for (int p = 0; p < 2; ++p) {
      for (int q = p + 1; q < 3; ++q) {
        if (a[p][q] == 0) continue;
        // The rotation J (c on the diagonal at p and q, J[p][q] = s, J[q][p] = -s) that
        // zeroes a[p][q] in J^T a J (Numerical Recipes, section 11.1).
        const double theta = (a[q][q] - a[p][p]) / (2 * a[p][q]);
        const double t = (theta >= 0 ? 1.0 : -1.0) / (std::abs(theta) + std::hypot(theta, 1.0));
        const double c = 1 / std::sqrt(t * t + 1);
        const double s = t * c;
        double rotated[3][3];
        for (int i = 0; i < 3; ++i) {  // a J
          rotated[i][p] = c * a[i][p] - s * a[i][q];
          rotated[i][q] = s * a[i][p] + c * a[i][q];
          const int r = 3 - p - q;
          rotated[i][r] = a[i][r];
        }
        for (int j = 0; j < 3; ++j) {  // J^T (a J)
          const double ap = rotated[p][j], aq = rotated[q][j];
          a[p][j] = c * ap - s * aq;
          a[q][j] = s * ap + c * aq;
          a[3 - p - q][j] = rotated[3 - p - q][j];
        }
        a[p][q] = a[q][p] = 0;
        for (int i = 0; i < 3; ++i) {  // v J
          const double vp = v[i][p], vq = v[i][q];
          v[i][p] = c * vp - s * vq;
          v[i][q] = s * vp + c * vq;
        }
      }
    }
  }
}

// Sums over a cluster's faces: area, area-weighted centroid, plain centroid, and for the
// Garland-Heckbert quadric sum_j A_j (n_j . (x - g_j))^2 its matrix Q = sum_j A_j n_j n_j^T
// and, in a second pass about the centroid c, r = sum_j A_j n_j (n_j . (g_j - c)): the
// quadric's gradient at x is 2 (Q (x - c) - r). Working about the centroid keeps the sums
// small where the mesh is far from the origin.
struct ClusterSums {
  double area = 0;
  Vec3 weighted_centroid;
  Vec3 centroid_sum;
  uint32_t faces = 0;
  double quadric[3][3] = {{0, 0, 0}, {0, 0, 0}, {0, 0, 0}};
  Vec3 residual;
};

// The minimiser of the quadric nearest to `centroid`: centroid + Q^+ r, where the
// pseudo-inverse drops the eigen-directions whose eigenvalue is at most
// `relative_threshold` times the largest (Lindstrom's SVD approach). Those directions are
// unconstrained by the planes (a planar cluster has two, a crease one) and keep the
// centroid's coordinate instead of flying off along them.
Vec3 QuadricMinimiser(const ClusterSums& sums, const Vec3& centroid, double relative_threshold) {
  double a[3][3], v[3][3];
  std::copy(&sums.quadric[0][0], &sums.quadric[0][0] + 9, &a[0][0]);
  SymmetricEigen3(a, v);
  const double largest = std::max({std::abs(a[0][0]), std::abs(a[1][1]), std::abs(a[2][2])});
  if (!(largest > 0) || !std::isfinite(largest)) return centroid;
  Vec3 position = centroid;
  for (int i = 0; i < 3; ++i) {
    const double eigenvalue = a[i][i];
    if (eigenvalue <= relative_threshold * largest) continue;
    const Vec3 direction{v[0][i], v[1][i], v[2][i]};
    position += (Dot(direction, sums.residual) / eigenvalue) * direction;
  }
  return position;
}

std::vector<Vec3> PlaceCoarseVertices(const TriangleMesh& mesh, const DenseClusters& dense,
                                      const CoarseningOptions& options) {
  const FaceMeasures measures = ComputeFaceMeasures(mesh);
  std::vector<ClusterSums> sums(dense.size());
  const bool quadric = options.placement == CoarseningOptions::Placement::kQuadric;
  const bool weighted = !options.face_density.empty();
  for (size_t face = 0; face < measures.num_faces(); ++face) {
    ClusterSums& s = sums[dense.dense[face]];
    const double area = measures.area[face];
    // Eq. 3.6 / 3.22: the mass of a face is rho_j A_j.
    const double mass = weighted ? options.face_density[face] * area : area;
    s.area += mass;
    s.weighted_centroid += mass * measures.centroid[face];
    s.centroid_sum += measures.centroid[face];
    ++s.faces;
    if (quadric) {
      const Vec3& n = measures.unit_normal[face];  // zero for a zero-area face
      const double nn[3] = {n.x, n.y, n.z};
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) s.quadric[i][j] += area * nn[i] * nn[j];
      }
    }
  }
  std::vector<Vec3> centroids(dense.size());
  for (size_t cluster = 0; cluster < dense.size(); ++cluster) {
    const ClusterSums& s = sums[cluster];
    centroids[cluster] =
        s.area > 0 ? s.weighted_centroid / s.area : s.centroid_sum / static_cast<double>(s.faces);
  }
  if (options.placement == CoarseningOptions::Placement::kClosestVertex) {
    // [VC04]: the cluster's own mesh vertex nearest to its centroid.
    std::vector<double> best(dense.size(), std::numeric_limits<double>::infinity());
    std::vector<uint32_t> best_vertex(dense.size(), 0);
    for (size_t face = 0; face < measures.num_faces(); ++face) {
      const uint32_t cluster = dense.dense[face];
      for (int c = 0; c < 3; ++c) {
        const uint32_t vertex = mesh.indices[3 * face + c];
        const double d = SquaredNorm(mesh.position(VertexId(vertex)) - centroids[cluster]);
        if (d < best[cluster] || (d == best[cluster] && vertex < best_vertex[cluster])) {
          best[cluster] = d;
          best_vertex[cluster] = vertex;
        }
      }
    }
    std::vector<Vec3> positions(dense.size());
    for (size_t cluster = 0; cluster < dense.size(); ++cluster) {
      positions[cluster] = mesh.position(VertexId(best_vertex[cluster]));
    }
    return positions;
  }
  if (!quadric) return centroids;
  for (size_t face = 0; face < measures.num_faces(); ++face) {
    const uint32_t cluster = dense.dense[face];
    const Vec3& n = measures.unit_normal[face];
    sums[cluster].residual +=
        (measures.area[face] * Dot(n, measures.centroid[face] - centroids[cluster])) * n;
  }
  std::vector<Vec3> positions(dense.size());
  for (size_t cluster = 0; cluster < dense.size(); ++cluster) {
    positions[cluster] =
        QuadricMinimiser(sums[cluster], centroids[cluster], options.quadric_relative_eigenvalue);
  }
  return positions;
}

// The coarse triangles of the capped surface: the clusters 0..k-1 and one virtual vertex
// k + l per boundary loop l. Halfedge 3t + i runs from triangles[t][i] to
// triangles[t][(i + 1) % 3]; twin is the same edge in the neighbouring triangle.
struct CoarseTriangulation {
  std::vector<std::array<uint32_t, 3>> triangles;
  std::vector<uint32_t> twin;
  std::vector<uint32_t> corner;  // the mesh vertex whose polygon gave each triangle
  uint32_t num_vertices = 0;     // k plus the boundary loops
};

// Builds the dual of the clusters' border graph on the capped surface: one polygon per
// corner (a mesh vertex with three or more entries around it), its sides paired with the
// other end of each border arc, triangulated (see the header's rules).
absl::StatusOr<CoarseTriangulation> BuildCappedDual(const TriangleMesh& mesh,
                                                    const VertexFans& fans,
                                                    const std::vector<Vec3>& positions, uint32_t k,
                                                    uint32_t num_loops,
                                                    const std::atomic<bool>* cancel) {
  const uint32_t num_vertices = static_cast<uint32_t>(mesh.num_vertices());
  auto is_corner = [&](uint32_t vertex) { return fans.size(vertex) >= 3; };
  // Pair each polygon side (entry a -> next entry b at corner v) with the side b -> a at
  // the corner where the border arc that starts across `transition` ends.
  std::vector<uint32_t> twin_side(fans.entry.size(), kNone);
  absl::flat_hash_set<uint64_t> edges;  // undirected coarse edges of the sides
  for (uint32_t vertex = 0; vertex < num_vertices; ++vertex) {
    if (vertex % kVerticesPerCancelCheck == 0) {
      MLCLUST_RETURN_IF_ERROR(CheckCancelled(cancel, "coarsening (dual)"));
    }
    if (!is_corner(vertex)) continue;
    for (uint32_t side = fans.offset[vertex]; side < fans.offset[vertex + 1]; ++side) {
      const uint32_t a = fans.entry[side], b = fans.entry[fans.next(vertex, side)];
      edges.insert(UndirectedKey(a, b));
      if (twin_side[side] != kNone) continue;
      uint32_t previous = vertex, current = fans.transition[side];
      for (uint32_t steps = 0; current != kNone && fans.size(current) == 2; ++steps) {
        const uint32_t t0 = fans.transition[fans.offset[current]];
        const uint32_t t1 = fans.transition[fans.offset[current] + 1];
        const uint32_t next = t0 == previous ? t1 : (t1 == previous ? t0 : kNone);
        if (next == kNone || steps > num_vertices) {
          current = kNone;
          break;
        }
        previous = current;
        current = next;
      }
      uint32_t other = kNone;
      if (current != kNone && is_corner(current)) {
        for (uint32_t s = fans.offset[current]; s < fans.offset[current + 1]; ++s) {
          if (fans.transition[s] == previous && fans.entry[s] == b &&
              fans.entry[fans.next(current, s)] == a) {
            other = s;
          }
        }
      }
      if (other == kNone || twin_side[other] != kNone) {
        return absl::InternalError(absl::StrCat("the border arc between regions ", a, " and ", b,
                                                " leaving mesh vertex ", vertex,
                                                " does not end at a corner"));
      }
      twin_side[side] = other;
      twin_side[other] = side;
    }
  }

  CoarseTriangulation dual;
  dual.num_vertices = k + num_loops;
  std::vector<uint32_t> side_halfedge(fans.entry.size(), kNone);
  absl::flat_hash_map<uint64_t, uint32_t> diagonal;  // (from, to) polygon positions -> halfedge
  std::vector<uint32_t> rest;
  for (uint32_t vertex = 0; vertex < num_vertices; ++vertex) {
    if (!is_corner(vertex)) continue;
    const uint32_t begin = fans.offset[vertex], n = fans.size(vertex);
    const uint32_t* polygon = fans.entry.data() + begin;
    diagonal.clear();
    // Emits the triangle of polygon positions (p, q, r): a halfedge between neighbouring
    // positions is that polygon side; any other is a diagonal, paired inside the polygon.
    auto emit = [&](uint32_t p, uint32_t q, uint32_t r) {
      const uint32_t t = static_cast<uint32_t>(dual.triangles.size());
      dual.triangles.push_back({polygon[p], polygon[q], polygon[r]});
      dual.corner.push_back(vertex);
      dual.twin.insert(dual.twin.end(), {kNone, kNone, kNone});
      const uint32_t ends[3][2] = {{p, q}, {q, r}, {r, p}};
      for (int i = 0; i < 3; ++i) {
        const uint32_t from = ends[i][0], to = ends[i][1], h = 3 * t + i;
        if ((from + 1) % n == to) {
          side_halfedge[begin + from] = h;
        } else if (auto it = diagonal.find(EdgeKey(to, from)); it != diagonal.end()) {
          dual.twin[h] = it->second;
          dual.twin[it->second] = h;
        } else {
          diagonal[EdgeKey(from, to)] = h;
        }
      }
    };
    // A boundary loop's virtual vertex gets the ear between its two neighbours, so that
    // the coarse boundary runs straight from the cluster before the gap to the one after.
    rest.clear();
    uint32_t virtual_at = kNone;
    for (uint32_t p = 0; p < n; ++p) {
      if (polygon[p] >= k) virtual_at = p;
    }
    for (uint32_t t = 1; t <= n; ++t) {
      const uint32_t p = virtual_at == kNone ? t - 1 : (virtual_at + t) % n;
      if (p != virtual_at) rest.push_back(p);
    }
    if (virtual_at != kNone) emit((virtual_at + n - 1) % n, virtual_at, (virtual_at + 1) % n);
    const uint32_t m = static_cast<uint32_t>(rest.size());
    if (m < 3) continue;
    // The fan from rest[i] has the diagonals (rest[i], rest[j]) for j not next to i. Prefer
    // apexes whose diagonals are not coarse edges already, then the shortest diagonals.
    // The search costs O(m^2); a corner of more clusters than kApexSearch (only pathological
    // clusterings have one) takes the fan from its first cluster.
    constexpr uint32_t kApexSearch = 64;
    uint32_t best_apex = 0;
    bool best_fresh = false;
    double best_length = std::numeric_limits<double>::infinity();
    for (uint32_t i = 0; i < m && m <= kApexSearch; ++i) {
      bool fresh = true;
      double length = 0;
      const uint32_t apex = polygon[rest[i]];
      for (uint32_t t = 2; t + 1 < m; ++t) {
        const uint32_t other = polygon[rest[(i + t) % m]];
        fresh = fresh && !edges.contains(UndirectedKey(apex, other));
        length += Norm(positions[apex] - positions[other]);
      }
      if ((fresh && !best_fresh) || (fresh == best_fresh && length < best_length)) {
        best_apex = i;
        best_fresh = fresh;
        best_length = length;
      }
    }
    for (uint32_t t = 1; t + 1 < m; ++t) {
      const uint32_t q = rest[(best_apex + t) % m], r = rest[(best_apex + t + 1) % m];
      if (t >= 2) edges.insert(UndirectedKey(polygon[rest[best_apex]], polygon[q]));
      emit(rest[best_apex], q, r);
    }
  }
  for (uint32_t side = 0; side < side_halfedge.size(); ++side) {
    if (side_halfedge[side] == kNone) continue;
    dual.twin[side_halfedge[side]] = side_halfedge[twin_side[side]];
  }
  return dual;
}

// Edge flips on a CoarseTriangulation, keeping twins, the triangles around each vertex and
// the number of edges between each pair of vertices up to date.
class Flipper {
 public:
  explicit Flipper(CoarseTriangulation& dual) : dual_(dual), star_(dual.num_vertices) {
    for (uint32_t t = 0; t < dual.triangles.size(); ++t) {
      for (uint32_t v : dual.triangles[t]) star_[v].push_back(t);
    }
    for (uint32_t h = 0; h < dual.twin.size(); ++h) {
      if (h < dual.twin[h]) ++edge_count_[Key(h)];
    }
  }

  uint32_t flips() const { return flips_; }
  uint32_t EdgeCount(uint32_t a, uint32_t b) const {
    auto it = edge_count_.find(UndirectedKey(a, b));
    return it == edge_count_.end() ? 0 : it->second;
  }
  std::vector<uint64_t> DoubledEdges() const {
    std::vector<uint64_t> doubled;
    for (const auto& [key, count] : edge_count_) {
      if (count > 1) doubled.push_back(key);
    }
    std::sort(doubled.begin(), doubled.end());
    return doubled;
  }
  const std::vector<uint32_t>& Star(uint32_t vertex) const { return star_[vertex]; }
  uint32_t From(uint32_t h) const { return dual_.triangles[h / 3][h % 3]; }
  uint32_t To(uint32_t h) const { return dual_.triangles[h / 3][(h % 3 + 1) % 3]; }
  // The vertices opposite halfedge h and its twin: the ends of the edge a flip would make.
  std::pair<uint32_t, uint32_t> FlipEnds(uint32_t h) const {
    const uint32_t g = dual_.twin[h];
    return {dual_.triangles[h / 3][(h % 3 + 2) % 3], dual_.triangles[g / 3][(g % 3 + 2) % 3]};
  }

  // Flips the edge of halfedge h (triangles (a, b, c) and (b, a, d) become (a, d, c) and
  // (d, b, c)) unless that would repeat an existing edge. Returns whether it flipped.
  bool TryFlip(uint32_t h) {
    auto& tri = dual_.triangles;
    auto& twin = dual_.twin;
    const uint32_t g = twin[h];
    const uint32_t t1 = h / 3, i = h % 3, t2 = g / 3, j = g % 3;
    const uint32_t a = tri[t1][i], b = tri[t1][(i + 1) % 3], c = tri[t1][(i + 2) % 3];
    const uint32_t d = tri[t2][(j + 2) % 3];
    if (c == d || EdgeCount(c, d) > 0) return false;
    const uint32_t outer_bc = twin[3 * t1 + (i + 1) % 3], outer_ca = twin[3 * t1 + (i + 2) % 3];
    const uint32_t outer_ad = twin[3 * t2 + (j + 1) % 3], outer_db = twin[3 * t2 + (j + 2) % 3];
    tri[t1] = {a, d, c};
    tri[t2] = {d, b, c};
    auto link = [&](uint32_t x, uint32_t y) {
      twin[x] = y;
      twin[y] = x;
    };
    link(3 * t1, outer_ad);
    link(3 * t1 + 1, 3 * t2 + 2);
    link(3 * t1 + 2, outer_ca);
    link(3 * t2, outer_db);
    link(3 * t2 + 1, outer_bc);
    auto erase = [](std::vector<uint32_t>& list, uint32_t value) {
      if (auto it = std::find(list.begin(), list.end(), value); it != list.end()) list.erase(it);
    };
    erase(star_[a], t2);
    erase(star_[b], t1);
    star_[c].push_back(t2);
    star_[d].push_back(t1);
    if (--edge_count_[UndirectedKey(a, b)] == 0) edge_count_.erase(UndirectedKey(a, b));
    edge_count_[UndirectedKey(c, d)] = 1;
    ++flips_;
    return true;
  }

 private:
  uint64_t Key(uint32_t h) const { return UndirectedKey(From(h), To(h)); }

  CoarseTriangulation& dual_;
  std::vector<std::vector<uint32_t>> star_;
  absl::flat_hash_map<uint64_t, uint32_t> edge_count_;
  uint32_t flips_ = 0;
};

std::string RegionName(uint32_t vertex, const DenseClusters& dense) {
  if (vertex < dense.size()) return absl::StrCat("cluster ", dense.original[vertex].value());
  return absl::StrCat("boundary loop ", vertex - dense.size());
}

// The halfedges of all edges between u and v, one per edge.
std::vector<uint32_t> EdgesBetween(const Flipper& flipper, const CoarseTriangulation& dual,
                                   uint32_t u, uint32_t v) {
  std::vector<uint32_t> found;
  for (uint32_t t : flipper.Star(u)) {
    for (uint32_t i = 0; i < 3; ++i) {
      if (dual.triangles[t][i] == u && dual.triangles[t][(i + 1) % 3] == v) {
        found.push_back(3 * t + i);
      }
    }
  }
  return found;
}

// Two clusters that meet along two border arcs, a cluster that meets only two others, or
// the same triangle from two corners all give two edges between one pair of vertices.
// Each doubled edge is flipped away (a flip that makes a new edge that is not there yet;
// where the new edge is there already, that one is flipped out of the way first, up to
// kMakeWayDepth edges deep), which keeps the surface and its topology. Every flip keeps
// edges single, and each successful round removes one doubled edge, so this ends.
// Returns the doubled edges left (undirected keys), none on success.
std::vector<uint64_t> RemoveDoubledEdges(Flipper& flipper, const CoarseTriangulation& dual) {
  constexpr int kMakeWayDepth = 3;
  std::function<bool(uint32_t, int)> flip = [&](uint32_t h, int depth) {
    if (flipper.TryFlip(h)) return true;
    const auto [c, d] = flipper.FlipEnds(h);
    if (depth == 0 || c == d || flipper.EdgeCount(c, d) != 1) return false;
    std::vector<uint32_t> in_the_way = EdgesBetween(flipper, dual, c, d);
    if (in_the_way.empty()) in_the_way = EdgesBetween(flipper, dual, d, c);
    const uint32_t from = flipper.From(h), to = flipper.To(h), across = dual.twin[h] / 3;
    if (in_the_way.empty() || !flip(in_the_way.front(), depth - 1)) return false;
    // The flips out of the way may have moved h's edge; retry only if it is where it was.
    if (flipper.From(h) != from || flipper.To(h) != to || dual.twin[h] / 3 != across) {
      return false;
    }
    return flipper.TryFlip(h);
  };
  auto flip_one_copy = [&](uint32_t u, uint32_t v) {
    for (int depth = 0; depth <= kMakeWayDepth; ++depth) {
      // A failed attempt may have moved the copies: list them again before each one.
      for (size_t copy = 0;; ++copy) {
        const std::vector<uint32_t> copies = EdgesBetween(flipper, dual, u, v);
        if (copy >= copies.size()) break;
        if (flip(copies[copy], depth)) return true;
      }
    }
    return false;
  };
  for (bool progress = true; progress;) {
    progress = false;
    for (uint64_t key : flipper.DoubledEdges()) {
      const uint32_t u = static_cast<uint32_t>(key >> 32), v = static_cast<uint32_t>(key);
      while (flipper.EdgeCount(u, v) > 1 && flip_one_copy(u, v)) progress = true;
    }
  }
  return flipper.DoubledEdges();
}

// The boundary loops' virtual vertices next to `vertex`.
std::vector<uint32_t> VirtualNeighbours(const Flipper& flipper, const CoarseTriangulation& dual,
                                        uint32_t vertex, uint32_t k) {
  std::vector<uint32_t> found;
  for (uint32_t t : flipper.Star(vertex)) {
    for (uint32_t v : dual.triangles[t]) {
      if (v >= k && v != vertex && std::find(found.begin(), found.end(), v) == found.end()) {
        found.push_back(v);
      }
    }
  }
  return found;
}

// A cluster next to two boundary loops' virtual vertices would, once they are removed, lie
// on two coarse boundary loops: a non-manifold vertex. Flips its edges to all but one of
// them away where that does not put another cluster next to two. Returns a cluster that is
// still next to two loops, with two of them, or nothing.
struct LoopConflict {
  uint32_t cluster = kNone;
  uint32_t first = kNone, second = kNone;  // virtual vertices
};

LoopConflict SeparateBoundaryLoops(Flipper& flipper, const CoarseTriangulation& dual, uint32_t k) {
  for (uint32_t cluster = 0; cluster < k; ++cluster) {
    std::vector<uint32_t> loops = VirtualNeighbours(flipper, dual, cluster, k);
    for (size_t attempt = 0; loops.size() > 1 && attempt < 4 * loops.size(); ++attempt) {
      bool flipped = false;
      for (size_t s = 0; s < flipper.Star(cluster).size() && !flipped; ++s) {
        const uint32_t t = flipper.Star(cluster)[s];
        for (uint32_t i = 0; i < 3 && !flipped; ++i) {
          const uint32_t h = 3 * t + i;
          if (dual.triangles[t][i] != cluster || dual.triangles[t][(i + 1) % 3] < k ||
              dual.triangles[t][(i + 1) % 3] == loops.front()) {
            continue;
          }
          // The new edge must not put a cluster next to a second loop.
          const auto [c, d] = flipper.FlipEnds(h);
          auto adds_second_loop = [&](uint32_t x, uint32_t loop) {
            if (x >= k || loop < k) return false;
            const std::vector<uint32_t> has = VirtualNeighbours(flipper, dual, x, k);
            return !has.empty() && (has.size() > 1 || has.front() != loop);
          };
          if (adds_second_loop(c, d) || adds_second_loop(d, c)) continue;
          flipped = flipper.TryFlip(h);
        }
      }
      if (!flipped) break;
      loops = VirtualNeighbours(flipper, dual, cluster, k);
    }
    if (loops.size() > 1) return {cluster, loops[0], loops[1]};
  }
  return {};
}

// Closes boundary loop `loop` over by giving its virtual region (the cap) to one of the
// clusters along it: in the fans of the loop's vertices the loop's entry becomes that
// cluster, merged with its neighbours where they are the same cluster. The cluster must
// meet the loop along one arc and touch it nowhere else, so that it stays a disc with the
// cap. Takes the cluster with most boundary edges on the loop among those.
bool FillLoop(const TriangleMesh& mesh, const BoundaryLoops& loops,
              const std::vector<uint32_t>& cluster_of_face, uint32_t loop, uint32_t k,
              VertexFans& fans) {
  const uint32_t begin = loops.offset[loop], end = loops.offset[loop + 1];
  const uint32_t cap = k + loop;
  absl::flat_hash_map<uint32_t, std::pair<uint32_t, uint32_t>> arcs_and_edges;
  for (uint32_t i = begin; i < end; ++i) {
    const uint32_t cluster = cluster_of_face[loops.edge[i] / 3];
    const uint32_t before = cluster_of_face[loops.edge[i == begin ? end - 1 : i - 1] / 3];
    auto& [arcs, edges] = arcs_and_edges[cluster];
    arcs += before != cluster;
    ++edges;
  }
  std::vector<std::pair<uint32_t, uint32_t>> candidates;  // (edges, cluster)
  for (const auto& [cluster, counts] : arcs_and_edges) {
    if (counts.first == 1) candidates.push_back({counts.second, cluster});
  }
  std::sort(candidates.begin(), candidates.end(), [](const auto& a, const auto& b) {
    return a.first != b.first ? a.first > b.first : a.second < b.second;
  });
  // The loop's vertices' new fans: (entry, transition) lists.
  using Fan = std::vector<std::pair<uint32_t, uint32_t>>;
  std::vector<std::pair<uint32_t, Fan>> changed;
  for (const auto& [edges, filler] : candidates) {
    changed.clear();
    bool pinched = false;
    for (uint32_t i = begin; i < end && !pinched; ++i) {
      const uint32_t vertex = VertexAt(mesh, loops.edge[i] / 3, loops.edge[i] % 3);
      Fan fan;
      for (uint32_t at = fans.offset[vertex]; at < fans.offset[vertex + 1]; ++at) {
        fan.push_back({fans.entry[at] == cap ? filler : fans.entry[at], fans.transition[at]});
      }
      size_t p = 0;
      while (p < fan.size() && fans.entry[fans.offset[vertex] + p] != cap) ++p;
      // Merge the filler's entry with the one before it and the one after it.
      if (fan.size() > 1 && fan[(p + fan.size() - 1) % fan.size()].first == filler) {
        const size_t q = (p + fan.size() - 1) % fan.size();
        fan[q].second = fan[p].second;
        fan.erase(fan.begin() + p);
        p = q < p ? q : q - 1;
      }
      if (fan.size() > 1 && fan[(p + 1) % fan.size()].first == filler) {
        const size_t n = (p + 1) % fan.size();
        fan[p].second = fan[n].second;
        fan.erase(fan.begin() + n);
      }
      pinched = std::count_if(fan.begin(), fan.end(),
                              [&](const auto& e) { return e.first == filler; }) > 1;
      changed.push_back({vertex, std::move(fan)});
    }
    if (pinched) continue;
    // Rebuild the compressed rows with the changed fans.
    std::sort(changed.begin(), changed.end(),
              [](const auto& a, const auto& b) { return a.first < b.first; });
    VertexFans rebuilt;
    rebuilt.offset.assign(fans.offset.size(), 0);
    size_t next_changed = 0;
    for (uint32_t vertex = 0; vertex + 1 < fans.offset.size(); ++vertex) {
      rebuilt.offset[vertex] = static_cast<uint32_t>(rebuilt.entry.size());
      if (next_changed < changed.size() && changed[next_changed].first == vertex) {
        for (const auto& [entry, transition] : changed[next_changed].second) {
          rebuilt.entry.push_back(entry);
          rebuilt.transition.push_back(transition);
        }
        ++next_changed;
        continue;
      }
      for (uint32_t at = fans.offset[vertex]; at < fans.offset[vertex + 1]; ++at) {
        rebuilt.entry.push_back(fans.entry[at]);
        rebuilt.transition.push_back(fans.transition[at]);
      }
    }
    rebuilt.offset.back() = static_cast<uint32_t>(rebuilt.entry.size());
    fans = std::move(rebuilt);
    return true;
  }
  return false;
}

// Checks that the coarse triangles form a manifold: each directed edge once, every edge
// with two triangles if the input is closed, every vertex used, and the triangles around
// each vertex one fan.
absl::Status CheckCoarseManifold(const std::vector<std::array<uint32_t, 3>>& triangles,
                                 const DenseClusters& dense, bool closed) {
  const uint32_t k = dense.size();
  auto label = [&](uint32_t cluster) { return dense.original[cluster].value(); };
  if (triangles.empty()) {
    return absl::FailedPreconditionError(absl::StrCat(
        "no vertex of the mesh is a corner where three or more of the ", k,
        " clusters (or two and the mesh boundary) meet, so the coarse mesh would have no "
        "triangle"));
  }
  absl::flat_hash_set<uint64_t> directed;
  directed.reserve(3 * triangles.size());
  for (const auto& t : triangles) {
    if (t[0] == t[1] || t[1] == t[2] || t[0] == t[2]) {
      return absl::InternalError(absl::StrCat("a coarse triangle repeats cluster ",
                                              label(t[0] == t[1] || t[0] == t[2] ? t[0] : t[1])));
    }
    for (int i = 0; i < 3; ++i) {
      if (!directed.insert(EdgeKey(t[i], t[(i + 1) % 3])).second) {
        return absl::InternalError(absl::StrCat("the coarse edge from cluster ", label(t[i]),
                                                " to cluster ", label(t[(i + 1) % 3]),
                                                " borders two triangles on the same side"));
      }
    }
  }
  if (closed) {
    for (uint64_t edge : directed) {
      const uint32_t a = static_cast<uint32_t>(edge >> 32), b = static_cast<uint32_t>(edge);
      if (!directed.contains(EdgeKey(b, a))) {
        return absl::InternalError(absl::StrCat("the coarse edge between clusters ", label(a),
                                                " and ", label(b),
                                                " borders one triangle on a closed mesh"));
      }
    }
  }
  // Triangles around each vertex, compressed rows.
  std::vector<uint32_t> offset(k + 1, 0);
  for (const auto& t : triangles) {
    for (uint32_t v : t) ++offset[v + 1];
  }
  for (uint32_t cluster = 0; cluster < k; ++cluster) {
    if (offset[cluster + 1] == 0) {
      return absl::FailedPreconditionError(absl::StrCat(
          "cluster ", label(cluster),
          " has no coarse triangle: no corner of three or more clusters lies on its border "
          "(it meets fewer than three other clusters and the mesh boundary)"));
    }
    offset[cluster + 1] += offset[cluster];
  }
  std::vector<std::pair<uint32_t, uint32_t>> link(offset[k]);  // (from, to) opposite vertex
  std::vector<uint32_t> cursor(offset.begin(), offset.end() - 1);
  for (const auto& t : triangles) {
    for (int i = 0; i < 3; ++i) link[cursor[t[i]]++] = {t[(i + 1) % 3], t[(i + 2) % 3]};
  }
  std::vector<uint32_t> ends;
  for (uint32_t cluster = 0; cluster < k; ++cluster) {
    auto first = link.begin() + offset[cluster], last = link.begin() + offset[cluster + 1];
    std::sort(first, last);
    // Directed edges are unique, so each link vertex starts at most one link edge and
    // ends at most one: the link is paths and cycles. It must be one path or one cycle.
    const size_t size = last - first;
    ends.clear();
    for (auto it = first; it != last; ++it) ends.push_back(it->second);
    std::sort(ends.begin(), ends.end());
    uint32_t start = first->first;
    size_t path_starts = 0;
    for (auto it = first; it != last; ++it) {
      if (!std::binary_search(ends.begin(), ends.end(), it->first)) {
        ++path_starts;
        start = it->first;
      }
    }
    size_t walked = 0;
    for (uint32_t at = start; walked <= size;) {
      auto next = std::lower_bound(first, last, std::make_pair(at, uint32_t{0}));
      if (next == last || next->first != at) break;
      ++walked;
      at = next->second;
      if (at == start) break;
    }
    if (path_starts > 1 || walked != size) {
      return absl::FailedPreconditionError(
          absl::StrCat("cluster ", label(cluster),
                       ": its coarse triangles do not form one fan, so its coarse vertex would be "
                       "non-manifold"));
    }
  }
  return absl::OkStatus();
}

}  // namespace

std::vector<ClusterId> CoarseVertexClusters(std::span<const ClusterId> labels) {
  return RenumberByFirstAppearance(labels).original;
}

absl::StatusOr<CoarseMesh> CoarsenMeshWithReport(const TriangleMesh& mesh,
                                                 const FaceAdjacency& adjacency,
                                                 std::span<const ClusterId> labels,
                                                 const CoarseningOptions& options) {
  MLCLUST_RETURN_IF_ERROR(CheckInputs(mesh, adjacency, labels));
  if (!(options.quadric_relative_eigenvalue >= 0 && options.quadric_relative_eigenvalue < 1)) {
    return absl::InvalidArgumentError(absl::StrCat("quadric_relative_eigenvalue is ",
                                                   options.quadric_relative_eigenvalue,
                                                   "; it must be in [0, 1)"));
  }
  if (options.max_repair_rounds < 0) {
    return absl::InvalidArgumentError(absl::StrCat(
        "max_repair_rounds is ", options.max_repair_rounds, "; it must not be negative"));
  }
  if (!options.face_density.empty()) {
    if (options.face_density.size() != mesh.num_faces()) {
      return absl::InvalidArgumentError(absl::StrCat("face_density holds ",
                                                     options.face_density.size(), " values for ",
                                                     mesh.num_faces(), " faces"));
    }
    for (size_t face = 0; face < options.face_density.size(); ++face) {
      const double rho = options.face_density[face];
      if (!(rho > 0) || !std::isfinite(rho)) {
        return absl::InvalidArgumentError(
            absl::StrCat("face_density of face ", face, " is ", rho, "; it must be positive"));
      }
    }
  }
  auto check_cancel = [&] { return CheckCancelled(options.cancel, "coarsening"); };
  MLCLUST_RETURN_IF_ERROR(check_cancel());
  const DenseClusters dense = RenumberByFirstAppearance(labels);
  const uint32_t k = dense.size();
  MLCLUST_RETURN_IF_ERROR(check_cancel());
  absl::StatusOr<BoundaryLoops> loops = FindBoundaryLoops(mesh, adjacency);
  if (!loops.ok()) return loops.status();

  CoarseMesh result;
  // The clusters the connectivity is built from: the caller's, or repaired ones.
  std::vector<uint32_t> cluster_of_face = dense.dense;
  absl::StatusOr<VertexFans> fans;
  VertexFaceTable vertex_faces;
  absl::flat_hash_set<uint32_t> repaired;
  for (int round = 0;; ++round) {
    MLCLUST_RETURN_IF_ERROR(check_cancel());
    fans = BuildVertexFans(mesh, adjacency, *loops, cluster_of_face, k, options.cancel);
    if (!fans.ok()) return fans.status();
    MLCLUST_RETURN_IF_ERROR(check_cancel());
    const std::vector<ClusterProblem> problems =
        FindClusterProblems(mesh, adjacency, *loops, cluster_of_face, *fans, dense);
    if (problems.empty()) break;
    if (!options.repair_clusters) {
      return absl::FailedPreconditionError(
          absl::StrCat(problems.front().message,
                       "; the coarse mesh needs every cluster to be a disc (repair_clusters is "
                       "off)"));
    }
    if (round == options.max_repair_rounds) {
      return absl::FailedPreconditionError(
          absl::StrCat(problems.front().message, "; still so after ", round,
                       " rounds of repair (its neighbours cannot take its faces and stay discs)"));
    }
    if (vertex_faces.offset.empty()) vertex_faces = BuildVertexFaceTable(mesh);
    absl::flat_hash_map<uint32_t, std::vector<uint32_t>> territory;  // the problems' faces
    for (const ClusterProblem& problem : problems) territory[problem.cluster];
    for (uint32_t face = 0; face < cluster_of_face.size(); ++face) {
      auto it = territory.find(cluster_of_face[face]);
      if (it != territory.end()) it->second.push_back(face);
    }
    for (const ClusterProblem& problem : problems) {
      const std::vector<uint32_t>& faces = territory[problem.cluster];
      result.moved_faces +=
          RegrowCluster(mesh, adjacency, vertex_faces, cluster_of_face, faces, problem.cluster);
      repaired.insert(problem.cluster);
      // Faces given to a cluster that is still to be re-grown join its territory.
      for (uint32_t face : faces) {
        const uint32_t now = cluster_of_face[face];
        if (now != problem.cluster) {
          if (auto it = territory.find(now); it != territory.end()) it->second.push_back(face);
        }
      }
    }
  }
  result.repaired_clusters = static_cast<uint32_t>(repaired.size());

  const std::vector<Vec3> positions = PlaceCoarseVertices(mesh, dense, options);
  // The dual of the capped surface, with doubled edges flipped away. A boundary loop whose
  // virtual vertex keeps a doubled edge, or next to which a cluster lies on a second loop,
  // is closed over (FillLoop) and the dual built again.
  std::vector<std::array<uint32_t, 3>> triangles;
  auto loop_length = [&](uint32_t loop) { return loops->offset[loop + 1] - loops->offset[loop]; };
  for (uint32_t attempt = 0;; ++attempt) {
    MLCLUST_RETURN_IF_ERROR(check_cancel());
    absl::StatusOr<CoarseTriangulation> dual =
        BuildCappedDual(mesh, *fans, positions, k, loops->size(), options.cancel);
    if (!dual.ok()) return dual.status();
    MLCLUST_RETURN_IF_ERROR(check_cancel());
    Flipper flipper(*dual);
    const std::vector<uint64_t> doubled = RemoveDoubledEdges(flipper, *dual);
    std::vector<uint32_t> fill;  // boundary loops to try closing over, smallest first
    std::string problem;         // the error if none of them can be
    if (!doubled.empty()) {
      // A doubled edge at a loop's virtual vertex: a cluster meets the loop along two arcs.
      for (uint64_t key : doubled) {
        const uint32_t u = static_cast<uint32_t>(key >> 32), v = static_cast<uint32_t>(key);
        if (v >= k) {
          fill.push_back(v - k);
          if (problem.empty()) {
            problem = absl::StrCat(RegionName(u, dense), " meets boundary loop ", v - k,
                                   " along more than one arc, and the loop cannot be closed "
                                   "over by one cluster along it");
          }
        }
      }
      if (fill.empty()) {
        // Two clusters around a small hole can meet on both sides of it; closing the hole
        // over can give the flips room.
        const uint32_t u = static_cast<uint32_t>(doubled.front() >> 32);
        const uint32_t v = static_cast<uint32_t>(doubled.front());
        for (uint32_t end : {u, v}) {
          for (uint32_t loop : VirtualNeighbours(flipper, *dual, end, k)) fill.push_back(loop - k);
        }
        problem = absl::StrCat(
            RegionName(u, dense), " and ", RegionName(v, dense),
            " meet along more than one border arc, and no edge flip separates their coarse "
            "edges: too few clusters around a thin part or handle of the mesh (",
            doubled.size(), " such pairs); more clusters there would give a valid coarse mesh");
      }
    } else if (loops->size() > 1) {
      const LoopConflict conflict = SeparateBoundaryLoops(flipper, *dual, k);
      if (conflict.cluster != kNone) {
        fill = {conflict.first - k, conflict.second - k};
        problem = absl::StrCat(RegionName(conflict.cluster, dense), " touches boundary loops ",
                               fill[0], " and ", fill[1],
                               ", and neither can be closed over by one cluster along it: its "
                               "coarse vertex would lie on two coarse boundary loops");
      }
    }
    if (doubled.empty() && fill.empty()) {
      result.edge_flips += flipper.flips();
      absl::flat_hash_set<uint32_t> open_loops;
      for (const auto& t : dual->triangles) {
        if (t[0] < k && t[1] < k && t[2] < k) {
          triangles.push_back(t);
        } else {
          for (uint32_t v : t) {
            if (v >= k) open_loops.insert(v);
          }
        }
      }
      result.closed_boundary_loops = loops->size() - static_cast<uint32_t>(open_loops.size());
      break;
    }
    std::sort(fill.begin(), fill.end(), [&](uint32_t a, uint32_t b) {
      return loop_length(a) != loop_length(b) ? loop_length(a) < loop_length(b) : a < b;
    });
    fill.erase(std::unique(fill.begin(), fill.end()), fill.end());
    bool filled = false;
    for (size_t i = 0; i < fill.size() && !filled && attempt < loops->size(); ++i) {
      filled = FillLoop(mesh, *loops, cluster_of_face, fill[i], k, *fans);
    }
    if (!filled) return absl::FailedPreconditionError(problem);
  }
  // Drop the boundary loops' virtual vertices with their triangles: what is left has a
  // boundary loop where each of them was.
  MLCLUST_RETURN_IF_ERROR(CheckCoarseManifold(triangles, dense, loops->size() == 0));

  result.mesh.positions.reserve(3 * positions.size());
  for (const Vec3& p : positions) {
    result.mesh.positions.insert(
        result.mesh.positions.end(),
        {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)});
  }
  result.mesh.indices.reserve(3 * triangles.size());
  for (const auto& t : triangles) {
    result.mesh.indices.insert(result.mesh.indices.end(), t.begin(), t.end());
  }
  result.vertex_cluster = dense.original;
  return result;
}

absl::StatusOr<TriangleMesh> CoarsenMesh(const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                                         std::span<const ClusterId> labels,
                                         const CoarseningOptions& options) {
  absl::StatusOr<CoarseMesh> coarse = CoarsenMeshWithReport(mesh, adjacency, labels, options);
  if (!coarse.ok()) return coarse.status();
  return std::move(coarse->mesh);
}

}  // namespace mlclust
