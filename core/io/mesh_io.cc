#include "core/io/mesh_io.h"

#include <assimp/config.h>
#include <assimp/mesh.h>
#include <assimp/scene.h>

#include <algorithm>
#include <assimp/Importer.hpp>
#include <bit>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <new>
#include <numeric>
#include <span>
#include <system_error>
#include <utility>
#include <vector>

#include "absl/container/flat_hash_map.h"
#include "absl/status/status.h"
#include "absl/strings/ascii.h"
#include "absl/strings/escaping.h"
#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"
#include "core/base/status_macros.h"
#include "core/io/draco_codec.h"
#include "core/io/gltf_draco.h"
#include "nlohmann/json.hpp"

namespace mlclust {
namespace {

// ---------------------------------------------------------------------------------------
// Polygons as a file holds them, before welding and triangulation.

// One mesh of a file: positions (already in world space) and polygons as runs of corner
// indices into those positions. Polygons with fewer than three corners are points and
// lines; they stay here and are dropped by MeshAssembler.
struct PolygonPart {
  std::vector<float> positions;         // x, y, z per vertex
  std::vector<uint32_t> polygon_start;  // polygon p: corners[start[p] .. start[p + 1])
  std::vector<uint32_t> corners;

  PolygonPart() : polygon_start{0} {}
  size_t num_vertices() const { return positions.size() / 3; }
  size_t num_polygons() const { return polygon_start.size() - 1; }
};

// ---------------------------------------------------------------------------------------
// Triangulation. Assimp's aiProcess_Triangulate is not used: from 5.1 on it "NGON-encodes"
// its output and rotates the corners of a plain triangle that follows a polygon sharing
// its first vertex (a triangle 0 1 4 after the quad 0 1 2 3 comes back as 4 0 1), so
// face corners would depend on the neighbouring faces. Doing it here keeps every
// triangle of the file exactly as written and treats OFF and Assimp formats alike.

// Ear clipping (Meisters' two-ears theorem) in the plane of the polygon's Newell normal.
// A polygon of n corners always yields n - 2 triangles, so a client can predict face ids;
// each triangle keeps the polygon's winding. Ears are tried from corner 1 on, which makes
// a convex polygon the fan (0 1 2) (0 2 3) ... (the split most exporters expect). A
// polygon with no ear (self-intersecting or degenerate) falls back to that fan.
// O(n^2) per polygon, fine for the polygons found in practice.
class Triangulator {
 public:
  // Appends the triangles of polygon `corners` (indices into `positions`) to `out`.
  void Triangulate(const std::vector<float>& positions, std::span<const uint32_t> corners,
                   std::vector<std::array<uint32_t, 3>>& out) {
    ProjectToPlane(positions, corners);
    ring_.resize(corners.size());
    std::iota(ring_.begin(), ring_.end(), 0);
    size_t candidate = 1;  // Position in ring_ where the search for an ear starts.
    while (ring_.size() > 3) {
      const size_t m = ring_.size();
      size_t ear = m;
      for (size_t attempt = 0; attempt < m && ear == m; ++attempt) {
        const size_t at = (candidate + attempt) % m;
        if (IsEar(ring_[(at + m - 1) % m], ring_[at], ring_[(at + 1) % m])) ear = at;
      }
      if (ear == m) ear = 1;  // No ear: clip the fan triangle around ring_[0].
      out.push_back(
          {corners[ring_[(ear + m - 1) % m]], corners[ring_[ear]], corners[ring_[(ear + 1) % m]]});
      ring_.erase(ring_.begin() + ear);
      candidate = ear < ring_.size() ? ear : 0;
    }
    out.push_back({corners[ring_[0]], corners[ring_[1]], corners[ring_[2]]});
  }

 private:
  struct Point2 {
    double u, v;
    bool operator==(const Point2&) const = default;
  };

  static double Cross(Point2 a, Point2 b, Point2 c) {
    return (b.u - a.u) * (c.v - a.v) - (b.v - a.v) * (c.u - a.u);
  }

  // Drops the dominant axis of the Newell normal and mirrors if needed so that the
  // polygon runs counter-clockwise in 2D.
  void ProjectToPlane(const std::vector<float>& positions, std::span<const uint32_t> corners) {
    const size_t n = corners.size();
    double normal[3] = {0, 0, 0};
    for (size_t i = 0; i < n; ++i) {
      const float* a = &positions[3 * size_t{corners[i]}];
      const float* b = &positions[3 * size_t{corners[(i + 1) % n]}];
      normal[0] += (double{a[1]} - b[1]) * (double{a[2]} + b[2]);
      normal[1] += (double{a[2]} - b[2]) * (double{a[0]} + b[0]);
      normal[2] += (double{a[0]} - b[0]) * (double{a[1]} + b[1]);
    }
    int axis = 2;
    if (std::abs(normal[0]) > std::abs(normal[1]) && std::abs(normal[0]) > std::abs(normal[2])) {
      axis = 0;
    } else if (std::abs(normal[1]) > std::abs(normal[2])) {
      axis = 1;
    }
    const double mirror = normal[axis] < 0 ? -1.0 : 1.0;
    projected_.resize(n);
    for (size_t i = 0; i < n; ++i) {
      const float* p = &positions[3 * size_t{corners[i]}];
      projected_[i] = {p[(axis + 1) % 3], mirror * p[(axis + 2) % 3]};
    }
  }

  // An ear: a strictly convex corner whose triangle holds no other corner of the ring
  // (corners at the same position as the ear's own, as in a polygon that touches
  // itself, are ignored).
  bool IsEar(uint32_t prev, uint32_t at, uint32_t next) const {
    const Point2 a = projected_[prev], b = projected_[at], c = projected_[next];
    if (Cross(a, b, c) <= 0) return false;
    for (uint32_t other : ring_) {
      const Point2 p = projected_[other];
      if (other == prev || other == at || other == next || p == a || p == b || p == c) {
        continue;
      }
      if (Cross(a, b, p) >= 0 && Cross(b, c, p) >= 0 && Cross(c, a, p) >= 0) return false;
    }
    return true;
  }

  std::vector<Point2> projected_;
  std::vector<uint32_t> ring_;
};

// ---------------------------------------------------------------------------------------
// Welding and triangulation of the parts into one TriangleMesh.

// Bits of a position with -0 folded into +0, so that the two zeros weld as == says.
std::array<uint32_t, 3> PositionKey(const float* p) {
  std::array<uint32_t, 3> key;
  for (int i = 0; i < 3; ++i) key[i] = std::bit_cast<uint32_t>(p[i] == 0.0f ? 0.0f : p[i]);
  return key;
}

class MeshAssembler {
 public:
  // Appends the triangles of `part` after those already added. `flip_winding` swaps
  // corners 1 and 2 of every triangle (for parts placed by a mirroring transform).
  absl::Status AddPart(const PolygonPart& part, bool flip_winding) {
    const size_t num_vertices = part.num_vertices();
    for (size_t i = 0; i < part.corners.size(); ++i) {
      if (part.corners[i] >= num_vertices) {
        const size_t polygon =
            std::upper_bound(part.polygon_start.begin(), part.polygon_start.end(), i) -
            part.polygon_start.begin() - 1;
        return absl::InvalidArgumentError(absl::StrCat("polygon ", polygon, " refers to vertex ",
                                                       part.corners[i], ", but its mesh has ",
                                                       num_vertices, " vertices"));
      }
    }

    // Triangulate first, in the part's own vertex ids.
    triangles_.clear();
    for (size_t p = 0; p < part.num_polygons(); ++p) {
      const std::span<const uint32_t> polygon(part.corners.data() + part.polygon_start[p],
                                              part.polygon_start[p + 1] - part.polygon_start[p]);
      if (polygon.size() < 3) continue;  // A point or a line.
      if (polygon.size() == 3) {
        triangles_.push_back({polygon[0], polygon[1], polygon[2]});
      } else {
        triangulator_.Triangulate(part.positions, polygon, triangles_);
      }
    }
    if (mesh_.num_faces() + triangles_.size() > kMaxMeshElements) {
      return absl::InvalidArgumentError(absl::StrCat("more than ", kMaxMeshElements, " triangles"));
    }

    // How often each vertex is a polygon corner (counting stops at 2).
    welded_id_.assign(num_vertices, 0);
    bool shares_vertices = false;
    for (size_t p = 0; p < part.num_polygons(); ++p) {
      if (part.polygon_start[p + 1] - part.polygon_start[p] < 3) continue;
      for (uint32_t i = part.polygon_start[p]; i < part.polygon_start[p + 1]; ++i) {
        uint32_t& uses = welded_id_[part.corners[i]];
        if (uses > 0) shares_vertices = true;
        uses = std::min(uses + 1, 2u);
      }
    }
    if (mesh_.num_vertices() + num_vertices > kMaxMeshElements) {
      return absl::InvalidArgumentError(absl::StrCat("more than ", kMaxMeshElements, " vertices"));
    }
    if (shares_vertices) {
      // The file says which corners share a vertex: keep its vertices as they are, all
      // of them and in its order. Welding them would be wrong: elephant-with-holes.off
      // lists vertices twice at one position on purpose, and merging them makes the mesh
      // non-manifold.
      const uint32_t base = static_cast<uint32_t>(mesh_.num_vertices());
      mesh_.positions.insert(mesh_.positions.end(), part.positions.begin(), part.positions.end());
      for (size_t v = 0; v < num_vertices; ++v) welded_id_[v] = base + static_cast<uint32_t>(v);
    } else {
      // Every corner has a vertex of its own (STL; OBJ as Assimp reads it; glTF without
      // indices), so the only connectivity there is lies in the positions: weld equal
      // ones, also across parts, in the order the part lists them. Vertices no polygon
      // uses are dropped.
      for (size_t v = 0; v < num_vertices; ++v) {
        if (welded_id_[v] == 0) continue;
        const float* p = &part.positions[3 * v];
        const auto [it, inserted] = vertex_of_position_.try_emplace(
            PositionKey(p), static_cast<uint32_t>(mesh_.num_vertices()));
        if (inserted) mesh_.positions.insert(mesh_.positions.end(), p, p + 3);
        welded_id_[v] = it->second;
      }
    }

    mesh_.indices.reserve(mesh_.indices.size() + 3 * triangles_.size());
    for (const auto& t : triangles_) {
      mesh_.indices.push_back(welded_id_[t[0]]);
      mesh_.indices.push_back(welded_id_[flip_winding ? t[2] : t[1]]);
      mesh_.indices.push_back(welded_id_[flip_winding ? t[1] : t[2]]);
    }
    return absl::OkStatus();
  }

  TriangleMesh Finish() && { return std::move(mesh_); }

 private:
  TriangleMesh mesh_;
  absl::flat_hash_map<std::array<uint32_t, 3>, uint32_t> vertex_of_position_;
  std::vector<uint32_t> welded_id_;
  std::vector<std::array<uint32_t, 3>> triangles_;
  Triangulator triangulator_;
};

// ---------------------------------------------------------------------------------------
// Files.

absl::Status FileError(const std::string& path, int error_number, absl::string_view what) {
  // errno 0 would map to OK; a failure with no reason recorded is still a failure.
  const absl::StatusCode code =
      error_number == 0 ? absl::StatusCode::kUnknown : absl::ErrnoToStatusCode(error_number);
  return absl::Status(code, absl::StrCat(path, ": ", what, ": ", std::strerror(error_number)));
}

// NOT_FOUND for a missing file; INVALID_ARGUMENT for a directory or other non-file.
absl::Status CheckIsFile(const std::string& path) {
  std::error_code error;
  const std::filesystem::file_status status = std::filesystem::status(path, error);
  if (status.type() == std::filesystem::file_type::not_found) {
    return absl::NotFoundError(absl::StrCat(path, ": no such file"));
  }
  if (error) return FileError(path, error.value(), "cannot inspect");
  if (status.type() != std::filesystem::file_type::regular) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": not a regular file"));
  }
  return absl::OkStatus();
}

// Reads at most `limit` bytes from the start of the file.
absl::StatusOr<std::string> ReadFileBytes(const std::string& path,
                                          size_t limit = std::numeric_limits<size_t>::max()) {
  std::ifstream file(path, std::ios::binary);
  if (!file) return FileError(path, errno, "cannot open");
  std::string bytes;
  char chunk[1 << 16];
  while (bytes.size() < limit && file) {
    file.read(chunk, static_cast<std::streamsize>(std::min(sizeof(chunk), limit - bytes.size())));
    bytes.append(chunk, static_cast<size_t>(file.gcount()));
  }
  if (file.bad()) return FileError(path, errno, "read failed");
  return bytes;
}

std::string LowercaseExtension(const std::string& path) {
  return absl::AsciiStrToLower(std::filesystem::path(path).extension().string());
}

// ---------------------------------------------------------------------------------------
// OFF, read here rather than by Assimp. Assimp 5.2's OFF reader silently clamps an
// out-of-range index to the last vertex, drops faces of more than 9 corners (shifting
// every later face id), reads a missing index as 0, needs each vertex on its own line,
// and on a short file leaves faces uninitialised (an assertion abort in the Debian build).
// This reader follows the Geomview/CGAL layout and refuses anything it cannot place.

bool IsSpace(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\v' || c == '\f'; }

// The keyword [ST][C][N][4][n]OFF; `homogeneous` and `has_dimension` report 4 and n.
bool ParseOffKeyword(absl::string_view token, bool* homogeneous, bool* has_dimension) {
  if (token.size() < 3 || token.substr(token.size() - 3) != "OFF") return false;
  absl::string_view prefix = token.substr(0, token.size() - 3);
  auto take = [&prefix](absl::string_view p) {
    if (prefix.substr(0, p.size()) != p) return false;
    prefix.remove_prefix(p.size());
    return true;
  };
  take("ST");
  take("C");
  take("N");
  *homogeneous = take("4");
  *has_dimension = take("n");
  return prefix.empty();
}

// Lines of an OFF file with comments removed and blank lines skipped.
class OffLines {
 public:
  explicit OffLines(absl::string_view text) : text_(text) {}

  // The next non-blank line, or false at the end of the text.
  bool Next(absl::string_view* line) {
    while (position_ < text_.size()) {
      const size_t end = std::min(text_.find('\n', position_), text_.size());
      absl::string_view raw = text_.substr(position_, end - position_);
      position_ = end + 1;
      ++line_number_;
      raw = raw.substr(0, raw.find('#'));
      if (std::any_of(raw.begin(), raw.end(), [](char c) { return !IsSpace(c); })) {
        *line = raw;
        return true;
      }
    }
    return false;
  }
  int line_number() const { return line_number_; }

 private:
  absl::string_view text_;
  size_t position_ = 0;
  int line_number_ = 0;
};

// Whitespace-separated tokens of one line.
class Tokens {
 public:
  explicit Tokens(absl::string_view line) : line_(line) {}
  bool Next(absl::string_view* token) {
    while (position_ < line_.size() && IsSpace(line_[position_])) ++position_;
    if (position_ == line_.size()) return false;
    const size_t start = position_;
    while (position_ < line_.size() && !IsSpace(line_[position_])) ++position_;
    *token = line_.substr(start, position_ - start);
    return true;
  }

 private:
  absl::string_view line_;
  size_t position_ = 0;
};

bool ParseFloat(absl::string_view token, float* value) {
  if (token.size() > 1 && token[0] == '+') token.remove_prefix(1);
  // from_chars is correctly rounded, so the float is the one the text denotes.
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), *value);
  return error == std::errc() && end == token.data() + token.size();
}

bool ParseUnsigned(absl::string_view token, uint64_t* value) {
  const auto [end, error] = std::from_chars(token.data(), token.data() + token.size(), *value);
  return error == std::errc() && end == token.data() + token.size();
}

absl::StatusOr<PolygonPart> ParseOff(absl::string_view text) {
  OffLines lines(text);
  auto error = [&lines](auto&&... message) {
    return absl::InvalidArgumentError(absl::StrCat("line ", lines.line_number(), ": ", message...));
  };
  absl::string_view line, token;
  if (!lines.Next(&line)) return absl::InvalidArgumentError("empty OFF file");

  // Header: optional keyword, optional dimension (nOFF), then the vertex and face
  // counts, which may share the keyword's line. The edge count is ignored.
  bool homogeneous = false, has_dimension = false;
  Tokens tokens(line);
  if (!tokens.Next(&token)) return error("empty header");
  if (!ParseOffKeyword(token, &homogeneous, &has_dimension)) {
    if (!absl::ascii_isdigit(static_cast<unsigned char>(token[0]))) {
      return error("expected the OFF keyword or the vertex count, found '", token, "'");
    }
    tokens = Tokens(line);  // No keyword (the spec allows it): the line holds counts.
  }
  const size_t numbers_wanted = has_dimension ? 3 : 2;
  std::vector<uint64_t> numbers;
  while (numbers.size() < numbers_wanted) {
    if (!tokens.Next(&token)) {
      if (!lines.Next(&line)) return error("the file ends inside the header");
      tokens = Tokens(line);
      continue;
    }
    if (token == "BINARY") return error("binary OFF is not supported");
    uint64_t number;
    if (!ParseUnsigned(token, &number)) return error("expected a count, found '", token, "'");
    numbers.push_back(number);
  }
  if (has_dimension && numbers[0] != 3) {
    return error("only 3-dimensional OFF is supported, this file has dimension ", numbers[0]);
  }
  const uint64_t num_vertices = numbers[numbers.size() - 2];
  const uint64_t num_faces = numbers[numbers.size() - 1];
  if (num_vertices > kMaxMeshElements || num_faces > kMaxMeshElements) {
    return error("too many elements: ", num_vertices, " vertices, ", num_faces, " faces");
  }

  PolygonPart part;
  // Counts are untrusted: reserve no more than the text could hold (a vertex takes at
  // least 6 bytes, a face 8), so a lying header cannot allocate gigabytes.
  part.positions.reserve(3 * std::min<uint64_t>(num_vertices, text.size() / 6));
  part.polygon_start.reserve(1 + std::min<uint64_t>(num_faces, text.size() / 8));
  part.corners.reserve(3 * std::min<uint64_t>(num_faces, text.size() / 8));
  for (uint64_t v = 0; v < num_vertices; ++v) {
    if (!lines.Next(&line)) {
      return error("the file ends after ", v, " of ", num_vertices, " vertices");
    }
    // Coordinates come first; normals, colours and texture coordinates that may follow
    // on the line are ignored.
    tokens = Tokens(line);
    float xyzw[4];
    const int wanted = homogeneous ? 4 : 3;
    for (int i = 0; i < wanted; ++i) {
      if (!tokens.Next(&token)) {
        return error("vertex ", v, " has ", i, " coordinates, ", wanted, " are needed");
      }
      if (!ParseFloat(token, &xyzw[i])) {
        return error("vertex ", v, ": '", token, "' is not a float coordinate");
      }
    }
    if (homogeneous) {
      for (int i = 0; i < 3; ++i) xyzw[i] /= xyzw[3];
    }
    part.positions.insert(part.positions.end(), xyzw, xyzw + 3);
  }
  for (uint64_t f = 0; f < num_faces; ++f) {
    if (!lines.Next(&line)) {
      return error("the file ends after ", f, " of ", num_faces, " faces");
    }
    tokens = Tokens(line);
    uint64_t num_corners = 0;
    tokens.Next(&token);
    if (!ParseUnsigned(token, &num_corners)) {
      return error("face ", f, ": '", token, "' is not a corner count");
    }
    if (num_corners > std::numeric_limits<uint32_t>::max() - part.corners.size()) {
      return error("face ", f, ": too many corners");
    }
    for (uint64_t c = 0; c < num_corners; ++c) {
      uint64_t index;
      if (!tokens.Next(&token)) {
        return error("face ", f, " has ", c, " of its ", num_corners, " vertex indices");
      }
      if (!ParseUnsigned(token, &index)) {
        return error("face ", f, ": '", token, "' is not a vertex index");
      }
      if (index >= num_vertices) {
        return error("face ", f, " corner ", c, " refers to vertex ", index, ", but the file has ",
                     num_vertices, " vertices");
      }
      part.corners.push_back(static_cast<uint32_t>(index));
    }
    // Anything after the indices is the face's colour, which we do not need.
    part.polygon_start.push_back(static_cast<uint32_t>(part.corners.size()));
  }
  return part;
}

// True if the file starts (after blank and comment lines) with an OFF keyword, so that
// OFF content under another extension does not reach Assimp's OFF reader either.
bool LooksLikeOff(absl::string_view head) {
  OffLines lines(head);
  absl::string_view line, token;
  bool homogeneous, has_dimension;
  return lines.Next(&line) && Tokens(line).Next(&token) &&
         ParseOffKeyword(token, &homogeneous, &has_dimension);
}

// ---------------------------------------------------------------------------------------
// Everything else, through Assimp.

// Node transforms as affine 3x4 matrices in double precision, so that composing a deep
// hierarchy does not lose more than the final rounding to float.
struct Affine {
  double m[3][4] = {{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}};

  static Affine From(const aiMatrix4x4& a) {
    Affine t;
    const ai_real* rows[3] = {&a.a1, &a.b1, &a.c1};
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) t.m[r][c] = rows[r][c];
    }
    return t;
  }
  Affine Then(const Affine& local) const {  // this * local
    Affine t;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        t.m[r][c] = m[r][0] * local.m[0][c] + m[r][1] * local.m[1][c] + m[r][2] * local.m[2][c] +
                    (c == 3 ? m[r][3] : 0.0);
      }
    }
    return t;
  }
  bool IsIdentity() const {  // Exact, unlike aiMatrix4x4::IsIdentity's 1e-2 tolerance.
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 4; ++c) {
        if (m[r][c] != (r == c ? 1.0 : 0.0)) return false;
      }
    }
    return true;
  }
  double Determinant() const {
    return m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1]) -
           m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0]) +
           m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]);
  }
};

PolygonPart PartFromAssimp(const aiMesh& mesh, const Affine& transform) {
  PolygonPart part;
  part.positions.resize(3 * size_t{mesh.mNumVertices});
  const bool identity = transform.IsIdentity();
  for (unsigned v = 0; v < mesh.mNumVertices; ++v) {
    const aiVector3D& p = mesh.mVertices[v];
    float* out = &part.positions[3 * size_t{v}];
    if (identity) {  // Bit-exact: no arithmetic at all on untransformed meshes.
      out[0] = p.x, out[1] = p.y, out[2] = p.z;
      continue;
    }
    for (int r = 0; r < 3; ++r) {
      const double* row = transform.m[r];
      out[r] = static_cast<float>(row[0] * p.x + row[1] * p.y + row[2] * p.z + row[3]);
    }
  }
  part.polygon_start.reserve(size_t{mesh.mNumFaces} + 1);
  for (unsigned f = 0; f < mesh.mNumFaces; ++f) {
    const aiFace& face = mesh.mFaces[f];
    if (face.mIndices != nullptr) {
      part.corners.insert(part.corners.end(), face.mIndices, face.mIndices + face.mNumIndices);
    }
    part.polygon_start.push_back(static_cast<uint32_t>(part.corners.size()));
  }
  return part;
}

// A PLY element or property name as files use them ("vertex", "vertex_indices", "nx").
// Assimp 5.2 reads a name that starts with digits as a number: "element 888…888face 2"
// (fuzz_ply, 337 bytes) made it allocate 9.6 GB.
bool IsPlyName(absl::string_view name) {
  if (name.empty() || !(absl::ascii_isalpha(name[0]) || name[0] == '_')) return false;
  return std::all_of(name.begin(), name.end(), [](char c) {
    return absl::ascii_isalnum(c) || c == '_' || c == '-' || c == '.';
  });
}

// The largest value a PLY list count of `type` can hold; 0 for a type that is not an
// integer type.
uint64_t PlyListCountMax(absl::string_view type) {
  if (type == "char" || type == "int8") return 127;
  if (type == "uchar" || type == "uint8") return 255;
  if (type == "short" || type == "int16") return 32767;
  if (type == "ushort" || type == "uint16") return 65535;
  if (type == "int" || type == "int32") return 2147483647;
  if (type == "uint" || type == "uint32") return 4294967295;
  return 0;
}

// Assimp 5.2's PLY reader loops forever on a header that ends early (a truncated file)
// or holds a line or type it does not know, so the header is checked here first.
// `head` is the start of the file; the header must end inside it. `file_size` is the
// whole file's: the elements the header declares must fit the bytes after it, at least
// one byte per property (or per element, for one without properties), because Assimp
// works through every declared element even when the body ends early, and on a body it
// cannot parse that costs a file seek and read each (a 295-byte file declaring 2,222,224
// faces took a minute; found by fuzz_ply).
struct PlyLayout {
  bool ascii = false;
  size_t body_offset = 0;  // the first byte after end_header's line
  struct Element {
    std::string name;
    uint64_t count = 0;
    uint64_t properties = 0;
    // Per property: "" for a scalar, the count's type for a list.
    std::vector<std::string> list_count_types;
  };
  std::vector<Element> elements;
};

absl::Status CheckPlyHeader(absl::string_view head, uint64_t file_size, PlyLayout* layout) {
  static constexpr absl::string_view kTypes[] = {
      "char", "uchar", "short", "ushort", "int",   "uint",   "float",   "double",
      "int8", "uint8", "int16", "uint16", "int32", "uint32", "float32", "float64"};
  auto is_type = [](absl::string_view t) {
    return std::find(std::begin(kTypes), std::end(kTypes), t) != std::end(kTypes);
  };
  size_t position = 0;
  int line_number = 0;
  bool has_format = false;
  std::vector<PlyLayout::Element>& elements = layout->elements;
  while (position < head.size()) {
    const size_t end = std::min(head.find('\n', position), head.size());
    absl::string_view line = head.substr(position, end - position);
    position = end + 1;
    ++line_number;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    // Assimp separates words by spaces and tabs only and ends lines at \r, \n, \f and \0,
    // so a header with other control characters reads differently there: "end_header\v..."
    // is an end here but not to Assimp, which then loops (found by fuzz_ply).
    for (const char c : line) {
      if ((static_cast<unsigned char>(c) < 0x20 && c != '\t') || c == 0x7f) {
        return absl::InvalidArgumentError(
            absl::StrCat("PLY header line ", line_number, ": control character 0x",
                         absl::Hex(static_cast<unsigned char>(c), absl::kZeroPad2),
                         " (words are separated by spaces and tabs only)"));
      }
    }
    Tokens tokens(line);
    std::vector<absl::string_view> words;
    for (absl::string_view word; tokens.Next(&word);) words.push_back(word);
    auto error = [line_number](auto&&... message) {
      return absl::InvalidArgumentError(
          absl::StrCat("PLY header line ", line_number, ": ", message...));
    };
    if (line_number == 1) {
      if (line != "ply") return error("the file does not start with 'ply'");
      continue;
    }
    if (words.empty()) continue;
    const absl::string_view keyword = words[0];
    if (keyword == "end_header") {
      if (!has_format) return error("no format line before end_header");
      const uint64_t body_bytes = file_size > position ? file_size - position : 0;
      uint64_t least_bytes = 0;
      for (const PlyLayout::Element& element : elements) {
        if (element.count > body_bytes) {
          least_bytes = body_bytes + 1;
          break;
        }
        least_bytes += element.count * std::max<uint64_t>(element.properties, 1);
        if (least_bytes > body_bytes) break;
      }
      if (least_bytes > body_bytes) {
        return absl::InvalidArgumentError(absl::StrCat(
            "the PLY header declares more elements than the ", body_bytes,
            " bytes after it can hold (at least one byte per property; truncated file?)"));
      }
      layout->body_offset = std::min(position, head.size());
      return absl::OkStatus();
    }
    if (keyword == "comment" || keyword == "obj_info") continue;
    uint64_t count;
    if (keyword == "format") {
      if (words.size() != 3 || (words[1] != "ascii" && words[1] != "binary_little_endian" &&
                                words[1] != "binary_big_endian")) {
        return error("unknown format '", line, "'");
      }
      has_format = true;
      layout->ascii = words[1] == "ascii";
    } else if (keyword == "element") {
      if (words.size() != 3 || !ParseUnsigned(words[2], &count)) {
        return error("expected 'element NAME COUNT', found '", line, "'");
      }
      if (!IsPlyName(words[1])) {
        return error("element name '", words[1],
                     "' is not a name (a letter or '_', then letters, digits, '_', '-' or '.')");
      }
      elements.push_back({std::string(words[1]), count, 0, {}});
    } else if (keyword == "property") {
      const bool list =
          words.size() == 5 && words[1] == "list" && is_type(words[2]) && is_type(words[3]);
      if (!list && !(words.size() == 3 && is_type(words[1]))) {
        return error("unknown property '", line, "'");
      }
      if (!IsPlyName(words.back())) {
        return error("property name '", words.back(),
                     "' is not a name (a letter or '_', then letters, digits, '_', '-' or '.')");
      }
      if (list && PlyListCountMax(words[2]) == 0) {
        return error("a list's count type must be an integer type, found '", words[2], "'");
      }
      if (!elements.empty()) {
        ++elements.back().properties;
        elements.back().list_count_types.push_back(list ? std::string(words[2]) : "");
      }
    } else {
      return error("unknown keyword '", keyword, "'");
    }
  }
  return absl::InvalidArgumentError("the PLY header has no end_header line (truncated file?)");
}

// Headers are a few hundred bytes; this leaves room for any number of comments.
constexpr size_t kMaxPlyHeaderBytes = 1 << 20;

bool LooksLikePly(absl::string_view head) {
  return absl::StartsWith(head, "ply\n") || absl::StartsWith(head, "ply\r\n");
}

// An ASCII PLY body read the way the header lays it out: every scalar one token, every list
// a count (an unsigned integer within its declared type) and that many tokens, for every
// element the header declares. Assimp 5.2's ASCII reader takes a list count out of its
// type's range or past the body's end as a loop bound and works through it token by token
// (a 268-byte file with the count 3555555555555555555555500 kept it busy for minutes;
// found by fuzz_ply), so a body that does not match its header is refused here, with the
// line that does not.
absl::Status CheckPlyAsciiBody(absl::string_view body, const PlyLayout& layout) {
  // Text only, up to the end of the data: Assimp ends a line at a NUL and reads bytes that
  // are not text its own way. The layout is walked over the text before the first other
  // byte; running into that byte is the error then.
  size_t text_end = 0;
  int text_lines = 1;
  for (; text_end < body.size(); ++text_end) {
    const auto c = static_cast<unsigned char>(body[text_end]);
    if ((c < 0x20 && c != '\t' && c != '\n' && c != '\r') || c >= 0x7f) break;
    if (c == '\n') ++text_lines;
  }
  const absl::string_view text = body.substr(0, text_end);
  // Assimp reads one element per line, as PLY files write them; blank lines are skipped.
  size_t position = 0;
  int line_number = 0;  // within the body
  absl::string_view line;
  auto next_line = [&]() {
    while (position < text.size()) {
      const size_t end = std::min(text.find('\n', position), text.size());
      line = text.substr(position, end - position);
      position = end + 1;
      ++line_number;
      if (!absl::StripAsciiWhitespace(line).empty()) return true;
    }
    return false;
  };
  for (const PlyLayout::Element& element : layout.elements) {
    for (uint64_t item = 0; item < element.count; ++item) {
      // The text stops at a byte that is not text: the error where a line runs into it.
      auto not_text = [&]() {
        return absl::InvalidArgumentError(
            absl::StrCat("PLY body line ", text_lines, ": byte 0x",
                         absl::Hex(static_cast<unsigned char>(body[text_end]), absl::kZeroPad2),
                         " in an ASCII file (text only)"));
      };
      const bool at_not_text = text_end < body.size();
      if (!next_line()) {
        if (at_not_text) return not_text();
        return absl::InvalidArgumentError(absl::StrCat(
            "PLY body: the body ends before ", element.name, " ", item, " (truncated file?)"));
      }
      auto error = [&](auto&&... message) {
        return absl::InvalidArgumentError(absl::StrCat("PLY body line ", line_number, " (",
                                                       element.name, " ", item, "): ", message...));
      };
      Tokens tokens(line);
      absl::string_view token;
      // Every value is a number: Assimp reads other words its own way (a 272-byte file of
      // numbers run into bytes took it 14 s; found by fuzz_ply).
      float number = 0;
      for (const std::string& count_type : element.list_count_types) {
        if (!tokens.Next(&token)) {
          return at_not_text && position > text.size() ? not_text() : error("the line ends early");
        }
        if (count_type.empty()) {
          if (!ParseFloat(token, &number)) return error("'", token, "' is not a number");
          continue;
        }
        uint64_t count = 0;
        if (!ParseUnsigned(token, &count) || count > PlyListCountMax(count_type)) {
          return error("list count '", token, "' is not a ", count_type);
        }
        for (uint64_t i = 0; i < count; ++i) {
          if (!tokens.Next(&token)) {
            return at_not_text && position > text.size()
                       ? not_text()
                       : error("the line ends inside a list of ", count);
          }
          if (!ParseFloat(token, &number)) return error("'", token, "' in a list is not a number");
        }
      }
      if (tokens.Next(&token)) return error("'", token, "' is more than the element holds");
    }
  }
  return absl::OkStatus();
}

// Reads `path` with Assimp, or, where `memory` is given, those bytes as a GLB (`path`
// then only names the file in messages).
absl::StatusOr<TriangleMesh> ReadWithAssimp(const std::string& path, std::string_view memory = {}) {
  Assimp::Importer importer;
  // Bones without geometry would otherwise come back as generated "skeleton" meshes.
  importer.SetPropertyBool(AI_CONFIG_IMPORT_NO_SKELETON_MESHES, true);
  // No post-processing at all: triangulation and welding are done below, and the steps
  // that could help (SortByPType, OptimizeMeshes, JoinIdenticalVertices, FindDegenerates,
  // PreTransformVertices) reorder or drop faces. Assimp logs nothing unless the process
  // installs an Assimp::DefaultLogger, which the library never does.
  const aiScene* scene = nullptr;
  try {
    scene = memory.empty() ? importer.ReadFile(path, 0)
                           : importer.ReadFileFromMemory(memory.data(), memory.size(), 0, "glb");
  } catch (const std::exception& e) {  // Assimp should catch its own; be sure.
    return absl::InvalidArgumentError(absl::StrCat(path, ": cannot be read: ", e.what()));
  }
  if (scene == nullptr) {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": cannot be read: ", importer.GetErrorString()));
  }

  // Meshes are placed by the node tree (glTF, FBX, COLLADA and the like position them
  // there; OBJ, PLY, OFF and STL hang them under identity nodes in file order). Walk it
  // depth first, parents before children, in the order the file lists them; a mesh used
  // by two nodes appears twice. Meshes no node uses are not part of the scene.
  MeshAssembler assembler;
  bool any_mesh_placed = false;
  struct Visit {
    const aiNode* node;
    Affine parent;
  };
  std::vector<Visit> stack;
  if (scene->mRootNode != nullptr) stack.push_back({scene->mRootNode, Affine()});
  while (!stack.empty()) {
    const Visit visit = stack.back();
    stack.pop_back();
    const Affine world = visit.parent.Then(Affine::From(visit.node->mTransformation));
    for (unsigned i = 0; i < visit.node->mNumMeshes; ++i) {
      const unsigned index = visit.node->mMeshes[i];
      if (index >= scene->mNumMeshes || scene->mMeshes[index] == nullptr) {
        return absl::InvalidArgumentError(absl::StrCat(path, ": node '", visit.node->mName.C_Str(),
                                                       "' uses missing mesh ", index));
      }
      any_mesh_placed = true;
      const aiMesh& mesh = *scene->mMeshes[index];
      if (mesh.mVertices == nullptr) continue;
      // A mirroring transform turns counter-clockwise triangles clockwise (glTF 2.0
      // 3.7.4: the sign of the determinant sets the winding); swap to undo it.
      const bool flip = world.Determinant() < 0;
      if (absl::Status status = assembler.AddPart(PartFromAssimp(mesh, world), flip);
          !status.ok()) {
        return absl::InvalidArgumentError(
            absl::StrCat(path, ": mesh '", mesh.mName.C_Str(), "': ", status.message()));
      }
    }
    // Reverse so that the first child is visited first.
    for (unsigned i = visit.node->mNumChildren; i-- > 0;) {
      if (visit.node->mChildren[i] != nullptr) stack.push_back({visit.node->mChildren[i], world});
    }
  }
  if (!any_mesh_placed) {
    // No node places anything; take the meshes as they are rather than return nothing.
    for (unsigned i = 0; i < scene->mNumMeshes; ++i) {
      const aiMesh* mesh = scene->mMeshes[i];
      if (mesh == nullptr || mesh->mVertices == nullptr) continue;
      if (absl::Status status = assembler.AddPart(PartFromAssimp(*mesh, Affine()), false);
          !status.ok()) {
        return absl::InvalidArgumentError(
            absl::StrCat(path, ": mesh '", mesh->mName.C_Str(), "': ", status.message()));
      }
    }
  }
  return std::move(assembler).Finish();
}

absl::StatusOr<TriangleMesh> ReadOffFile(const std::string& path) {
  MLCLUST_ASSIGN_OR_RETURN(const std::string text, ReadFileBytes(path));
  absl::StatusOr<PolygonPart> part = ParseOff(text);
  if (!part.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": ", part.status().message()));
  }
  MeshAssembler assembler;
  if (absl::Status status = assembler.AddPart(*part, false); !status.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": ", status.message()));
  }
  return std::move(assembler).Finish();
}

// glTF / GLB: Assimp reads them, except primitives compressed with
// KHR_draco_mesh_compression, which are decoded first (gltf_draco.h).
absl::StatusOr<TriangleMesh> ReadGltfFile(const std::string& path) {
  MLCLUST_ASSIGN_OR_RETURN(std::string bytes, ReadFileBytes(path));
  if (!GltfUsesDraco(bytes)) return ReadWithAssimp(path);
  // Relative URIs name files beside the glTF (percent-escapes are not decoded).
  const std::filesystem::path directory = std::filesystem::path(path).parent_path();
  absl::StatusOr<std::string> glb = DecompressDracoGltf(
      bytes, [&](const std::string& uri) { return ReadFileBytes((directory / uri).string()); });
  if (!glb.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": ", glb.status().message()));
  }
  std::string().swap(bytes);
  return ReadWithAssimp(path, *glb);
}

absl::StatusOr<TriangleMesh> ReadDracoFile(const std::string& path) {
  MLCLUST_ASSIGN_OR_RETURN(const std::string bytes, ReadFileBytes(path));
  absl::StatusOr<TriangleMesh> mesh = DecodeDracoMesh(bytes);
  if (!mesh.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": ", mesh.status().message()));
  }
  return mesh;
}

// ---------------------------------------------------------------------------------------
// PLY output.

void AppendUint32(std::string& out, uint32_t value) {  // Little-endian on any host.
  const char bytes[4] = {static_cast<char>(value), static_cast<char>(value >> 8),
                         static_cast<char>(value >> 16), static_cast<char>(value >> 24)};
  out.append(bytes, 4);
}

void AppendColour(std::string& out, const std::array<uint8_t, 3>& colour) {
  out.append(reinterpret_cast<const char*>(colour.data()), 3);
}

// Faces whose label is ClusterId::Invalid() (not clustered) are drawn in this grey.
constexpr std::array<uint8_t, 3> kUnlabelledColour = {128, 128, 128};

// The checks both clustered writers make: whole triples, one label per face, indices in
// range.
absl::Status CheckLabelledMesh(const TriangleMesh& mesh, std::span<const ClusterId> labels) {
  if (mesh.positions.size() % 3 != 0 || mesh.indices.size() % 3 != 0) {
    return absl::InvalidArgumentError("mesh positions and indices must hold whole triples");
  }
  if (labels.size() != mesh.num_faces()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "got ", labels.size(), " labels for ", mesh.num_faces(), " faces; one per face is needed"));
  }
  return CheckVertexIndices(mesh);
}

absl::Status WriteWholeFile(const std::string& path, const std::string& bytes) {
  std::ofstream file(path, std::ios::binary | std::ios::trunc);
  if (!file) return FileError(path, errno, "cannot open for writing");
  file.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  file.close();
  if (!file) return FileError(path, errno, "write failed");
  return absl::OkStatus();
}

// One output vertex per (vertex, cluster) pair, numbered in order of first use, so that
// a vertex on a cluster boundary carries each cluster's colour (or id) on its own copy:
// source_vertex[s] is the input vertex of copy s, out_indices the faces over the copies.
void SplitByCluster(const TriangleMesh& mesh, std::span<const ClusterId> labels,
                    std::vector<uint32_t>& source_vertex, std::vector<uint32_t>& out_indices) {
  absl::flat_hash_map<uint64_t, uint32_t> split_vertex;
  split_vertex.reserve(mesh.num_vertices() + mesh.num_vertices() / 4);
  source_vertex.clear();
  out_indices.resize(mesh.indices.size());
  for (size_t i = 0; i < mesh.indices.size(); ++i) {
    const uint64_t key = (uint64_t{mesh.indices[i]} << 32) | labels[i / 3].value();
    const auto [it, inserted] =
        split_vertex.try_emplace(key, static_cast<uint32_t>(source_vertex.size()));
    if (inserted) source_vertex.push_back(mesh.indices[i]);
    out_indices[i] = it->second;
  }
}

}  // namespace

absl::StatusOr<TriangleMesh> ReadMeshFile(const std::string& path) {
  MLCLUST_RETURN_IF_ERROR(CheckIsFile(path));
  const std::string extension = LowercaseExtension(path);
  MLCLUST_ASSIGN_OR_RETURN(const std::string head, ReadFileBytes(path, 4096));

  absl::StatusOr<TriangleMesh> mesh;
  try {
    if (extension == ".drc" || head.starts_with("DRACO")) {
      mesh = ReadDracoFile(path);
    } else if (extension == ".off" || LooksLikeOff(head)) {
      mesh = ReadOffFile(path);
    } else if (extension == ".ply" || LooksLikePly(head)) {
      MLCLUST_ASSIGN_OR_RETURN(const std::string header, ReadFileBytes(path, kMaxPlyHeaderBytes));
      std::error_code size_error;
      const uintmax_t file_size = std::filesystem::file_size(path, size_error);
      if (size_error) return FileError(path, size_error.value(), "cannot read its size");
      PlyLayout layout;
      if (absl::Status status = CheckPlyHeader(header, file_size, &layout); !status.ok()) {
        return absl::InvalidArgumentError(absl::StrCat(path, ": ", status.message()));
      }
      if (layout.ascii) {
        MLCLUST_ASSIGN_OR_RETURN(const std::string text, ReadFileBytes(path));
        const absl::string_view body = absl::string_view(text).substr(layout.body_offset);
        if (absl::Status status = CheckPlyAsciiBody(body, layout); !status.ok()) {
          return absl::InvalidArgumentError(absl::StrCat(path, ": ", status.message()));
        }
      }
      mesh = ReadWithAssimp(path);
    } else if (extension == ".gltf" || extension == ".glb" || head.starts_with("glTF")) {
      mesh = ReadGltfFile(path);
    } else {
      mesh = ReadWithAssimp(path);
    }
  } catch (const std::bad_alloc&) {
    return absl::ResourceExhaustedError(absl::StrCat(path, ": out of memory while reading"));
  }
  if (mesh.ok() && mesh->num_faces() == 0) {
    return absl::InvalidArgumentError(absl::StrCat(path, ": holds no triangles"));
  }
  return mesh;
}

absl::Status WriteClusteredPly(const std::string& path, const TriangleMesh& mesh,
                               std::span<const ClusterId> labels,
                               const ClusteredPlyOptions& options) {
  MLCLUST_RETURN_IF_ERROR(CheckLabelledMesh(mesh, labels));
  const size_t num_faces = mesh.num_faces();
  if (mesh.indices.size() > static_cast<size_t>(std::numeric_limits<int32_t>::max())) {
    return absl::InvalidArgumentError("too many faces for PLY's int vertex indices");
  }
  for (size_t f = 0; f < num_faces; ++f) {
    if (labels[f].valid() && labels[f].value() > uint32_t{std::numeric_limits<int32_t>::max()}) {
      return absl::InvalidArgumentError(absl::StrCat("face ", f, ": cluster id ", labels[f].value(),
                                                     " does not fit PLY's int property"));
    }
  }

  // Output vertices: the input's, one to one; or, for vertex colours, one per (vertex,
  // cluster) pair (SplitByCluster).
  std::vector<uint32_t> source_vertex;
  std::vector<uint32_t> out_indices;
  if (options.split_vertices) {
    SplitByCluster(mesh, labels, source_vertex, out_indices);
  } else {
    source_vertex.resize(mesh.num_vertices());
    std::iota(source_vertex.begin(), source_vertex.end(), 0u);
    out_indices = mesh.indices;
  }

  auto colour_of = [](ClusterId label) {
    return label.valid() ? ClusterColour(label.value()) : kUnlabelledColour;
  };
  const char* vertex_colour = options.split_vertices ? "property uchar red\n"
                                                       "property uchar green\n"
                                                       "property uchar blue\n"
                                                     : "";
  std::string out = absl::StrCat(
      "ply\n"
      "format binary_little_endian 1.0\n"
      "comment mlclust clusters: face property cluster (-1: unlabelled), colour per cluster\n"
      "element vertex ",
      source_vertex.size(),
      "\n"
      "property float x\n"
      "property float y\n"
      "property float z\n",
      vertex_colour, "element face ", num_faces,
      "\n"
      "property list uchar int vertex_indices\n"
      "property int cluster\n"
      "property uchar red\n"
      "property uchar green\n"
      "property uchar blue\n"
      "end_header\n");
  out.reserve(out.size() + source_vertex.size() * 15 + num_faces * 20);
  // The cluster of each split vertex: the label of the first face that used it.
  std::vector<ClusterId> split_label;
  if (options.split_vertices) {
    split_label.resize(source_vertex.size());
    for (size_t i = 0; i < out_indices.size(); ++i) split_label[out_indices[i]] = labels[i / 3];
  }
  for (size_t s = 0; s < source_vertex.size(); ++s) {
    const float* p = &mesh.positions[3 * size_t{source_vertex[s]}];
    for (int c = 0; c < 3; ++c) AppendUint32(out, std::bit_cast<uint32_t>(p[c]));
    if (options.split_vertices) AppendColour(out, colour_of(split_label[s]));
  }
  for (size_t f = 0; f < num_faces; ++f) {
    out.push_back(3);
    for (int c = 0; c < 3; ++c) AppendUint32(out, out_indices[3 * f + c]);
    // Two's complement: an unlabelled face's -1 is 0xFFFFFFFF.
    AppendUint32(out, labels[f].valid() ? labels[f].value() : ClusterId::kInvalidValue);
    AppendColour(out, colour_of(labels[f]));
  }

  return WriteWholeFile(path, out);
}

absl::Status WriteClusteredGltf(const std::string& path, const TriangleMesh& mesh,
                                std::span<const ClusterId> labels) {
  const std::string extension = LowercaseExtension(path);
  if (extension != ".glb" && extension != ".gltf") {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": a glTF file name ends in .glb or .gltf"));
  }
  MLCLUST_RETURN_IF_ERROR(CheckLabelledMesh(mesh, labels));
  const size_t num_faces = mesh.num_faces();
  if (mesh.indices.size() > std::numeric_limits<uint32_t>::max() / 4) {
    return absl::InvalidArgumentError("too many faces for one glTF buffer");
  }
  constexpr uint32_t kExactFloatIds = 1u << 24;
  for (size_t f = 0; f < num_faces; ++f) {
    if (labels[f].valid() && labels[f].value() >= kExactFloatIds) {
      return absl::InvalidArgumentError(absl::StrCat("face ", f, ": cluster id ", labels[f].value(),
                                                     " is not exact as glTF's float _CLUSTER"));
    }
  }
  std::vector<uint32_t> source_vertex, out_indices;
  SplitByCluster(mesh, labels, source_vertex, out_indices);
  std::vector<ClusterId> vertex_label(source_vertex.size());
  for (size_t i = 0; i < out_indices.size(); ++i) vertex_label[out_indices[i]] = labels[i / 3];

  // The buffer: positions, colours, cluster ids, indices; each a multiple of 4 bytes.
  const size_t num_out = source_vertex.size();
  std::string bin;
  bin.reserve(num_out * 20 + out_indices.size() * 4);
  float low[3] = {0, 0, 0}, high[3] = {0, 0, 0};
  for (size_t s = 0; s < num_out; ++s) {
    const float* p = &mesh.positions[3 * size_t{source_vertex[s]}];
    for (int c = 0; c < 3; ++c) {
      if (!std::isfinite(p[c])) {
        return absl::InvalidArgumentError(
            absl::StrCat("vertex ", source_vertex[s], " has a non-finite coordinate"));
      }
      low[c] = s == 0 ? p[c] : std::min(low[c], p[c]);
      high[c] = s == 0 ? p[c] : std::max(high[c], p[c]);
      AppendUint32(bin, std::bit_cast<uint32_t>(p[c]));
    }
  }
  const size_t colour_offset = bin.size();
  for (size_t s = 0; s < num_out; ++s) {
    AppendColour(
        bin, vertex_label[s].valid() ? ClusterColour(vertex_label[s].value()) : kUnlabelledColour);
    bin.push_back(static_cast<char>(255));
  }
  const size_t cluster_offset = bin.size();
  for (size_t s = 0; s < num_out; ++s) {
    const float id = vertex_label[s].valid() ? static_cast<float>(vertex_label[s].value()) : -1.0f;
    AppendUint32(bin, std::bit_cast<uint32_t>(id));
  }
  const size_t index_offset = bin.size();
  for (uint32_t index : out_indices) AppendUint32(bin, index);

  using Json = nlohmann::json;
  constexpr int kArrayBuffer = 34962, kElementArrayBuffer = 34963;
  auto view = [](size_t offset, size_t length, int target) {
    return Json{{"buffer", 0}, {"byteOffset", offset}, {"byteLength", length}, {"target", target}};
  };
  Json gltf = {
      {"asset", {{"version", "2.0"}, {"generator", "mlclust"}}},
      {"scene", 0},
      {"scenes", Json::array({Json{{"nodes", {0}}}})},
      {"nodes", Json::array({Json{{"mesh", 0}, {"name", "clusters"}}})},
      {"meshes",
       Json::array({Json{
           {"name", "clusters"},
           {"primitives",
            Json::array({Json{{"attributes", {{"POSITION", 0}, {"COLOR_0", 1}, {"_CLUSTER", 2}}},
                              {"indices", 3},
                              {"mode", 4}}})}}})},
      {"accessors",
       Json::array(
           {Json{{"bufferView", 0},
                 {"componentType", 5126},
                 {"count", num_out},
                 {"type", "VEC3"},
                 {"min", {low[0], low[1], low[2]}},
                 {"max", {high[0], high[1], high[2]}}},
            Json{{"bufferView", 1},
                 {"componentType", 5121},
                 {"normalized", true},
                 {"count", num_out},
                 {"type", "VEC4"}},
            Json{
                {"bufferView", 2}, {"componentType", 5126}, {"count", num_out}, {"type", "SCALAR"}},
            Json{{"bufferView", 3},
                 {"componentType", 5125},
                 {"count", out_indices.size()},
                 {"type", "SCALAR"}}})},
      {"bufferViews",
       Json::array({view(0, colour_offset, kArrayBuffer),
                    view(colour_offset, cluster_offset - colour_offset, kArrayBuffer),
                    view(cluster_offset, index_offset - cluster_offset, kArrayBuffer),
                    view(index_offset, bin.size() - index_offset, kElementArrayBuffer)})},
  };
  std::string out;
  if (extension == ".gltf") {
    gltf["buffers"] = Json::array({Json{
        {"byteLength", bin.size()},
        {"uri", absl::StrCat("data:application/octet-stream;base64,", absl::Base64Escape(bin))}}});
    out = gltf.dump(1);
  } else {
    gltf["buffers"] = Json::array({Json{{"byteLength", bin.size()}}});
    MLCLUST_ASSIGN_OR_RETURN(out, PackGlb(gltf.dump(), std::move(bin)));
  }
  return WriteWholeFile(path, out);
}

std::array<uint8_t, 3> ClusterColour(uint32_t id) {
  // Golden-ratio hue steps: id * (2^32 / phi) mod 2^32 is the fractional part of
  // id / phi in 32-bit fixed point, exact on every platform. Consecutive ids land
  // 0.382 of the circle (137.5 degrees) apart and no two hues ever coincide.
  const uint32_t hue_fixed = id * 0x9E3779B9u;
  const double hue = hue_fixed / 4294967296.0 * 6.0;  // In [0, 6): the sector and offset.
  constexpr double kSaturation = 0.65, kValue = 0.95;
  const int sector = static_cast<int>(hue);
  const double f = hue - sector;
  const double p = kValue * (1 - kSaturation);
  const double q = kValue * (1 - kSaturation * f);
  const double t = kValue * (1 - kSaturation * (1 - f));
  double rgb[3];
  switch (sector) {
    case 0:
      rgb[0] = kValue, rgb[1] = t, rgb[2] = p;
      break;
    case 1:
      rgb[0] = q, rgb[1] = kValue, rgb[2] = p;
      break;
    case 2:
      rgb[0] = p, rgb[1] = kValue, rgb[2] = t;
      break;
    case 3:
      rgb[0] = p, rgb[1] = q, rgb[2] = kValue;
      break;
    case 4:
      rgb[0] = t, rgb[1] = p, rgb[2] = kValue;
      break;
    default:
      rgb[0] = kValue, rgb[1] = p, rgb[2] = q;
      break;
  }
  std::array<uint8_t, 3> colour;
  for (int c = 0; c < 3; ++c) colour[c] = static_cast<uint8_t>(std::lround(rgb[c] * 255));
  return colour;
}

absl::Status WriteMeshFile(const std::string& path, const TriangleMesh& mesh) {
  MLCLUST_RETURN_IF_ERROR(CheckVertexIndices(mesh));
  const std::string extension = LowercaseExtension(path);
  if (extension != ".ply" && extension != ".obj" && extension != ".off") {
    return absl::InvalidArgumentError(
        absl::StrCat(path, ": cannot write '", extension, "' files (use .ply, .obj or .off)"));
  }
  std::FILE* out = std::fopen(path.c_str(), "wb");
  if (out == nullptr) return absl::UnavailableError(absl::StrCat("cannot write ", path));
  const size_t nv = mesh.num_vertices(), nf = mesh.num_faces();
  if (extension == ".ply") {
    std::fprintf(out,
                 "ply\nformat binary_little_endian 1.0\ncomment written by mlclust\n"
                 "element vertex %zu\nproperty float x\nproperty float y\nproperty float z\n"
                 "element face %zu\nproperty list uchar int vertex_indices\nend_header\n",
                 nv, nf);
    std::fwrite(mesh.positions.data(), sizeof(float), mesh.positions.size(), out);
    for (size_t f = 0; f < nf; ++f) {
      const uint8_t count = 3;
      const int32_t corners[3] = {static_cast<int32_t>(mesh.indices[3 * f]),
                                  static_cast<int32_t>(mesh.indices[3 * f + 1]),
                                  static_cast<int32_t>(mesh.indices[3 * f + 2])};
      std::fwrite(&count, 1, 1, out);
      std::fwrite(corners, sizeof(int32_t), 3, out);
    }
  } else if (extension == ".obj") {
    std::fprintf(out, "# written by mlclust: %zu vertices, %zu faces\n", nv, nf);
    for (size_t v = 0; v < nv; ++v) {
      std::fprintf(out, "v %.9g %.9g %.9g\n", mesh.positions[3 * v], mesh.positions[3 * v + 1],
                   mesh.positions[3 * v + 2]);
    }
    for (size_t f = 0; f < nf; ++f) {
      std::fprintf(out, "f %u %u %u\n", mesh.indices[3 * f] + 1, mesh.indices[3 * f + 1] + 1,
                   mesh.indices[3 * f + 2] + 1);
    }
  } else {
    std::fprintf(out, "OFF\n%zu %zu 0\n", nv, nf);
    for (size_t v = 0; v < nv; ++v) {
      std::fprintf(out, "%.9g %.9g %.9g\n", mesh.positions[3 * v], mesh.positions[3 * v + 1],
                   mesh.positions[3 * v + 2]);
    }
    for (size_t f = 0; f < nf; ++f) {
      std::fprintf(out, "3 %u %u %u\n", mesh.indices[3 * f], mesh.indices[3 * f + 1],
                   mesh.indices[3 * f + 2]);
    }
  }
  if (std::fclose(out) != 0) return absl::UnavailableError(absl::StrCat("cannot write ", path));
  return absl::OkStatus();
}

}  // namespace mlclust
