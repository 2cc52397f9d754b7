#include "client/polygons.h"

#include <cmath>
#include <fstream>
#include <map>

#include "absl/strings/ascii.h"
#include "absl/strings/match.h"
#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"

namespace mlclust::client {
namespace {

// The OFF keyword, as mesh_io reads it: [ST][C][N][4][n]OFF.
bool IsOffKeyword(absl::string_view token, bool* has_dimension) {
  if (token.size() < 3 || !absl::EndsWith(token, "OFF")) return false;
  *has_dimension = token.size() >= 4 && token[token.size() - 4] == 'n';
  return true;
}

double TriangleArea(const TriangleMesh& mesh, size_t f) {
  const float* p[3];
  for (int c = 0; c < 3; ++c) p[c] = &mesh.positions[3 * size_t{mesh.indices[3 * f + c]}];
  double u[3], v[3];
  for (int i = 0; i < 3; ++i) {
    u[i] = double{p[1][i]} - p[0][i];
    v[i] = double{p[2][i]} - p[0][i];
  }
  const double x = u[1] * v[2] - u[2] * v[1];
  const double y = u[2] * v[0] - u[0] * v[2];
  const double z = u[0] * v[1] - u[1] * v[0];
  return 0.5 * std::sqrt(x * x + y * y + z * z);
}

}  // namespace

absl::StatusOr<std::vector<uint32_t>> ReadPolygonTriangleCounts(const std::string& path) {
  std::ifstream in(path);
  if (!in) return absl::NotFoundError(absl::StrCat("cannot open ", path));
  // Tokens line by line, comments and blank lines skipped.
  std::string line;
  size_t line_number = 0;
  std::vector<std::string> tokens;
  auto next_line = [&]() {
    while (std::getline(in, line)) {
      ++line_number;
      const size_t hash = line.find('#');
      if (hash != std::string::npos) line.resize(hash);
      tokens = absl::StrSplit(line, absl::ByAnyChar(" \t\r"), absl::SkipEmpty());
      if (!tokens.empty()) return true;
    }
    return false;
  };
  auto error = [&](auto&&... message) {
    return absl::InvalidArgumentError(absl::StrCat(path, " line ", line_number, ": ", message...));
  };
  if (absl::EndsWithIgnoreCase(path, ".obj")) {
    // OBJ: every "f" line is a polygon, its corners the words after "f". Assimp splits an
    // OBJ by material, so faces keep file order only with one material at most.
    std::vector<uint32_t> counts;
    int materials = 0;
    while (next_line()) {
      if (tokens[0] == "usemtl" && ++materials > 1) {
        return absl::UnimplementedError(absl::StrCat(
            "--per-polygon: ", path, " uses several materials (line ", line_number,
            "); the reader groups its faces by material, so polygons cannot be followed"));
      }
      if (tokens[0] == "f" && tokens.size() >= 4) {
        counts.push_back(static_cast<uint32_t>(tokens.size() - 1 - 2));
      }
    }
    return counts;
  }
  if (!next_line()) return error("empty file");
  bool has_dimension = false;
  size_t at = 0;
  if (IsOffKeyword(tokens[0], &has_dimension)) {
    at = 1;
  } else if (absl::EndsWithIgnoreCase(path, ".off")) {
    if (!absl::ascii_isdigit(static_cast<unsigned char>(tokens[0][0]))) {
      return error("expected the OFF keyword or the vertex count");
    }
  } else {
    return absl::UnimplementedError(absl::StrCat(
        "--per-polygon: ", path, " is neither OFF nor OBJ; only those report their polygons yet"));
  }
  std::vector<uint64_t> numbers;
  const size_t wanted = has_dimension ? 3 : 2;
  while (numbers.size() < wanted) {
    if (at == tokens.size()) {
      if (!next_line()) return error("the file ends inside the header");
      at = 0;
      continue;
    }
    uint64_t number;
    if (!absl::SimpleAtoi(tokens[at++], &number)) return error("expected a count");
    numbers.push_back(number);
  }
  const uint64_t num_vertices = numbers[wanted - 2];
  const uint64_t num_faces = numbers[wanted - 1];
  for (uint64_t v = 0; v < num_vertices; ++v) {
    if (!next_line()) return error("the file ends inside the vertices");
  }
  std::vector<uint32_t> counts;
  for (uint64_t f = 0; f < num_faces; ++f) {
    if (!next_line()) return error("the file ends inside the faces");
    uint32_t corners;
    if (!absl::SimpleAtoi(tokens[0], &corners)) return error("expected a corner count");
    if (corners >= 3) counts.push_back(corners - 2);
  }
  return counts;
}

bool ServerClustersPolygons(const std::string& algorithm) {
  return algorithm == "ml" || algorithm == "hc" || algorithm == "pml" || algorithm == "emlo" ||
         algorithm == "bb";
}

absl::StatusOr<PolygonLabels> LabelsPerPolygon(const TriangleMesh& mesh,
                                               std::span<const uint32_t> triangle_counts,
                                               std::span<const ClusterId> face_labels) {
  const size_t num_faces = mesh.num_faces();
  if (face_labels.size() != num_faces) {
    return absl::InvalidArgumentError(
        absl::StrCat("labels: ", face_labels.size(), " for ", num_faces, " faces"));
  }
  uint64_t total = 0;
  for (uint32_t count : triangle_counts) total += count;
  if (total != num_faces) {
    return absl::InvalidArgumentError(absl::StrCat("--per-polygon: the file's ",
                                                   triangle_counts.size(), " polygons make ", total,
                                                   " triangles, but the mesh has ", num_faces));
  }
  PolygonLabels result;
  result.per_polygon.reserve(triangle_counts.size());
  result.per_face.reserve(num_faces);
  size_t first = 0;
  std::map<uint32_t, double> area;  // cluster -> area of the polygon's triangles in it
  for (uint32_t count : triangle_counts) {
    area.clear();
    for (size_t f = first; f < first + count; ++f) {
      area[face_labels[f].value()] += TriangleArea(mesh, f);
    }
    // The cluster of most area; ties to the smaller id (the map's order).
    uint32_t best = area.begin()->first;
    double best_area = area.begin()->second;
    for (const auto& [cluster, a] : area) {
      if (a > best_area) {
        best = cluster;
        best_area = a;
      }
    }
    if (area.size() > 1) ++result.split_polygons;
    result.per_polygon.push_back(ClusterId(best));
    result.per_face.insert(result.per_face.end(), count, ClusterId(best));
    first += count;
  }
  return result;
}

}  // namespace mlclust::client
