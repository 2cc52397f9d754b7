#include "core/cluster/planar_merging.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <queue>
#include <utility>

#include "absl/container/flat_hash_map.h"
#include "absl/container/flat_hash_set.h"
#include "absl/strings/str_cat.h"
#include "core/base/cancel.h"
#include "core/base/status_macros.h"
#include "core/base/vec3.h"
#include "core/mesh/face_measures.h"

namespace mlclust {
namespace {

// The angle between two non-zero vectors in degrees, by atan2 of |a x b| and a . b, which
// stays accurate for the small angles Δ_merging is about (acos of the dot product loses
// half the digits there).
double AngleDegrees(const Vec3& a, const Vec3& b) {
  return std::atan2(Norm(Cross(a, b)), Dot(a, b)) * (180.0 / std::numbers::pi);
}

struct Candidate {
  double angle = 0;
  uint32_t a = 0, b = 0;  // dense cluster indices, a < b
  uint32_t version_a = 0, version_b = 0;
  // std::priority_queue pops the largest: smallest angle first, then the smaller pair.
  bool operator<(const Candidate& o) const {
    if (angle != o.angle) return angle > o.angle;
    if (a != o.a) return a > o.a;
    return b > o.b;
  }
};

}  // namespace

absl::StatusOr<PlanarMergingResult> MergePlanarClusters(const TriangleMesh& mesh,
                                                        std::span<const ClusterId> labels,
                                                        const PlanarMergingOptions& options) {
  MLCLUST_RETURN_IF_ERROR(ValidateMesh(mesh));
  const size_t num_faces = mesh.num_faces();
  if (labels.size() != num_faces) {
    return absl::InvalidArgumentError(absl::StrCat("'labels' holds ", labels.size(),
                                                   " labels for a mesh of ", num_faces, " faces"));
  }
  if (!(options.max_angle_degrees >= 0 && options.max_angle_degrees <= 180)) {
    return absl::InvalidArgumentError(
        absl::StrCat("'max_angle_degrees' must be in [0, 180], not ", options.max_angle_degrees));
  }
  const std::span<const double> density = options.face_density;
  if (!density.empty() && density.size() != num_faces) {
    return absl::InvalidArgumentError(absl::StrCat("'face_density' holds ", density.size(),
                                                   " values for a mesh of ", num_faces, " faces"));
  }
  for (size_t f = 0; f < density.size(); ++f) {
    if (!std::isfinite(density[f]) || density[f] < 0) {
      return absl::InvalidArgumentError(
          absl::StrCat("'face_density' of face ", f, " must be finite and >= 0, not ", density[f]));
    }
  }

  // Dense cluster slots in order of first appearance, with their labels (after merges, the
  // smallest label of the clusters merged into the slot).
  absl::flat_hash_map<uint32_t, uint32_t> dense_of;
  std::vector<uint32_t> dense(num_faces);
  std::vector<uint32_t> label_of;
  for (size_t f = 0; f < num_faces; ++f) {
    if (!labels[f].valid()) {
      return absl::InvalidArgumentError(absl::StrCat("'labels' of face ", f, " is invalid"));
    }
    auto [it, inserted] =
        dense_of.try_emplace(labels[f].value(), static_cast<uint32_t>(label_of.size()));
    if (inserted) label_of.push_back(labels[f].value());
    dense[f] = it->second;
  }
  const uint32_t k = static_cast<uint32_t>(label_of.size());

  // Eq. 3.37: the summed ρ_j A_j n_j of each cluster.
  const FaceMeasures measures = ComputeFaceMeasures(mesh);
  std::vector<Vec3> normal_sum(k);
  for (size_t f = 0; f < num_faces; ++f) {
    const double weight = measures.area[f] * (density.empty() ? 1.0 : density[f]);
    normal_sum[dense[f]] += weight * measures.unit_normal[f];
  }
  MLCLUST_ASSIGN_OR_RETURN(const FaceAdjacency adjacency, BuildFaceAdjacency(mesh));
  std::vector<absl::flat_hash_set<uint32_t>> neighbours(k);
  for (size_t f = 0; f < num_faces; ++f) {
    for (FaceId other : adjacency.neighbours[f]) {
      if (!other.valid()) continue;
      const uint32_t a = dense[f], b = dense[other.value()];
      if (a != b) neighbours[a].insert(b);
    }
  }

  // Greedy, smallest angle first; a merge bumps the survivor's version, so queued pairs
  // that name it with the old normal are skipped when they come up.
  std::vector<uint32_t> version(k, 0);
  std::vector<bool> alive(k, true);
  std::vector<uint32_t> parent(k);
  for (uint32_t c = 0; c < k; ++c) parent[c] = c;
  std::priority_queue<Candidate> queue;
  auto consider = [&](uint32_t a, uint32_t b) {
    if (a > b) std::swap(a, b);
    if (SquaredNorm(normal_sum[a]) == 0 || SquaredNorm(normal_sum[b]) == 0) return;
    const double angle = AngleDegrees(normal_sum[a], normal_sum[b]);
    if (angle < options.max_angle_degrees) queue.push({angle, a, b, version[a], version[b]});
  };
  for (uint32_t a = 0; a < k; ++a) {
    for (uint32_t b : neighbours[a]) {
      if (a < b) consider(a, b);
    }
  }

  PlanarMergingResult result;
  result.input_clusters = k;
  while (!queue.empty()) {
    const Candidate top = queue.top();
    queue.pop();
    if (!alive[top.a] || !alive[top.b] || version[top.a] != top.version_a ||
        version[top.b] != top.version_b) {
      continue;
    }
    if (result.merges.size() % 4096 == 4095) {
      MLCLUST_RETURN_IF_ERROR(CheckCancelled(
          options.cancel, absl::StrCat("planar merging, merge ", result.merges.size())));
    }
    // The merged cluster lives on in the slot with more neighbours (so that each merge
    // moves the smaller neighbour set) and carries the smaller of the two labels.
    uint32_t keep = top.a, gone = top.b;
    if (neighbours[keep].size() < neighbours[gone].size()) std::swap(keep, gone);
    const uint32_t kept_label = std::min(label_of[keep], label_of[gone]);
    const uint32_t absorbed_label = std::max(label_of[keep], label_of[gone]);
    label_of[keep] = kept_label;
    for (uint32_t n : neighbours[gone]) {
      neighbours[n].erase(gone);
      if (n != keep) {
        neighbours[n].insert(keep);
        neighbours[keep].insert(n);
      }
    }
    neighbours[keep].erase(gone);
    neighbours[gone] = {};
    normal_sum[keep] += normal_sum[gone];
    alive[gone] = false;
    parent[gone] = keep;
    ++version[keep];
    result.merges.push_back({ClusterId(kept_label), ClusterId(absorbed_label), top.angle});
    for (uint32_t n : neighbours[keep]) consider(keep, n);
  }

  // Each face takes the label of the cluster its own was merged into (path halving).
  auto find = [&](uint32_t c) {
    while (parent[c] != c) {
      parent[c] = parent[parent[c]];
      c = parent[c];
    }
    return c;
  };
  result.labels.resize(num_faces);
  for (size_t f = 0; f < num_faces; ++f) result.labels[f] = ClusterId(label_of[find(dense[f])]);
  result.output_clusters = k - static_cast<uint32_t>(result.merges.size());
  return result;
}

}  // namespace mlclust
