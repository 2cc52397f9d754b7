#include "core/meshlets/meshlets.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <span>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/status_macros.h"

namespace mlclust {
namespace {

constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
constexpr uint8_t kNotInMeshlet = 0xff;
// Faces between two looks at the cancel flag.
constexpr uint32_t kCancelStride = 4096;

// The faces across each face's edges, in compressed rows; an edge shared by k faces gives
// each of them the other k - 1 (a non-manifold edge connects all its faces). Edges of a
// degenerate face whose two ends are one vertex connect nothing.
struct EdgeNeighbours {
  std::vector<uint32_t> offset;  // faces + 1
  std::vector<uint32_t> faces;

  std::span<const uint32_t> of(uint32_t face) const {
    return {faces.data() + offset[face], faces.data() + offset[face + 1]};
  }
};

// Half-edge matching through the corners around each vertex: for every face at vertex v,
// the face and its two other corners (the next and the previous one), so that the faces on
// an edge (v, w) are found in v's rows without reading the index buffer at random.
absl::StatusOr<EdgeNeighbours> BuildEdgeNeighbours(const TriangleMesh& mesh,
                                                   const std::atomic<bool>* cancel) {
  const auto faces = static_cast<uint32_t>(mesh.num_faces());
  const size_t vertices = mesh.num_vertices();
  const uint32_t* indices = mesh.indices.data();
  struct Corner {
    uint32_t face, next, previous;
  };
  std::vector<uint32_t> start(vertices + 1, 0);
  for (size_t i = 0; i < 3 * size_t{faces}; ++i) ++start[indices[i] + 1];
  for (size_t v = 0; v < vertices; ++v) start[v + 1] += start[v];
  std::vector<Corner> corners(3 * size_t{faces});
  {
    std::vector<uint32_t> fill(start.begin(), start.end() - 1);
    for (uint32_t f = 0; f < faces; ++f) {
      const uint32_t* c = indices + 3 * size_t{f};
      corners[fill[c[0]]++] = {f, c[1], c[2]};
      corners[fill[c[1]]++] = {f, c[2], c[0]};
      corners[fill[c[2]]++] = {f, c[0], c[1]};
    }
  }
  EdgeNeighbours result;
  result.offset.resize(size_t{faces} + 1);
  result.faces.reserve(3 * size_t{faces});
  for (uint32_t f = 0; f < faces; ++f) {
    if (f % kCancelStride == 0) {
      if (IsCancelled(cancel)) return absl::CancelledError("cancelled during meshlet adjacency");
    }
    const auto first = static_cast<uint32_t>(result.faces.size());
    result.offset[f] = first;
    const uint32_t* c = indices + 3 * size_t{f};
    for (int edge = 0; edge < 3; ++edge) {
      const uint32_t a = c[edge];
      const uint32_t b = c[(edge + 1) % 3];
      if (a == b) continue;
      // Walk the end with fewer faces: a fan of 1,000 faces around one vertex costs each
      // spoke its other end's handful, not the hub's thousand.
      const bool walk_a = start[a + 1] - start[a] <= start[b + 1] - start[b];
      const uint32_t walk = walk_a ? a : b;
      const uint32_t other = walk_a ? b : a;
      for (uint32_t i = start[walk]; i < start[walk + 1]; ++i) {
        const Corner& corner = corners[i];
        if (corner.face == f || (corner.next != other && corner.previous != other)) continue;
        bool known = false;
        for (size_t j = first; j < result.faces.size(); ++j)
          known |= result.faces[j] == corner.face;
        if (!known) result.faces.push_back(corner.face);
      }
    }
  }
  result.offset[faces] = static_cast<uint32_t>(result.faces.size());
  return result;
}

struct FaceFrame {
  std::array<float, 3> centroid;
  std::array<float, 3> normal;  // unit, or zero for a zero-area face
};

// The greedy pass's state (see the top of meshlets.h). Faces of meshlet m are a linked
// list head[m] -> next[f] -> ... so that the merge pass can join two in O(1).
class MeshletBuilder {
 public:
  MeshletBuilder(const TriangleMesh& mesh, const MeshletOptions& options,
                 const VertexFaceTable& around, const EdgeNeighbours& neighbours)
      : mesh_(mesh),
        options_(options),
        around_(around),
        neighbours_(neighbours),
        faces_(static_cast<uint32_t>(mesh.num_faces())),
        meshlet_of_(faces_, kNone),
        next_(faces_, kNone),
        live_faces_(faces_),
        live_vertex_(mesh.num_vertices()),
        local_(mesh.num_vertices(), kNotInMeshlet),
        candidate_stamp_(faces_, kNone),
        closing_(mesh.num_vertices()),
        frames_(faces_) {
    for (uint32_t f = 0; f < faces_; ++f) {
      live_faces_[f] = static_cast<uint32_t>(neighbours.of(f).size());
    }
    for (size_t v = 0; v < mesh.num_vertices(); ++v) {
      live_vertex_[v] = static_cast<uint32_t>(around.faces_around(static_cast<uint32_t>(v)).size());
    }
    double area = 0;
    for (uint32_t f = 0; f < faces_; ++f) {
      const Vec3 p0 = mesh.position(mesh.corner(FaceId(f), 0));
      const Vec3 p1 = mesh.position(mesh.corner(FaceId(f), 1));
      const Vec3 p2 = mesh.position(mesh.corner(FaceId(f), 2));
      const Vec3 n = Cross(p1 - p0, p2 - p0);
      const double length = Norm(n);
      const double scale = length > 0 ? 1.0 / length : 0.0;
      const Vec3 c = (p0 + p1 + p2) / 3.0;
      frames_[f].centroid = {static_cast<float>(c.x), static_cast<float>(c.y),
                             static_cast<float>(c.z)};
      frames_[f].normal = {static_cast<float>(n.x * scale), static_cast<float>(n.y * scale),
                           static_cast<float>(n.z * scale)};
      area += 0.5 * length;
    }
    // A meshlet as a disc of max_triangles average triangles: distances are scored in
    // units of its radius, so the cone weight trades the two on a scale-free footing.
    const double disc = area / std::max<uint32_t>(faces_, 1) * options.max_triangles;
    expected_radius_ = static_cast<float>(std::sqrt(disc / 3.14159265358979));
    if (!(expected_radius_ > 0)) expected_radius_ = 1;
  }

  absl::Status Grow() {
    uint32_t scan = 0;
    uint32_t seed = kNone;
    uint32_t assigned = 0;
    while (assigned < faces_) {
      if (seed == kNone || meshlet_of_[seed] != kNone) {
        seed = kNone;
        while (!pending_.empty() && seed == kNone) {
          if (meshlet_of_[pending_.back()] == kNone) seed = pending_.back();
          pending_.pop_back();
        }
        while (seed == kNone) {
          if (meshlet_of_[scan] == kNone) seed = scan;
          ++scan;
        }
      }
      const uint32_t before = assigned;
      seed = GrowOne(seed, assigned);
      if (before / kCancelStride != assigned / kCancelStride) {
        MLCLUST_RETURN_IF_ERROR(CheckCancelled(options_.cancel, "meshlet growth"));
      }
    }
    return absl::OkStatus();
  }

 private:
  // Grows meshlet `head_.size()` from `seed`; returns the next seed (kNone: none left over).
  uint32_t GrowOne(uint32_t seed, uint32_t& assigned) {
    const auto meshlet = static_cast<uint32_t>(head_.size());
    head_.push_back(kNone);
    tail_.push_back(kNone);
    triangles_.push_back(0);
    vertices_.clear();
    candidates_.clear();
    std::array<double, 6> sum = {0, 0, 0, 0, 0, 0};
    Add(meshlet, seed, sum);
    ++assigned;
    const uint32_t max_vertices = options_.max_vertices;
    const float cone_weight = options_.cone_weight;
    while (triangles_[meshlet] < options_.max_triangles) {
      // Faces that add no vertex are taken at once, without scoring: whatever the order,
      // the greedy would take them before any face that adds one.
      if (!free_.empty()) {
        const uint32_t face = free_.back();
        free_.pop_back();
        if (meshlet_of_[face] == kNone) {
          Add(meshlet, face, sum);
          ++assigned;
        }
        continue;
      }
      const auto count = static_cast<double>(triangles_[meshlet]);
      const float center[3] = {static_cast<float>(sum[0] / count),
                               static_cast<float>(sum[1] / count),
                               static_cast<float>(sum[2] / count)};
      const double axis_length = std::sqrt(sum[3] * sum[3] + sum[4] * sum[4] + sum[5] * sum[5]);
      const double axis_scale = axis_length > 0 ? 1.0 / axis_length : 0.0;
      const float axis[3] = {static_cast<float>(sum[3] * axis_scale),
                             static_cast<float>(sum[4] * axis_scale),
                             static_cast<float>(sum[5] * axis_scale)};
      size_t best = kNone;
      int best_class = 3;
      float best_score = std::numeric_limits<float>::infinity();
      // Pass 1: count, per outside vertex, the candidates it would admit (a vertex that
      // closes several faces at once keeps the border short). Counts are stamped with the
      // step so that nothing has to be cleared.
      ++step_;
      size_t kept = 0;
      for (size_t i = 0; i < candidates_.size(); ++i) {
        const Candidate& candidate = candidates_[i];
        if (meshlet_of_[candidate.face] != kNone) continue;  // taken from free_
        candidates_[kept++] = candidate;
        for (const uint32_t v : candidate.corners) {
          if (local_[v] != kNotInMeshlet) continue;
          Closing& closing = closing_[v];
          if (closing.step != step_) closing = {step_, 0};
          ++closing.count;
        }
      }
      candidates_.resize(kept);
      for (size_t i = 0; i < candidates_.size(); ++i) {
        const Candidate& candidate = candidates_[i];
        uint32_t added = 0;
        uint32_t closes = 0;
        bool stranded = live_faces_[candidate.face] == 0;
        for (const uint32_t v : candidate.corners) {
          if (local_[v] == kNotInMeshlet) {
            ++added;
            closes = std::max(closes, closing_[v].count);
          }
          stranded |= live_vertex_[v] == 1;
        }
        if (vertices_.size() + added > max_vertices) continue;
        const int face_class = added == 0 ? 0 : (stranded ? 1 : 2);
        if (face_class > best_class) continue;
        const float dx = candidate.centroid[0] - center[0];
        const float dy = candidate.centroid[1] - center[1];
        const float dz = candidate.centroid[2] - center[2];
        const float distance = std::sqrt(dx * dx + dy * dy + dz * dz) / expected_radius_;
        const float spread = candidate.normal[0] * axis[0] + candidate.normal[1] * axis[1] +
                             candidate.normal[2] * axis[2];
        const float cone = std::max(1.0f - spread * cone_weight, 1e-3f);
        float score = (1.0f + distance * (1.0f - cone_weight)) * cone;
        // Each further face the new vertex admits counts as one unit of distance.
        if (added == 1) score -= static_cast<float>(closes - 1);
        if (face_class < best_class || score < best_score) {
          best = i;
          best_class = face_class;
          best_score = score;
        }
      }
      if (best == kNone) break;
      const uint32_t face = candidates_[best].face;
      candidates_[best] = candidates_.back();
      candidates_.pop_back();
      Add(meshlet, face, sum);
      ++assigned;
    }
    for (uint32_t v : vertices_) local_[v] = kNotInMeshlet;
    for (const uint32_t face : free_) {
      if (meshlet_of_[face] == kNone) pending_.push_back(face);
    }
    free_.clear();
    // The next seed: the most enclosed face left over (fewest unassigned edge neighbours,
    // then fewest unassigned faces around its corners).
    uint32_t next = kNone;
    uint64_t next_key = std::numeric_limits<uint64_t>::max();
    for (const Candidate& candidate : candidates_) {
      const uint32_t c = candidate.face;
      if (meshlet_of_[c] != kNone) continue;
      const uint32_t* corners = &mesh_.indices[3 * size_t{c}];
      const uint64_t around =
          uint64_t{live_vertex_[corners[0]]} + live_vertex_[corners[1]] + live_vertex_[corners[2]];
      const uint64_t key = (uint64_t{live_faces_[c]} << 40) | around;
      if (key < next_key) {
        if (next != kNone) pending_.push_back(next);
        next = c;
        next_key = key;
      } else {
        pending_.push_back(c);
      }
    }
    return next;
  }

  bool AllInside(uint32_t face) const {
    const uint32_t* c = &mesh_.indices[3 * size_t{face}];
    return local_[c[0]] != kNotInMeshlet && local_[c[1]] != kNotInMeshlet &&
           local_[c[2]] != kNotInMeshlet;
  }

  void Add(uint32_t meshlet, uint32_t face, std::array<double, 6>& sum) {
    meshlet_of_[face] = meshlet;
    if (tail_[meshlet] == kNone) {
      head_[meshlet] = face;
    } else {
      next_[tail_[meshlet]] = face;
    }
    tail_[meshlet] = face;
    ++triangles_[meshlet];
    const uint32_t* corners = &mesh_.indices[3 * size_t{face}];
    for (int corner = 0; corner < 3; ++corner) {
      const uint32_t v = corners[corner];
      if (local_[v] == kNotInMeshlet) {
        local_[v] = static_cast<uint8_t>(vertices_.size());
        vertices_.push_back(v);
        // Candidates around the new vertex may now add none.
        for (const uint32_t g : around_.faces_around(v)) {
          if (candidate_stamp_[g] == meshlet && meshlet_of_[g] == kNone && AllInside(g)) {
            free_.push_back(g);
          }
        }
      }
      --live_vertex_[v];
    }
    for (uint32_t g : neighbours_.of(face)) {
      --live_faces_[g];
      if (meshlet_of_[g] == kNone && candidate_stamp_[g] != meshlet) {
        candidate_stamp_[g] = meshlet;
        if (AllInside(g)) {
          free_.push_back(g);
          continue;
        }
        const uint32_t* c = &mesh_.indices[3 * size_t{g}];
        const FaceFrame& frame = frames_[g];
        candidates_.push_back({g, {c[0], c[1], c[2]}, frame.centroid, frame.normal});
      }
    }
    const FaceFrame& frame = frames_[face];
    for (int axis = 0; axis < 3; ++axis) {
      sum[axis] += frame.centroid[axis];
      sum[3 + axis] += frame.normal[axis];
    }
  }

 public:
  // The merge pass: a meshlet below `merge_below` triangles joins the edge-neighbouring
  // meshlet whose union with it adds the fewest vertices and still fits both caps.
  // Smallest meshlets first; a meshlet that grew by a merge may take part again.
  void MergeSmall(uint32_t merge_below) {
    const auto count = static_cast<uint32_t>(head_.size());
    std::vector<uint32_t> order;
    for (uint32_t m = 0; m < count; ++m) {
      if (triangles_[m] < merge_below) order.push_back(m);
    }
    std::stable_sort(order.begin(), order.end(),
                     [&](uint32_t a, uint32_t b) { return triangles_[a] < triangles_[b]; });
    alive_.assign(count, 1);
    std::vector<uint32_t> stamp(mesh_.num_vertices(), kNone);
    std::vector<uint32_t> targets;
    for (uint32_t small : order) {
      if (!alive_[small] || triangles_[small] >= merge_below) continue;
      // Its vertices, stamped.
      uint32_t small_vertices = 0;
      for (uint32_t f = head_[small]; f != kNone; f = next_[f]) {
        for (int corner = 0; corner < 3; ++corner) {
          const uint32_t v = mesh_.indices[3 * size_t{f} + corner];
          if (stamp[v] != small) {
            stamp[v] = small;
            ++small_vertices;
          }
        }
      }
      targets.clear();
      for (uint32_t f = head_[small]; f != kNone; f = next_[f]) {
        for (uint32_t g : neighbours_.of(f)) {
          const uint32_t t = meshlet_of_[g];
          if (t != small && std::find(targets.begin(), targets.end(), t) == targets.end()) {
            targets.push_back(t);
          }
        }
      }
      uint32_t best = kNone;
      uint32_t best_added = kNone;
      for (uint32_t t : targets) {
        if (triangles_[t] + triangles_[small] > options_.max_triangles) continue;
        // Vertices of t not in small; stamp with a second mark so each counts once.
        uint32_t union_vertices = small_vertices;
        const uint32_t mark = count + t;
        for (uint32_t f = head_[t]; f != kNone; f = next_[f]) {
          for (int corner = 0; corner < 3; ++corner) {
            const uint32_t v = mesh_.indices[3 * size_t{f} + corner];
            if (stamp[v] != small && stamp[v] != mark) {
              stamp[v] = mark;
              ++union_vertices;
            }
          }
        }
        // Restore small's stamps overwritten? None were: only unstamped ones took `mark`.
        if (union_vertices > options_.max_vertices) continue;
        const uint32_t added = union_vertices - small_vertices;
        if (added < best_added) {
          best = t;
          best_added = added;
        }
      }
      // Clear the marks of the targets so later passes see a clean slate.
      for (uint32_t t : targets) {
        for (uint32_t f = head_[t]; f != kNone; f = next_[f]) {
          for (int corner = 0; corner < 3; ++corner) {
            uint32_t& s = stamp[mesh_.indices[3 * size_t{f} + corner]];
            if (s == count + t) s = kNone;
          }
        }
      }
      if (best == kNone) continue;
      for (uint32_t f = head_[small]; f != kNone; f = next_[f]) meshlet_of_[f] = best;
      next_[tail_[best]] = head_[small];
      tail_[best] = tail_[small];
      triangles_[best] += triangles_[small];
      triangles_[small] = 0;
      head_[small] = tail_[small] = kNone;
      alive_[small] = 0;
    }
  }

  // Writes the layout: surviving meshlets in order of their ids, faces in list order.
  void Emit(MeshletResult& result) {
    const auto count = static_cast<uint32_t>(head_.size());
    std::vector<uint32_t> renumber(count, kNone);
    uint32_t kept = 0;
    size_t triangle_bytes = 0;
    for (uint32_t m = 0; m < count; ++m) {
      if (triangles_[m] == 0) continue;
      renumber[m] = kept++;
      triangle_bytes += (3 * size_t{triangles_[m]} + 3) & ~size_t{3};
    }
    result.meshlets.resize(kept);
    result.meshlet_triangles.assign(triangle_bytes, 0);
    result.meshlet_vertices.clear();
    result.meshlet_vertices.reserve(faces_);
    result.triangle_faces.clear();
    result.triangle_faces.reserve(faces_);
    result.face_meshlet.resize(faces_);
    uint32_t byte = 0;
    for (uint32_t m = 0; m < count; ++m) {
      if (renumber[m] == kNone) continue;
      Meshlet& out = result.meshlets[renumber[m]];
      out.vertex_offset = static_cast<uint32_t>(result.meshlet_vertices.size());
      out.triangle_offset = byte;
      for (uint32_t f = head_[m]; f != kNone; f = next_[f]) {
        result.face_meshlet[f] = renumber[m];
        result.triangle_faces.push_back(f);
        for (int corner = 0; corner < 3; ++corner) {
          const uint32_t v = mesh_.indices[3 * size_t{f} + corner];
          if (local_[v] == kNotInMeshlet) {
            local_[v] = static_cast<uint8_t>(result.meshlet_vertices.size() - out.vertex_offset);
            result.meshlet_vertices.push_back(v);
          }
          result.meshlet_triangles[byte + 3 * out.triangle_count + corner] = local_[v];
        }
        ++out.triangle_count;
      }
      out.vertex_count = static_cast<uint32_t>(result.meshlet_vertices.size()) - out.vertex_offset;
      for (uint32_t i = out.vertex_offset; i < result.meshlet_vertices.size(); ++i) {
        local_[result.meshlet_vertices[i]] = kNotInMeshlet;
      }
      byte += (3 * out.triangle_count + 3) & ~3u;
    }
  }

 private:
  const TriangleMesh& mesh_;
  const MeshletOptions& options_;
  const VertexFaceTable& around_;
  const EdgeNeighbours& neighbours_;
  uint32_t faces_;
  float expected_radius_ = 1;
  std::vector<uint32_t> meshlet_of_;
  std::vector<uint32_t> next_;
  std::vector<uint32_t> head_, tail_, triangles_;
  std::vector<uint8_t> alive_;
  std::vector<uint32_t> live_faces_;   // unassigned edge neighbours of each face
  std::vector<uint32_t> live_vertex_;  // unassigned faces around each vertex
  std::vector<uint8_t> local_;         // a vertex's index in the meshlet being built
  std::vector<uint32_t> candidate_stamp_;
  struct Closing {
    uint32_t step = 0;
    uint32_t count = 0;
  };
  std::vector<Closing> closing_;  // scratch: candidates each outside vertex admits
  uint32_t step_ = 0;
  std::vector<FaceFrame> frames_;
  std::vector<uint32_t> vertices_;  // of the meshlet being built
  // A face across an edge of the meshlet being built, with what scoring reads.
  struct Candidate {
    uint32_t face;
    std::array<uint32_t, 3> corners;
    std::array<float, 3> centroid;
    std::array<float, 3> normal;
  };
  std::vector<Candidate> candidates_;  // of the meshlet being built; none assigned
  std::vector<uint32_t> pending_;      // left over by finished meshlets
  std::vector<uint32_t> free_;         // candidates that add no vertex (may repeat)
};

// meshopt_computeMeshletBounds skips zero-area triangles and returns all zeros for a
// meshlet of nothing else (a cutoff of 0 with a zero axis would cull it from every
// side): a sphere around its vertices' box centre, and a cone that never culls.
void DegenerateBounds(const TriangleMesh& mesh, const MeshletResult& result, const Meshlet& meshlet,
                      MeshletBounds& out) {
  std::array<float, 3> low = {std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
                              std::numeric_limits<float>::max()};
  std::array<float, 3> high = {-low[0], -low[1], -low[2]};
  for (uint32_t i = 0; i < meshlet.vertex_count; ++i) {
    const float* p =
        &mesh.positions[3 * size_t{result.meshlet_vertices[meshlet.vertex_offset + i]}];
    for (int axis = 0; axis < 3; ++axis) {
      low[axis] = std::min(low[axis], p[axis]);
      high[axis] = std::max(high[axis], p[axis]);
    }
  }
  double radius = 0;
  for (int axis = 0; axis < 3; ++axis) out.center[axis] = 0.5f * (low[axis] + high[axis]);
  for (uint32_t i = 0; i < meshlet.vertex_count; ++i) {
    const float* p =
        &mesh.positions[3 * size_t{result.meshlet_vertices[meshlet.vertex_offset + i]}];
    double d2 = 0;
    for (int axis = 0; axis < 3; ++axis) d2 += std::pow(p[axis] - out.center[axis], 2);
    radius = std::max(radius, std::sqrt(d2));
  }
  out.radius = static_cast<float>(radius);
  std::memcpy(out.cone_apex, out.center, sizeof(out.cone_apex));
  out.cone_axis[0] = out.cone_axis[1] = 0;
  out.cone_axis[2] = 1;
  out.cone_cutoff = 1;
  out.cone_axis_s8[0] = out.cone_axis_s8[1] = 0;
  out.cone_axis_s8[2] = 127;
  out.cone_cutoff_s8 = 127;
}

absl::Status CheckMeshletInput(const TriangleMesh& mesh) {
  if (mesh.positions.size() % 3 != 0) {
    return absl::InvalidArgumentError(absl::StrCat("meshlets: ", mesh.positions.size(),
                                                   " position floats, not whole xyz triples"));
  }
  if (mesh.indices.size() % 3 != 0) {
    return absl::InvalidArgumentError(
        absl::StrCat("meshlets: ", mesh.indices.size(), " indices, not whole triangles"));
  }
  if (mesh.indices.empty()) return absl::InvalidArgumentError("meshlets: the mesh has no face");
  if (mesh.num_faces() > kMaxMeshElements || mesh.num_vertices() > kMaxMeshElements) {
    return absl::InvalidArgumentError(absl::StrCat("meshlets: ", mesh.num_faces(), " faces and ",
                                                   mesh.num_vertices(), " vertices; at most ",
                                                   kMaxMeshElements));
  }
  MLCLUST_RETURN_IF_ERROR(CheckVertexIndices(mesh));
  for (size_t i = 0; i < mesh.positions.size(); ++i) {
    if (!std::isfinite(mesh.positions[i])) {
      return absl::InvalidArgumentError(
          absl::StrCat("meshlets: vertex ", i / 3, " has a non-finite coordinate"));
    }
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status ValidateMeshletOptions(const MeshletOptions& options) {
  if (options.max_vertices < 3 || options.max_vertices > kMaxMeshletVertices) {
    return absl::InvalidArgumentError(absl::StrCat("max_vertices is ", options.max_vertices,
                                                   "; it must be in [3, ", kMaxMeshletVertices,
                                                   "]"));
  }
  if (options.max_triangles < 1 || options.max_triangles > kMaxMeshletTriangles) {
    return absl::InvalidArgumentError(absl::StrCat("max_triangles is ", options.max_triangles,
                                                   "; it must be in [1, ", kMaxMeshletTriangles,
                                                   "]"));
  }
  if (!(options.cone_weight >= 0.0f && options.cone_weight <= 1.0f)) {
    return absl::InvalidArgumentError(
        absl::StrCat("cone_weight is ", options.cone_weight, "; it must be in [0, 1]"));
  }
  if (options.merge_below > options.max_triangles) {
    return absl::InvalidArgumentError(absl::StrCat("merge_below is ", options.merge_below,
                                                   "; it must be at most max_triangles (",
                                                   options.max_triangles, ")"));
  }
  return absl::OkStatus();
}

absl::StatusOr<MeshletResult> BuildMeshlets(const TriangleMesh& mesh,
                                            const MeshletOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidateMeshletOptions(options));
  MLCLUST_RETURN_IF_ERROR(CheckMeshletInput(mesh));
  const VertexFaceTable around = BuildVertexFaceTable(mesh);
  absl::StatusOr<EdgeNeighbours> neighbours = BuildEdgeNeighbours(mesh, options.cancel);
  if (!neighbours.ok()) return neighbours.status();
  MeshletBuilder builder(mesh, options, around, *neighbours);
  MLCLUST_RETURN_IF_ERROR(builder.Grow());
  const uint32_t merge_below =
      options.merge_below == 0 ? options.max_triangles / 2 : options.merge_below;
  builder.MergeSmall(merge_below);
  MeshletResult result;
  builder.Emit(result);
  if (options.compute_bounds) {
    MLCLUST_RETURN_IF_ERROR(CheckCancelled(options.cancel, "meshlet bounds"));
    result.bounds.resize(result.meshlets.size());
    for (size_t m = 0; m < result.meshlets.size(); ++m) {
      const Meshlet& meshlet = result.meshlets[m];
      const meshopt_Bounds b = meshopt_computeMeshletBounds(
          &result.meshlet_vertices[meshlet.vertex_offset],
          &result.meshlet_triangles[meshlet.triangle_offset], meshlet.triangle_count,
          mesh.positions.data(), mesh.num_vertices(), 3 * sizeof(float));
      MeshletBounds& out = result.bounds[m];
      std::memcpy(out.center, b.center, sizeof(out.center));
      out.radius = b.radius;
      std::memcpy(out.cone_apex, b.cone_apex, sizeof(out.cone_apex));
      std::memcpy(out.cone_axis, b.cone_axis, sizeof(out.cone_axis));
      out.cone_cutoff = b.cone_cutoff;
      for (int axis = 0; axis < 3; ++axis) out.cone_axis_s8[axis] = b.cone_axis_s8[axis];
      out.cone_cutoff_s8 = b.cone_cutoff_s8;
      if (b.radius == 0) DegenerateBounds(mesh, result, meshlet, out);
    }
  }
  return result;
}

absl::Status CheckMeshletLayout(const MeshletResult& meshlets, uint32_t max_vertices,
                                uint32_t max_triangles, const TriangleMesh* mesh) {
  const size_t faces = mesh != nullptr ? mesh->num_faces() : meshlets.face_meshlet.size();
  if (meshlets.face_meshlet.size() != faces || meshlets.triangle_faces.size() != faces) {
    return absl::InvalidArgumentError(
        absl::StrCat("meshlets: ", meshlets.face_meshlet.size(), " face labels and ",
                     meshlets.triangle_faces.size(), " triangle faces for ", faces, " faces"));
  }
  if (!meshlets.bounds.empty() && meshlets.bounds.size() != meshlets.meshlets.size()) {
    return absl::InvalidArgumentError(absl::StrCat("meshlets: ", meshlets.bounds.size(),
                                                   " bounds for ", meshlets.meshlets.size(),
                                                   " meshlets"));
  }
  std::vector<uint8_t> seen(faces, 0);
  size_t vertex_end = 0;
  size_t byte_end = 0;
  size_t triangle = 0;
  for (size_t m = 0; m < meshlets.meshlets.size(); ++m) {
    const Meshlet& meshlet = meshlets.meshlets[m];
    auto fail = [&](absl::string_view what) {
      return absl::InvalidArgumentError(absl::StrCat("meshlet ", m, ": ", what));
    };
    if (meshlet.vertex_offset != vertex_end) return fail("vertex run not contiguous");
    if (meshlet.triangle_offset != byte_end) return fail("triangle run not contiguous");
    if (meshlet.triangle_offset % 4 != 0) return fail("triangle run not 4-byte aligned");
    if (meshlet.vertex_count > max_vertices) return fail("more vertices than the cap");
    if (meshlet.triangle_count == 0) return fail("no triangle");
    if (meshlet.triangle_count > max_triangles) return fail("more triangles than the cap");
    vertex_end += meshlet.vertex_count;
    byte_end += (3 * size_t{meshlet.triangle_count} + 3) & ~size_t{3};
    if (vertex_end > meshlets.meshlet_vertices.size() ||
        byte_end > meshlets.meshlet_triangles.size() || triangle + meshlet.triangle_count > faces) {
      return fail("runs past the end of the arrays");
    }
    for (uint32_t t = 0; t < meshlet.triangle_count; ++t, ++triangle) {
      const uint32_t face = meshlets.triangle_faces[triangle];
      if (face >= faces) return fail(absl::StrCat("face ", face, " out of range"));
      if (seen[face]) return fail(absl::StrCat("face ", face, " twice"));
      seen[face] = 1;
      if (meshlets.face_meshlet[face] != m) {
        return fail(absl::StrCat("face ", face, " labelled ", meshlets.face_meshlet[face]));
      }
      for (int corner = 0; corner < 3; ++corner) {
        const uint8_t local = meshlets.meshlet_triangles[meshlet.triangle_offset + 3 * t + corner];
        if (local >= meshlet.vertex_count) {
          return fail(absl::StrCat("triangle ", t, " local index ", local, " >= vertex count ",
                                   meshlet.vertex_count));
        }
        if (mesh != nullptr && meshlets.meshlet_vertices[meshlet.vertex_offset + local] !=
                                   mesh->indices[3 * size_t{face} + corner]) {
          return fail(
              absl::StrCat("triangle ", t, " corner ", corner, " is not face ", face, "'s vertex"));
        }
      }
    }
  }
  if (vertex_end != meshlets.meshlet_vertices.size() ||
      byte_end != meshlets.meshlet_triangles.size() || triangle != faces) {
    return absl::InvalidArgumentError("meshlets: arrays longer than the meshlets use");
  }
  return absl::OkStatus();
}

}  // namespace mlclust
