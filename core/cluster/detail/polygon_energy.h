// A mesh energy over polygons (core/mesh/polygons.h): the drivers are templates over an
// energy with per-element sums and costs; this one's elements are the polygons. Every
// energy's sums are additive, so a polygon's sums are its triangles' sums added, and its
// cost against a proxy is its triangles' costs added: E(cluster) and sum FaceCost ==
// Energy hold as for triangles. Internal to core/cluster.
#ifndef MLCLUST_CORE_CLUSTER_DETAIL_POLYGON_ENERGY_H_
#define MLCLUST_CORE_CLUSTER_DETAIL_POLYGON_ENERGY_H_

#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "core/hierarchy/hierarchy.h"
#include "core/mesh/polygons.h"

namespace mlclust::detail {

template <typename TriangleEnergy>
class PolygonEnergy {
 public:
  using Sums = typename TriangleEnergy::Sums;
  using Proxy = typename TriangleEnergy::Proxy;

  // Both must outlive the energy.
  PolygonEnergy(const TriangleEnergy& triangles, const MeshPolygons& polygons)
      : triangles_(&triangles), polygons_(&polygons), sums_(polygons.num_polygons()) {
    for (size_t p = 0; p < sums_.size(); ++p) {
      for (uint32_t f = polygons.first_face[p]; f < polygons.first_face[p + 1]; ++f) {
        sums_[p] += triangles.face_sums(f);
      }
    }
  }

  const Sums& face_sums(uint32_t polygon) const { return sums_[polygon]; }
  double Energy(const Sums& sums) const { return triangles_->Energy(sums); }
  double MergeCost(const Sums& a, const Sums& b) const { return triangles_->MergeCost(a, b); }
  Proxy FitProxy(const Sums& sums) const { return triangles_->FitProxy(sums); }
  double FaceCost(uint32_t polygon, const Proxy& proxy) const {
    double cost = 0;
    for (uint32_t f = polygons_->first_face[polygon]; f < polygons_->first_face[polygon + 1]; ++f) {
      cost += triangles_->FaceCost(f, proxy);
    }
    return cost;
  }
  size_t num_faces() const { return sums_.size(); }  // polygons; the drivers' name

 private:
  const TriangleEnergy* triangles_;
  const MeshPolygons* polygons_;
  std::vector<Sums> sums_;
};

// A driver's levels over polygons, passed on over faces: a polygon's move is the move of
// each of its triangles, and cluster id p (a polygon's, as the engine numbers clusters by
// their first element) becomes the id of polygon p's first face, so that cluster ids
// stay face ids as for a run on triangles.
class PolygonLevelSink : public LevelSink {
 public:
  // Both must outlive the sink.
  PolygonLevelSink(const MeshPolygons& polygons, LevelSink& faces)
      : polygons_(polygons), faces_(faces) {}

  absl::Status OnStart(std::span<const ClusterId> labels, uint32_t cluster_count,
                       double energy) override {
    std::vector<ClusterId> face_labels(polygons_.num_faces());
    for (size_t f = 0; f < face_labels.size(); ++f) {
      face_labels[f] = FaceCluster(labels[polygons_.polygon_of_face[f]].value());
    }
    return faces_.OnStart(face_labels, cluster_count, energy);
  }

  absl::Status OnLevel(const LevelMoves& level) override {
    element_.clear();
    to_.clear();
    from_.clear();
    for (size_t i = 0; i < level.element.size(); ++i) {
      const uint32_t p = level.element[i];
      for (uint32_t f = polygons_.first_face[p]; f < polygons_.first_face[p + 1]; ++f) {
        element_.push_back(f);
        to_.push_back(FaceCluster(level.to_cluster[i]).value());
        from_.push_back(FaceCluster(level.from_cluster[i]).value());
      }
    }
    LevelMoves faces = level;
    faces.element = element_;
    faces.to_cluster = to_;
    faces.from_cluster = from_;
    return faces_.OnLevel(faces);
  }

 private:
  ClusterId FaceCluster(uint32_t polygon) const { return ClusterId(polygons_.first_face[polygon]); }

  const MeshPolygons& polygons_;
  LevelSink& faces_;
  std::vector<uint32_t> element_, to_, from_;
};

}  // namespace mlclust::detail

#endif  // MLCLUST_CORE_CLUSTER_DETAIL_POLYGON_ENERGY_H_
