// Meshlets with hard caps, ours: the mesh cut into connected pieces a mesh shader can draw.
//
// A meshlet is at most `max_vertices` distinct vertices and at most `max_triangles`
// triangles, stored as meshoptimizer stores them (meshopt_Meshlet, 0.18): a meshlet names
// a run of `meshlet_vertices` (global vertex indices) and a run of `meshlet_triangles`
// (three one-byte local indices per triangle, into the meshlet's vertex run). Both caps
// hold for every meshlet, whatever the input. Every meshlet is edge-connected: its faces
// form one piece across shared edges (an edge shared by three or more faces connects all
// of them), so a meshlet never spans two pieces of the mesh.
//
// How (ours; meshoptimizer's meshopt_buildMeshlets, 0.18, was read for its scoring, not
// copied): one greedy pass over a copy of the mesh in spatial order (faces in Morton order
// of their centroids, vertices by first use: the arrays are then read in runs, where
// scanned meshes list faces in no order). A meshlet grows across edges from a seed face:
//   1. a candidate (an unassigned face across an edge of the meshlet) that adds no vertex
//      is taken at once;
//   2. otherwise the one to take adds one vertex; first a candidate that would be left
//      stranded (all its edge neighbours assigned, or a corner whose other faces are all
//      assigned), then by score: distance from the meshlet's centroid in units of the
//      expected meshlet radius (with cone_weight, meshoptimizer's blend with the normal's
//      spread from the meshlet's mean normal), less one for each further candidate the same
//      new vertex admits (a vertex that closes several faces keeps the border short: about
//      0.64 vertices per triangle where distance alone gives 0.66);
//   3. the meshlet ends when no candidate fits either cap.
// If a finished meshlet leaves a pocket of at most max_triangles / 2 unassigned faces
// (between itself, holes and earlier meshlets), it is grown again from inside the pocket
// (twice at most): a pocket would otherwise become a small meshlet that no full neighbour
// can take. The next seed is the finished meshlet's left-over candidate with the fewest
// unassigned edge neighbours, then the fewest unassigned faces around its corners (the
// most enclosed one: filling corners first leaves fewer islands); failing that, a face
// left over by an earlier meshlet (most recent first), then the lowest unassigned face (a
// new piece of the mesh). Unlike meshopt_buildMeshlets it never jumps to a face that does
// not touch the meshlet, which is why its meshlets are connected; the price is a small
// meshlet wherever the unassigned surface closes around a region (bunny00: 45 meshlets
// under 80 triangles and under the vertex cap, where meshoptimizer, jumping, has none).
#ifndef MLCLUST_CORE_MESHLETS_MESHLETS_H_
#define MLCLUST_CORE_MESHLETS_MESHLETS_H_

#include <atomic>
#include <cstdint>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/mesh/mesh.h"

namespace mlclust {

// The caps GPUs take. Local indices are one byte and meshoptimizer keeps 0xff for "not in
// the meshlet", hence 255 vertices; 512 triangles is NVIDIA's mesh-shader output limit
// (VK_NV_mesh_shader) and meshoptimizer's. VK_EXT_mesh_shader and Direct3D 12 guarantee
// 256 vertices and 256 primitives; the defaults (64, 124) are the common choice of NVIDIA's
// mesh-shading guide and meshoptimizer.
inline constexpr uint32_t kMaxMeshletVertices = 255;
inline constexpr uint32_t kMaxMeshletTriangles = 512;

struct MeshletOptions {
  uint32_t max_vertices = 64;    // distinct vertices per meshlet, in [3, kMaxMeshletVertices]
  uint32_t max_triangles = 124;  // triangles per meshlet, in [1, kMaxMeshletTriangles]
  // In [0, 1]: 0 grows by distance alone; towards 1 normals matter more than distance
  // (tighter normal cones for back-face culling, larger spheres). meshoptimizer's meaning.
  float cone_weight = 0.0f;
  // The bounding sphere and normal cone of each meshlet (meshopt_computeMeshletBounds).
  bool compute_bounds = true;
  const std::atomic<bool>* cancel = nullptr;  // checked every few thousand faces
};

// meshopt_Meshlet's layout (four 32-bit fields).
struct Meshlet {
  uint32_t vertex_offset = 0;    // first entry in meshlet_vertices
  uint32_t triangle_offset = 0;  // first byte in meshlet_triangles, a multiple of 4
  uint32_t vertex_count = 0;     // in [3, max_vertices] (fewer only for degenerate faces)
  uint32_t triangle_count = 0;   // in [1, max_triangles]
};

// meshopt_Bounds' fields (meshopt_computeMeshletBounds): a sphere holding the meshlet, and
// a normal cone: the meshlet is back-facing for a camera at c when
// dot(normalize(cone_apex - c), cone_axis) >= cone_cutoff (cos of half the cone's angle; 1
// when the normals spread too far for a cone).
struct MeshletBounds {
  float center[3] = {0, 0, 0};
  float radius = 0;
  float cone_apex[3] = {0, 0, 0};
  float cone_axis[3] = {0, 0, 0};
  float cone_cutoff = 1;
  int8_t cone_axis_s8[3] = {0, 0, 0};  // the axis as 8-bit SNORM (x / 127)
  int8_t cone_cutoff_s8 = 127;
};

struct MeshletResult {
  std::vector<Meshlet> meshlets;
  std::vector<uint32_t> meshlet_vertices;  // global vertex indices, meshlet by meshlet
  // Three local indices per triangle (each < its meshlet's vertex_count), in the input
  // face's corner order (the winding is kept); each meshlet's run is padded with zeros to
  // a multiple of 4 bytes, as meshoptimizer pads it.
  std::vector<uint8_t> meshlet_triangles;
  // The input face of each meshlet triangle: meshlet m's triangles are
  // triangle_faces[first .. first + triangle_count) with first = the sum of the triangle
  // counts of meshlets 0..m-1 (for per-face attributes).
  std::vector<uint32_t> triangle_faces;
  std::vector<uint32_t> face_meshlet;  // each input face's meshlet
  std::vector<MeshletBounds> bounds;   // one per meshlet; empty without compute_bounds
};

// OK, or INVALID_ARGUMENT naming the option and its range.
absl::Status ValidateMeshletOptions(const MeshletOptions& options);

// Cuts `input` into capped, connected meshlets (see the top of this file). The mesh needs
// whole triples, at least one face, vertex indices in range and finite coordinates; it may
// be non-manifold, have degenerate faces, borders and any number of pieces. Every face is
// in exactly one meshlet. Deterministic. INVALID_ARGUMENT for options
// ValidateMeshletOptions refuses or a mesh that breaks the above (naming the face corner
// or vertex); CANCELLED if options.cancel was set.
absl::StatusOr<MeshletResult> BuildMeshlets(const TriangleMesh& input,
                                            const MeshletOptions& options = {});

// The checks a consumer would make, for tests and for files read back: offsets and counts
// within the arrays and contiguous in meshlet order, 4-byte aligned triangle runs, every
// local index below its meshlet's vertex count, both caps, each face exactly once
// (triangle_faces and face_meshlet agree, F = face_meshlet's size), bounds (when present)
// one per meshlet; with `mesh`, also F = its face count and each triangle's corners those
// of its face, in order. OK, or INVALID_ARGUMENT naming the first meshlet that breaks one.
absl::Status CheckMeshletLayout(const MeshletResult& meshlets, uint32_t max_vertices,
                                uint32_t max_triangles, const TriangleMesh* mesh = nullptr);

}  // namespace mlclust

#endif  // MLCLUST_CORE_MESHLETS_MESHLETS_H_
