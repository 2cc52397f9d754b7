// A face clustering with its cluster sums: the state every driver works on.
#ifndef MLCLUST_CORE_CLUSTER_PARTITION_H_
#define MLCLUST_CORE_CLUSTER_PARTITION_H_

#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

#include "core/base/ids.h"

namespace mlclust {

// Labels (one cluster id per face) plus, per cluster id, the energy's sums, the face count
// and the cluster's energy. Cluster ids are indices below capacity(); a cluster with no
// faces is empty, not an error. Moving a face updates both clusters in O(1).
//
// Exact sums (issue 26 item 7): adding a face's sums rounds like any sum of the cluster's
// faces, but removing one subtracts, and what the subtraction cancels is lost: mwcvd-max's
// sum of rho^10 spans some 40 orders of magnitude on a mesh with flat regions (power density),
// so a flat cluster that gave away an edge face keeps a residue of the edge's rho^10 (or 0) in
// place of its own sum, and its weight and energy drift. RefreshAllSums() recomputes every
// cluster's sums from the labels, so that a driver reports the energy its labels have; the
// multilevel engine keeps exact sums of its own for the levels (core/cluster/multilevel.cc).
template <typename Energy>
class Partition {
 public:
  using Sums = typename Energy::Sums;

  // `labels` values must be below `capacity`.
  Partition(const Energy& energy, std::span<const uint32_t> labels, uint32_t capacity)
      : energy_(&energy),
        labels_(labels.begin(), labels.end()),
        sums_(capacity),
        sizes_(capacity, 0),
        cluster_energy_(capacity, 0.0) {
    for (size_t f = 0; f < labels_.size(); ++f) {
      sums_[labels_[f]] += energy.face_sums(static_cast<uint32_t>(f));
      ++sizes_[labels_[f]];
    }
    for (uint32_t c = 0; c < capacity; ++c) {
      if (sizes_[c] > 0) {
        cluster_energy_[c] = energy.Energy(sums_[c]);
        ++num_clusters_;
      }
    }
  }

  uint32_t label(uint32_t face) const { return labels_[face]; }
  std::span<const uint32_t> labels() const { return labels_; }
  const Sums& sums(uint32_t cluster) const { return sums_[cluster]; }
  uint32_t size(uint32_t cluster) const { return sizes_[cluster]; }
  std::span<const uint32_t> sizes() const { return sizes_; }
  double cluster_energy(uint32_t cluster) const { return cluster_energy_[cluster]; }
  uint32_t capacity() const { return static_cast<uint32_t>(sums_.size()); }
  uint32_t num_clusters() const { return num_clusters_; }
  const Energy& energy() const { return *energy_; }

  // Sum of the cluster energies, recomputed (O(capacity)).
  double TotalEnergy() const {
    double total = 0;
    for (uint32_t c = 0; c < capacity(); ++c) total += cluster_energy_[c];
    return total;
  }

  // Recomputes every cluster's sums and energy from the labels: a single-level driver's last
  // step before it reports its energy. O(faces + capacity).
  void RefreshAllSums() {
    std::fill(sums_.begin(), sums_.end(), Sums());
    for (size_t f = 0; f < labels_.size(); ++f) {
      sums_[labels_[f]] += energy_->face_sums(static_cast<uint32_t>(f));
    }
    for (uint32_t c = 0; c < capacity(); ++c) {
      cluster_energy_[c] = sizes_[c] > 0 ? energy_->Energy(sums_[c]) : 0.0;
    }
  }

  // Moves `face` to cluster `to`, updating sums, sizes and the two cluster energies.
  void Move(uint32_t face, uint32_t to) {
    const uint32_t from = labels_[face];
    const Sums& face_sums = energy_->face_sums(face);
    sums_[from] -= face_sums;
    sums_[to] += face_sums;
    if (--sizes_[from] == 0) {
      sums_[from] = Sums();  // no rounding residue in an empty cluster
      --num_clusters_;
    }
    if (sizes_[to]++ == 0) ++num_clusters_;
    cluster_energy_[from] = sizes_[from] > 0 ? energy_->Energy(sums_[from]) : 0.0;
    cluster_energy_[to] = energy_->Energy(sums_[to]);
    labels_[face] = to;
  }

  // Moves every face of cluster `gone` into `keep` at once (a merge): O(1) in the sums,
  // O(faces moved) in the labels, which the caller passes.
  void Merge(uint32_t keep, uint32_t gone, std::span<const uint32_t> faces_of_gone) {
    MergeUncounted(keep, gone, faces_of_gone);
    --num_clusters_;
  }
  // Merge for many disjoint pairs at once (PML): MergeUncounted may run for different pairs
  // in parallel (it writes only the two clusters and the faces passed); then
  // CountMerges(number of pairs) once.
  void MergeUncounted(uint32_t keep, uint32_t gone, std::span<const uint32_t> faces_of_gone) {
    sums_[keep] += sums_[gone];
    sizes_[keep] += sizes_[gone];
    sums_[gone] = Sums();
    sizes_[gone] = 0;
    cluster_energy_[keep] = energy_->Energy(sums_[keep]);
    cluster_energy_[gone] = 0;
    for (uint32_t f : faces_of_gone) labels_[f] = keep;
  }
  void CountMerges(uint32_t merges) { num_clusters_ -= merges; }

 private:
  const Energy* energy_;
  std::vector<uint32_t> labels_;
  std::vector<Sums> sums_;
  std::vector<uint32_t> sizes_;
  std::vector<double> cluster_energy_;
  uint32_t num_clusters_ = 0;
};

}  // namespace mlclust

#endif  // MLCLUST_CORE_CLUSTER_PARTITION_H_
