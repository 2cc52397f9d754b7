// Labels per input polygon (`mlclust mesh --per-polygon`, issue 13): the reader
// (core/io/mesh_io.h) turns a polygon of n corners into n - 2 triangles in its place, so
// the triangles of polygon p are a run of consecutive face ids, and a clustering of the
// triangles can be read back per polygon.
//
// The client sends the counts (JobSpec.polygon_triangle_counts) for the algorithms that
// cluster whole polygons on the server (ServerClustersPolygons); their levels never split
// a polygon. The fallback, ours, a post-pass for the other algorithms and for a server
// older than that field (it then splits polygons): the clustering runs on the triangles;
// each polygon then goes to the cluster holding most of its area (ties to the smaller
// cluster id), so a polygon's triangles end in one cluster. The energy of the result is
// recomputed from its labels.
#ifndef MLCLUST_CLIENT_POLYGONS_H_
#define MLCLUST_CLIENT_POLYGONS_H_

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "core/base/ids.h"
#include "core/mesh/mesh.h"

namespace mlclust::client {

// The number of triangles each polygon of an OFF or OBJ file becomes, in file order (n - 2
// for a polygon of n >= 3 corners; points and lines, which the reader drops, are left out).
// OFF: INVALID_ARGUMENT naming the line for a file that is not OFF as mesh_io reads it (the
// keyword variants [ST][C][N][4][n]OFF, comments, counts on the keyword's line). OBJ: its
// "f" lines; UNIMPLEMENTED for more than one material (Assimp groups faces by material).
// Other formats: UNIMPLEMENTED (their readers do not report polygons yet). The caller
// checks the total against the mesh read (LabelsPerPolygon).
absl::StatusOr<std::vector<uint32_t>> ReadPolygonTriangleCounts(const std::string& path);

// Whether the server clusters whole polygons for `algorithm` (a registry name): ml, hc,
// pml, emlo and bb (core/mesh/polygons.h).
bool ServerClustersPolygons(const std::string& algorithm);

struct PolygonLabels {
  std::vector<ClusterId> per_polygon;  // one per polygon
  std::vector<ClusterId> per_face;     // one per triangle: its polygon's
  uint32_t split_polygons = 0;         // polygons whose triangles were in several clusters
};

// Each polygon in the cluster of most of its area (`face_labels` one per triangle of
// `mesh`; `triangle_counts` from ReadPolygonTriangleCounts). INVALID_ARGUMENT if the
// counts do not add up to the mesh's faces or the labels are not one per face.
absl::StatusOr<PolygonLabels> LabelsPerPolygon(const TriangleMesh& mesh,
                                               std::span<const uint32_t> triangle_counts,
                                               std::span<const ClusterId> face_labels);

}  // namespace mlclust::client

#endif  // MLCLUST_CLIENT_POLYGONS_H_
