#include "core/mesh/polygons.h"

#include <algorithm>
#include <utility>

#include "absl/container/flat_hash_map.h"
#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"

namespace mlclust {
namespace {

constexpr uint32_t kGap = ConnectivityGuard::kGap;

int CornerOf(const TriangleMesh& mesh, uint32_t face, uint32_t vertex) {
  const uint32_t* f = &mesh.indices[3 * size_t{face}];
  return f[0] == vertex ? 0 : f[1] == vertex ? 1 : 2;
}

// A boundary edge of a polygon: corner `from` to corner `to` of triangle `face` (in the
// triangle's orientation), with the face across it (kGap at the mesh border).
struct BoundaryEdge {
  uint32_t from, to, face, across;
};

// The ring of faces around polygon `p` (see BuildPolygonConnectivityGuard), appended to
// `ring` as face ids and kGap; false if p's boundary is not one simple loop.
bool PolygonFaceRing(const TriangleMesh& mesh, const FaceAdjacency& adjacency,
                     const MeshPolygons& polygons, uint32_t p, std::vector<BoundaryEdge>& edges,
                     absl::flat_hash_map<uint32_t, uint32_t>& edge_from,
                     std::vector<uint32_t>& ring) {
  auto in_polygon = [&](uint32_t face) { return polygons.polygon_of_face[face] == p; };
  edges.clear();
  edge_from.clear();
  for (uint32_t t = polygons.first_face[p]; t < polygons.first_face[p + 1]; ++t) {
    for (int e = 0; e < 3; ++e) {
      const FaceId g = adjacency.neighbours[t][e];
      if (g.valid() && in_polygon(g.value())) continue;
      const uint32_t from = mesh.indices[3 * size_t{t} + e];
      const uint32_t to = mesh.indices[3 * size_t{t} + (e + 1) % 3];
      // Two boundary edges leaving one vertex: the polygon is pinched there.
      if (!edge_from.emplace(from, static_cast<uint32_t>(edges.size())).second) return false;
      edges.push_back({from, to, t, g.valid() ? g.value() : kGap});
    }
  }
  if (edges.empty()) return false;  // the polygon is the whole closed component
  // Steps from `current` (entered from `previous`) to the next face around `vertex`: across
  // the other edge of `current` that contains it (as ConnectivityGuard's corner walk).
  auto step = [&](uint32_t vertex, uint32_t previous, uint32_t current) -> uint32_t {
    const int c = CornerOf(mesh, current, vertex);
    const FaceId a = adjacency.neighbours[current][c];
    const FaceId b = adjacency.neighbours[current][(c + 2) % 3];
    const FaceId next = (a.valid() && a.value() == previous) ? b : a;
    return next.valid() ? next.value() : kGap;
  };
  // Around `vertex` outside the polygon, from `first` (entered from `first_inside`) until
  // the walk comes back into the polygon or reaches the mesh border.
  auto walk = [&](uint32_t vertex, uint32_t inside, uint32_t start, std::vector<uint32_t>& out) {
    uint32_t previous = inside, current = start;
    size_t steps = 0;
    while (current != kGap && !in_polygon(current) && steps++ < 4096) {
      out.push_back(current);
      const uint32_t next = step(vertex, previous, current);
      previous = current;
      current = next;
    }
    return current;
  };
  size_t h = 0;
  for (size_t visited = 0; visited < edges.size(); ++visited) {
    const auto next_it = edge_from.find(edges[h].to);
    if (next_it == edge_from.end()) return false;
    const BoundaryEdge& in = edges[h];
    const BoundaryEdge& out = edges[next_it->second];
    // Around in.to, from the face across `in` to the face across `out`.
    const uint32_t end = walk(in.to, in.face, in.across, ring);
    if (end == kGap) {
      ring.push_back(kGap);
      const size_t backward = ring.size();
      walk(in.to, out.face, out.across, ring);
      std::reverse(ring.begin() + static_cast<ptrdiff_t>(backward), ring.end());
    }
    h = next_it->second;
    if (h == 0 && visited + 1 != edges.size()) return false;  // more than one loop
  }
  return h == 0;
}

}  // namespace

absl::StatusOr<MeshPolygons> MakeMeshPolygons(std::span<const uint32_t> triangle_counts,
                                              const FaceAdjacency& adjacency) {
  const size_t faces = adjacency.num_faces();
  if (triangle_counts.empty()) {
    return absl::InvalidArgumentError("polygons: the list of triangle counts is empty");
  }
  MeshPolygons polygons;
  polygons.first_face.reserve(triangle_counts.size() + 1);
  polygons.first_face.push_back(0);
  uint64_t total = 0;
  for (size_t p = 0; p < triangle_counts.size(); ++p) {
    if (triangle_counts[p] == 0) {
      return absl::InvalidArgumentError(
          absl::StrCat("polygons: polygon ", p, " has 0 triangles (every polygon has at least 1)"));
    }
    total += triangle_counts[p];
    if (total > faces) {
      return absl::InvalidArgumentError(absl::StrCat("polygons: the triangle counts up to polygon ",
                                                     p, " add up to ", total,
                                                     ", more than the mesh's ", faces, " faces"));
    }
    polygons.first_face.push_back(static_cast<uint32_t>(total));
  }
  if (total != faces) {
    return absl::InvalidArgumentError(absl::StrCat("polygons: the ", triangle_counts.size(),
                                                   " triangle counts add up to ", total,
                                                   ", not the mesh's ", faces, " faces"));
  }
  polygons.polygon_of_face.resize(faces);
  const uint32_t count = static_cast<uint32_t>(triangle_counts.size());
  for (uint32_t p = 0; p < count; ++p) {
    for (uint32_t f = polygons.first_face[p]; f < polygons.first_face[p + 1]; ++f) {
      polygons.polygon_of_face[f] = p;
    }
  }
  // Each polygon edge-connected (a flood inside it from its first triangle), and its
  // neighbours across the triangles' edges.
  NeighbourRows& rows = polygons.adjacency.neighbours;
  rows.offset.reserve(count + 1);
  std::vector<uint32_t> queue;
  std::vector<uint32_t> around;
  std::vector<uint8_t> reached(faces, 0);
  for (uint32_t p = 0; p < count; ++p) {
    const uint32_t first = polygons.first_face[p];
    queue.assign(1, first);
    reached[first] = 1;
    around.clear();
    for (size_t i = 0; i < queue.size(); ++i) {
      for (FaceId g : adjacency.neighbours[queue[i]]) {
        if (!g.valid()) continue;
        const uint32_t q = polygons.polygon_of_face[g.value()];
        if (q != p) {
          // First appearance order (for polygons of one triangle, the faces' edge order).
          if (std::find(around.begin(), around.end(), q) == around.end()) around.push_back(q);
        } else if (!reached[g.value()]) {
          reached[g.value()] = 1;
          queue.push_back(g.value());
        }
      }
    }
    if (queue.size() != polygons.triangles(p)) {
      return absl::InvalidArgumentError(absl::StrCat(
          "polygons: polygon ", p, " (faces ", first, "..", polygons.first_face[p + 1] - 1,
          ") is not edge-connected: its triangles are not one polygon of the mesh"));
    }
    for (uint32_t q : around) rows.ids.push_back(FaceId(q));
    rows.offset.push_back(static_cast<uint32_t>(rows.ids.size()));
  }
  return polygons;
}

absl::StatusOr<ConnectivityGuard> BuildPolygonConnectivityGuard(const TriangleMesh& mesh,
                                                                const FaceAdjacency& adjacency,
                                                                const MeshPolygons& polygons,
                                                                const std::atomic<bool>* cancel) {
  const size_t count = polygons.num_polygons();
  std::vector<uint64_t> offset(count + 1, 0);
  std::vector<uint32_t> rings;
  rings.reserve(8 * count);
  std::vector<BoundaryEdge> edges;
  absl::flat_hash_map<uint32_t, uint32_t> edge_from;
  std::vector<uint32_t> faces, ring;
  for (uint32_t p = 0; p < count; ++p) {
    if (p % 16384 == 0 && IsCancelled(cancel)) {
      return absl::CancelledError("cancelled while building the polygons' connectivity guard");
    }
    faces.clear();
    ring.clear();
    if (PolygonFaceRing(mesh, adjacency, polygons, p, edges, edge_from, faces)) {
      // Faces to polygons; equal neighbours collapse, cyclically (a run of one polygon's
      // faces is one entry, as a gap split into two walks is one gap).
      for (uint32_t f : faces) {
        const uint32_t element = f == kGap ? kGap : polygons.polygon_of_face[f];
        if (ring.empty() || ring.back() != element) ring.push_back(element);
      }
      while (ring.size() > 1 && ring.front() == ring.back()) ring.pop_back();
    }
    rings.insert(rings.end(), ring.begin(), ring.end());
    offset[p + 1] = rings.size();
  }
  return ConnectivityGuard::FromRings(std::move(offset), std::move(rings));
}

std::vector<ClusterId> FaceLabelsOfPolygons(const MeshPolygons& polygons,
                                            std::span<const uint32_t> polygon_labels) {
  std::vector<ClusterId> labels(polygons.num_faces());
  for (size_t f = 0; f < labels.size(); ++f) {
    labels[f] = ClusterId(polygon_labels[polygons.polygon_of_face[f]]);
  }
  return labels;
}

absl::StatusOr<std::vector<ClusterId>> PolygonLabelsOfFaces(
    const MeshPolygons& polygons, std::span<const ClusterId> face_labels) {
  if (face_labels.size() != polygons.num_faces()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "labels: ", face_labels.size(), " for a mesh of ", polygons.num_faces(), " faces"));
  }
  std::vector<ClusterId> labels(polygons.num_polygons());
  for (uint32_t p = 0; p < labels.size(); ++p) {
    labels[p] = face_labels[polygons.first_face[p]];
    for (uint32_t f = polygons.first_face[p] + 1; f < polygons.first_face[p + 1]; ++f) {
      if (face_labels[f] != labels[p]) {
        return absl::InvalidArgumentError(
            absl::StrCat("labels: polygon ", p, "'s triangles are in two clusters (face ",
                         polygons.first_face[p], " in ", labels[p].value(), ", face ", f, " in ",
                         face_labels[f].value(), ")"));
      }
    }
  }
  return labels;
}

}  // namespace mlclust
