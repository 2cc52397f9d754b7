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
#include "core/base/morton.h"
#include "core/base/status_macros.h"

namespace mlclust {
namespace {

constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
constexpr uint8_t kNotInMeshlet = 0xff;
// Faces between two looks at the cancel flag.
constexpr uint32_t kCancelStride = 4096;

// The mesh with its faces in Morton order of their centroids (10 bits per axis of the
// vertices' box) and its vertices in order of first use by those faces. Growth visits
// faces near each other in space; in this order they are near each other in memory too
// (scanned meshes often list faces in no spatial order: bunny00's faces span 15,000
// vertex ids at the median), so every per-face and per-vertex array is read in runs.
struct SpatialOrder {
  TriangleMesh mesh;
  std::vector<uint32_t> input_face;    // of each face of `mesh`
  std::vector<uint32_t> input_vertex;  // of each vertex of `mesh`
};

SpatialOrder OrderSpatially(const TriangleMesh& input) {
  const auto faces = static_cast<uint32_t>(input.num_faces());
  const size_t vertices = input.num_vertices();
  std::array<float, 3> low = {std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
                              std::numeric_limits<float>::max()};
  std::array<float, 3> high = {-low[0], -low[1], -low[2]};
  for (size_t v = 0; v < vertices; ++v) {
    for (int axis = 0; axis < 3; ++axis) {
      low[axis] = std::min(low[axis], input.positions[3 * v + axis]);
      high[axis] = std::max(high[axis], input.positions[3 * v + axis]);
    }
  }
  const float extent = std::max({high[0] - low[0], high[1] - low[1], high[2] - low[2]});
  // Three times the centroid: the corners' sum, scaled once.
  const float scale = extent > 0 ? 1023.0f / (3.0f * extent) : 0.0f;
  std::vector<uint32_t> codes(faces);
  for (uint32_t f = 0; f < faces; ++f) {
    uint32_t cell[3];
    for (int axis = 0; axis < 3; ++axis) {
      float sum = -3.0f * low[axis];
      for (int corner = 0; corner < 3; ++corner) {
        sum += input.positions[3 * size_t{input.indices[3 * size_t{f} + corner]} + axis];
      }
      cell[axis] = static_cast<uint32_t>(std::clamp(sum * scale, 0.0f, 1023.0f));
    }
    codes[f] = MortonCode(cell[0], cell[1], cell[2]);
  }
  // Stable counting passes over the 30-bit codes (ties keep the input order): two of 15
  // bits, or three of 10 for a small mesh, where clearing 32,768 buckets twice would cost
  // more than its faces.
  SpatialOrder order;
  order.input_face.resize(faces);
  std::vector<uint32_t> pass(faces);
  for (uint32_t f = 0; f < faces; ++f) pass[f] = f;
  const uint32_t bits = faces < (1u << 16) ? 10 : 15;
  const uint32_t mask = (1u << bits) - 1;
  std::vector<uint32_t> start((1u << bits) + 1);
  for (uint32_t shift = 0; shift < 30; shift += bits) {
    std::fill(start.begin(), start.end(), 0);
    for (uint32_t f : pass) ++start[((codes[f] >> shift) & mask) + 1];
    for (size_t b = 0; b + 1 < start.size(); ++b) start[b + 1] += start[b];
    for (uint32_t f : pass) order.input_face[start[(codes[f] >> shift) & mask]++] = f;
    pass.swap(order.input_face);
  }
  order.input_face.swap(pass);
  std::vector<uint32_t> renumber(vertices, kNone);
  order.mesh.indices.resize(3 * size_t{faces});
  order.input_vertex.reserve(vertices);
  for (uint32_t f = 0; f < faces; ++f) {
    const uint32_t* corners = &input.indices[3 * size_t{order.input_face[f]}];
    for (int corner = 0; corner < 3; ++corner) {
      uint32_t& id = renumber[corners[corner]];
      if (id == kNone) {
        id = static_cast<uint32_t>(order.input_vertex.size());
        order.input_vertex.push_back(corners[corner]);
      }
      order.mesh.indices[3 * size_t{f} + corner] = id;
    }
  }
  order.mesh.positions.resize(3 * order.input_vertex.size());
  for (size_t v = 0; v < order.input_vertex.size(); ++v) {
    for (int axis = 0; axis < 3; ++axis) {
      order.mesh.positions[3 * v + axis] =
          input.positions[3 * size_t{order.input_vertex[v]} + axis];
    }
  }
  return order;
}

// The corners around each vertex, in compressed rows (a counting sort by vertex): for each
// face at vertex v, the face, which of its corners v is, and its two other corners. The
// faces on an edge (v, w) are then found in v's row alone, without reading the index buffer
// at random; the row also gives the faces around v.
struct CornerTable {
  struct Corner {
    uint32_t face;
    uint32_t next;      // the face's corner after v (the edge v -> next is this corner's)
    uint32_t previous;  // the face's corner before v
    uint32_t corner;    // v is corner 0, 1 or 2 of the face
  };
  std::vector<uint32_t> start;  // vertices + 1
  std::vector<Corner> corners;

  std::span<const Corner> around(uint32_t vertex) const {
    return {corners.data() + start[vertex], corners.data() + start[vertex + 1]};
  }
  uint32_t faces_around(uint32_t vertex) const { return start[vertex + 1] - start[vertex]; }
};

CornerTable BuildCornerTable(const TriangleMesh& mesh) {
  const auto faces = static_cast<uint32_t>(mesh.num_faces());
  const size_t vertices = mesh.num_vertices();
  const uint32_t* indices = mesh.indices.data();
  CornerTable table;
  table.start.assign(vertices + 1, 0);
  for (size_t i = 0; i < 3 * size_t{faces}; ++i) ++table.start[indices[i] + 1];
  for (size_t v = 0; v < vertices; ++v) table.start[v + 1] += table.start[v];
  table.corners.resize(3 * size_t{faces});
  std::vector<uint32_t> fill(table.start.begin(), table.start.end() - 1);
  for (uint32_t f = 0; f < faces; ++f) {
    const uint32_t* c = indices + 3 * size_t{f};
    table.corners[fill[c[0]]++] = {f, c[1], c[2], 0};
    table.corners[fill[c[1]]++] = {f, c[2], c[0], 1};
    table.corners[fill[c[2]]++] = {f, c[0], c[1], 2};
  }
  return table;
}

// The faces across each face's edges, in compressed rows over half-edges: the faces across
// edge k of face f (corner k to corner k + 1) are faces[offset[3f + k] .. offset[3f + k + 1]),
// so a face's neighbours are one run from offset[3f] to offset[3f + 3]. An edge shared by n
// faces gives each of them the other n - 1 (a non-manifold edge connects all its faces; a
// face may appear twice when two faces share two edges). Edges of a degenerate face whose
// two ends are one vertex connect nothing.
struct EdgeNeighbours {
  std::vector<uint32_t> offset;  // 3 faces + 1
  std::vector<uint32_t> faces;

  std::span<const uint32_t> of(uint32_t face) const {
    return {faces.data() + offset[3 * size_t{face}], faces.data() + offset[3 * size_t{face} + 3]};
  }
};

// Every half-edge v -> w is matched in v's row of the corner table: the other faces at v
// that have w as their next or previous corner. One pass over the rows keeps each
// half-edge's first partner in a slot of its own and any further ones (non-manifold
// edges) aside; the rows are then laid out half-edge by half-edge, partners in row order.
absl::StatusOr<EdgeNeighbours> BuildEdgeNeighbours(const CornerTable& table, uint32_t faces,
                                                   const std::atomic<bool>* cancel) {
  using Corner = CornerTable::Corner;
  const auto vertices = static_cast<uint32_t>(table.start.size() - 1);
  const size_t half_edges = 3 * size_t{faces};
  std::vector<uint32_t> first(half_edges, kNone);
  std::vector<std::pair<uint32_t, uint32_t>> further;  // (half-edge, face)
  for (uint32_t v = 0; v < vertices; ++v) {
    if (v % kCancelStride == 0 && IsCancelled(cancel)) {
      return absl::CancelledError("cancelled during meshlet adjacency");
    }
    const std::span<const Corner> ring = table.around(v);
    for (const Corner& corner : ring) {
      if (corner.next == v) continue;  // degenerate edge
      const uint32_t half_edge = 3 * corner.face + corner.corner;
      for (const Corner& other : ring) {
        if (other.face != corner.face &&
            (other.previous == corner.next || other.next == corner.next)) {
          if (first[half_edge] == kNone) {
            first[half_edge] = other.face;
          } else {
            further.emplace_back(half_edge, other.face);
          }
        }
      }
    }
  }
  EdgeNeighbours result;
  result.offset.assign(half_edges + 1, 0);
  for (size_t h = 0; h < half_edges; ++h) {
    result.offset[h + 1] = first[h] != kNone ? 1 : 0;
  }
  for (const auto& [half_edge, face] : further) ++result.offset[half_edge + 1];
  for (size_t h = 0; h < half_edges; ++h) result.offset[h + 1] += result.offset[h];
  result.faces.resize(result.offset.back());
  for (size_t h = 0; h < half_edges; ++h) {
    if (first[h] != kNone) result.faces[result.offset[h]] = first[h];
  }
  if (!further.empty()) {
    // Further partners after the first, in the order the rows found them.
    std::vector<uint32_t> fill(half_edges);
    for (size_t h = 0; h < half_edges; ++h) fill[h] = result.offset[h] + 1;
    for (const auto& [half_edge, face] : further) result.faces[fill[half_edge]++] = face;
  }
  return result;
}

// What scoring reads of a face, copied into a candidate when it becomes one.
struct FaceFrame {
  std::array<uint32_t, 3> corners;
  std::array<float, 3> centroid;
  std::array<float, 3> normal;  // unit, or zero for a zero-area face
};

// The greedy pass's state (see the top of meshlets.h). Faces of meshlet m are a linked
// list head[m] -> next[f] -> ... (a meshlet grown again is taken back along it).
class MeshletBuilder {
 public:
  MeshletBuilder(const TriangleMesh& mesh, const MeshletOptions& options, const CornerTable& around,
                 const EdgeNeighbours& neighbours)
      : mesh_(mesh),
        options_(options),
        around_(around),
        neighbours_(neighbours),
        faces_(static_cast<uint32_t>(mesh.num_faces())),
        state_(faces_),
        next_(faces_, kNone),
        live_vertex_(mesh.num_vertices()),
        local_(mesh.num_vertices(), kNotInMeshlet),
        closing_(mesh.num_vertices()),
        frames_(faces_),
        flood_stamp_(faces_, kNone) {
    for (uint32_t f = 0; f < faces_; ++f) {
      state_[f].live = static_cast<uint32_t>(neighbours.of(f).size());
    }
    for (size_t v = 0; v < mesh.num_vertices(); ++v) {
      live_vertex_[v] = around.faces_around(static_cast<uint32_t>(v));
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
      frames_[f].corners = {mesh.indices[3 * size_t{f}], mesh.indices[3 * size_t{f} + 1],
                            mesh.indices[3 * size_t{f} + 2]};
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
    // Pockets up to half a meshlet; larger ones hold a meshlet of their own and more.
    pocket_limit_ = std::max<uint32_t>(1, options.max_triangles / 2);
  }

  absl::Status Grow() {
    uint32_t scan = 0;
    uint32_t seed = kNone;
    uint32_t assigned = 0;
    while (assigned < faces_) {
      if (seed == kNone || state_[seed].meshlet != kNone) {
        seed = kNone;
        while (!pending_.empty() && seed == kNone) {
          if (state_[pending_.back()].meshlet == kNone) seed = pending_.back();
          pending_.pop_back();
        }
        while (seed == kNone) {
          if (state_[scan].meshlet == kNone) seed = scan;
          ++scan;
        }
      }
      const uint32_t before = assigned;
      seed = GrowOne(seed, assigned);
      // Lookahead: a meshlet that leaves a small pocket of unassigned faces behind (between
      // itself, holes and earlier meshlets) would leave an island that no full neighbour can
      // take; grown again from inside the pocket, it takes the pocket first.
      for (uint32_t retry = 0; retry < kPocketRetries; ++retry) {
        const uint32_t pocket = FindPocket();
        if (pocket == kNone) break;
        Undo(assigned);
        seed = GrowOne(pocket, assigned);
      }
      if (before / kCancelStride != assigned / kCancelStride) {
        MLCLUST_RETURN_IF_ERROR(CheckCancelled(options_.cancel, "meshlet growth"));
      }
    }
    return absl::OkStatus();
  }

 private:
  // A face of an unassigned region of at most pocket_limit_ faces that touches the last
  // meshlet's left-over candidates, or kNone. Floods stop past the limit; a flood that
  // reaches a face an earlier flood found in a large region stops at once.
  uint32_t FindPocket() {
    for (const Candidate& candidate : candidates_) {
      const uint32_t start = candidate.face;
      if (state_[start].meshlet != kNone || flood_stamp_[start] == flood_large_) continue;
      ++flood_;
      flood_stamp_[start] = flood_;
      flood_faces_.assign(1, start);
      bool large = false;
      for (size_t i = 0; i < flood_faces_.size() && !large; ++i) {
        for (const uint32_t g : neighbours_.of(flood_faces_[i])) {
          if (state_[g].meshlet != kNone || flood_stamp_[g] == flood_) continue;
          if (flood_stamp_[g] == flood_large_ || flood_faces_.size() >= pocket_limit_) {
            large = true;
            break;
          }
          flood_stamp_[g] = flood_;
          flood_faces_.push_back(g);
        }
      }
      if (!large) return start;
      for (const uint32_t f : flood_faces_) flood_stamp_[f] = flood_large_;
    }
    return kNone;
  }

  // Takes the last meshlet's faces back (as if never grown); its id is reused.
  void Undo(uint32_t& assigned) {
    const auto meshlet = static_cast<uint32_t>(head_.size() - 1);
    for (uint32_t f = head_[meshlet]; f != kNone;) {
      const uint32_t after = next_[f];
      state_[f].meshlet = kNone;
      next_[f] = kNone;
      for (int corner = 0; corner < 3; ++corner) {
        ++live_vertex_[mesh_.indices[3 * size_t{f} + corner]];
      }
      for (const uint32_t g : neighbours_.of(f)) ++state_[g].live;
      --assigned;
      f = after;
    }
    head_.pop_back();
    tail_.pop_back();
    triangles_.pop_back();
    // Every flood verdict may change with the faces back.
    flood_large_ = ++flood_;
  }

  // Grows meshlet `head_.size()` from `seed`; returns the next seed (kNone: none left over).
  uint32_t GrowOne(uint32_t seed, uint32_t& assigned) {
    ++growth_;
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
        if (state_[face].meshlet == kNone) {
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
        // Its outside vertex joined: it went to free_ (and may be taken already).
        if (local_[candidate.outside] != kNotInMeshlet) continue;
        if (kept != i) candidates_[kept] = candidate;
        ++kept;
        Closing& closing = closing_[candidate.outside];
        if (closing.step != step_) closing = {step_, 0};
        ++closing.count;
      }
      candidates_.resize(kept);
      // Every candidate left adds its one outside vertex.
      if (vertices_.size() + 1 > max_vertices) break;
      const float inverse_radius = 1.0f / expected_radius_;
      for (size_t i = 0; i < candidates_.size(); ++i) {
        const Candidate& candidate = candidates_[i];
        const uint32_t closes = closing_[candidate.outside].count;
        const bool stranded =
            state_[candidate.face].live == 0 || live_vertex_[candidate.corners[0]] == 1 ||
            live_vertex_[candidate.corners[1]] == 1 || live_vertex_[candidate.corners[2]] == 1;
        const int face_class = stranded ? 1 : 2;
        if (face_class > best_class) continue;
        const float dx = candidate.centroid[0] - center[0];
        const float dy = candidate.centroid[1] - center[1];
        const float dz = candidate.centroid[2] - center[2];
        const float distance = std::sqrt(dx * dx + dy * dy + dz * dz) * inverse_radius;
        const float spread = candidate.normal[0] * axis[0] + candidate.normal[1] * axis[1] +
                             candidate.normal[2] * axis[2];
        const float cone = std::max(1.0f - spread * cone_weight, 1e-3f);
        // Each further face the new vertex admits counts as one unit of distance.
        const float score =
            (1.0f + distance * (1.0f - cone_weight)) * cone - static_cast<float>(closes - 1);
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
      if (state_[face].meshlet == kNone) pending_.push_back(face);
    }
    free_.clear();
    // The next seed: the most enclosed face left over (fewest unassigned edge neighbours,
    // then fewest unassigned faces around its corners).
    uint32_t next = kNone;
    uint64_t next_key = std::numeric_limits<uint64_t>::max();
    for (const Candidate& candidate : candidates_) {
      const uint32_t c = candidate.face;
      if (state_[c].meshlet != kNone) continue;
      const uint32_t* corners = &mesh_.indices[3 * size_t{c}];
      const uint64_t around =
          uint64_t{live_vertex_[corners[0]]} + live_vertex_[corners[1]] + live_vertex_[corners[2]];
      const uint64_t key = (uint64_t{state_[c].live} << 40) | around;
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

  void Add(uint32_t meshlet, uint32_t face, std::array<double, 6>& sum) {
    state_[face].meshlet = meshlet;
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
        for (const CornerTable::Corner& around : around_.around(v)) {
          const uint32_t g = around.face;
          if (local_[around.next] != kNotInMeshlet && local_[around.previous] != kNotInMeshlet &&
              state_[g].stamp == growth_ && state_[g].meshlet == kNone) {
            free_.push_back(g);
          }
        }
      }
      --live_vertex_[v];
    }
    for (uint32_t g : neighbours_.of(face)) {
      --state_[g].live;
      if (state_[g].meshlet == kNone && state_[g].stamp != growth_) {
        state_[g].stamp = growth_;
        const FaceFrame& frame = frames_[g];
        uint32_t outside = kNone;
        for (const uint32_t v : frame.corners) {
          if (local_[v] == kNotInMeshlet) outside = v;
        }
        if (outside == kNone) {
          free_.push_back(g);
          continue;
        }
        candidates_.push_back({g, outside, frame.corners, frame.centroid, frame.normal});
      }
    }
    const FaceFrame& frame = frames_[face];
    for (int axis = 0; axis < 3; ++axis) {
      sum[axis] += frame.centroid[axis];
      sum[3 + axis] += frame.normal[axis];
    }
  }

 public:
  // Writes the layout: meshlets in order of their ids, faces in list order (ids of the
  // spatially ordered mesh; BuildMeshlets maps them back).
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
  const CornerTable& around_;
  const EdgeNeighbours& neighbours_;
  uint32_t faces_;
  float expected_radius_ = 1;
  // What growth reads and writes of a face, side by side (one cache line per visit).
  struct FaceState {
    uint32_t meshlet = kNone;  // its meshlet; kNone while unassigned
    uint32_t stamp = kNone;    // the meshlet that has it as a candidate
    uint32_t live = 0;         // its unassigned edge neighbours
  };
  std::vector<FaceState> state_;
  std::vector<uint32_t> next_;
  std::vector<uint32_t> head_, tail_, triangles_;
  std::vector<uint32_t> live_vertex_;  // unassigned faces around each vertex
  std::vector<uint8_t> local_;         // a vertex's index in the meshlet being built
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
    uint32_t outside;  // its corner outside the meshlet (one: it shares an edge with it)
    std::array<uint32_t, 3> corners;
    std::array<float, 3> centroid;
    std::array<float, 3> normal;
  };
  std::vector<Candidate> candidates_;  // of the meshlet being built; none assigned
  std::vector<uint32_t> pending_;      // left over by finished meshlets
  std::vector<uint32_t> free_;         // candidates that add no vertex (may repeat)
  uint32_t growth_ = 0;                // GrowOne calls: the stamp of FaceState::stamp
  uint32_t pocket_limit_ = 1;
  // Regrowths of one meshlet at most (measured on elephant-with-holes: 75 meshlets without,
  // 63 with 2, no better with 4; bunny00 and refined_elephant unchanged).
  static constexpr uint32_t kPocketRetries = 2;
  std::vector<uint32_t> flood_stamp_;  // FindPocket's visits
  std::vector<uint32_t> flood_faces_;
  uint32_t flood_ = 1;
  uint32_t flood_large_ = 0;  // the stamp of faces found in a large region
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
  return absl::OkStatus();
}

absl::StatusOr<MeshletResult> BuildMeshlets(const TriangleMesh& input,
                                            const MeshletOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidateMeshletOptions(options));
  MLCLUST_RETURN_IF_ERROR(CheckMeshletInput(input));
  // Built on the spatially ordered copy; ids map back to the input's at the end.
  const SpatialOrder order = OrderSpatially(input);
  const TriangleMesh& mesh = order.mesh;
  const CornerTable around = BuildCornerTable(mesh);
  absl::StatusOr<EdgeNeighbours> neighbours =
      BuildEdgeNeighbours(around, static_cast<uint32_t>(mesh.num_faces()), options.cancel);
  if (!neighbours.ok()) return neighbours.status();
  MeshletBuilder builder(mesh, options, around, *neighbours);
  MLCLUST_RETURN_IF_ERROR(builder.Grow());
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
  for (uint32_t& face : result.triangle_faces) face = order.input_face[face];
  for (uint32_t& vertex : result.meshlet_vertices) vertex = order.input_vertex[vertex];
  std::vector<uint32_t> face_meshlet(result.face_meshlet.size());
  for (size_t f = 0; f < face_meshlet.size(); ++f) {
    face_meshlet[order.input_face[f]] = result.face_meshlet[f];
  }
  result.face_meshlet = std::move(face_meshlet);
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
