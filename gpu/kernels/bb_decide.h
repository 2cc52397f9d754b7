// The decide stage of boundary-based optimisation (Alg. 5.1; the GPU passes of Alg.
// 5.4/5.5) as a compute kernel: for every face, the neighbouring cluster whose proxy fits
// it better, with the rule of DecideBoundaryMove (core/cluster/boundary_based.h). It
// plugs into RunBoundaryBased as its Decide; fitting proxies, the conflict rule and
// applying the moves stay the CPU's, so the GPU and CPU drivers cannot drift apart.
//
// Energies: those whose FaceCost has the "proxy point" form
//   FaceCost(f, proxy) = (weight(proxy) * mass_f) * |point_f - point(proxy)|^2,
// described by ProxyPointForm<Energy>: CVD and adaptive CVD (point: the centroid, weight
// 1), MWCVD (centroid, cluster weight w_i) and planar L2,1 (unit normal, weight 1). The
// sphere energies have other proxies and no GPU decide yet.
//
// Precision: costs in fp64 with the CPU's operations in the CPU's order (the shader marks
// them `precise`, so no fused multiply-add), so on a driver with IEEE fp64 (llvmpipe) the
// targets equal the CPU's; elsewhere a target can differ only where two costs tie to
// rounding.
//
// Data stay on the GPU across sweeps: adjacency (12 bytes per face), the faces' points (32
// bytes per face) and the labels are uploaded once; each later sweep uploads only the labels
// that changed (8 bytes per change; all labels again when more than an eighth of the faces
// changed) and the proxies (32 bytes per cluster), and reads back only the proposals (8
// bytes per face that wants to move, compacted on the GPU by an atomic counter).
#ifndef MLCLUST_GPU_KERNELS_BB_DECIDE_H_
#define MLCLUST_GPU_KERNELS_BB_DECIDE_H_

#include <array>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/base/status_macros.h"
#include "core/energy/energies.h"
#include "core/mesh/mesh.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// (x, y, z, w): a face's point and mass, or a proxy's point and weight.
using PointAndWeight = std::array<double, 4>;

// How an energy's FaceCost reads as the proxy-point form above; specialised below for the
// energies that have it.
template <typename Energy>
struct ProxyPointForm;

template <>
struct ProxyPointForm<CvdEnergy> {
  static PointAndWeight Face(const CvdEnergy& energy, uint32_t face) {
    const CvdSums& s = energy.face_sums(face);
    if (s.area <= 0) return {0, 0, 0, 0};  // FaceCost is 0
    const Vec3 point = s.weighted_centroid / s.area;
    return {point.x, point.y, point.z, s.area};
  }
  static PointAndWeight Proxy(const CvdEnergy::Proxy& proxy) {
    return {proxy.x, proxy.y, proxy.z, 1.0};
  }
};

template <>
struct ProxyPointForm<MwcvdEnergy> {
  static PointAndWeight Face(const MwcvdEnergy& energy, uint32_t face) {
    const CvdSums& s = energy.face_sums(face).cvd;
    if (s.area <= 0) return {0, 0, 0, 0};
    const Vec3 point = s.weighted_centroid / s.area;
    return {point.x, point.y, point.z, s.area};
  }
  static PointAndWeight Proxy(const MwcvdEnergy::Proxy& proxy) {
    return {proxy.centroid.x, proxy.centroid.y, proxy.centroid.z, proxy.weight};
  }
};

template <>
struct ProxyPointForm<PlanarEnergy> {
  static PointAndWeight Face(const PlanarEnergy& energy, uint32_t face) {
    const PlanarEnergy::Sums& s = energy.face_sums(face);
    if (s.area <= 0) return {0, 0, 0, 0};
    const Vec3 point = s.weighted_normal / s.area;
    return {point.x, point.y, point.z, s.area};
  }
  static PointAndWeight Proxy(const PlanarEnergy::Proxy& proxy) {
    return {proxy.x, proxy.y, proxy.z, 1.0};
  }
};

// Whether Energy has a GPU decide stage.
template <typename Energy>
inline constexpr bool kHasGpuDecide = requires(const Energy& e) {
  ProxyPointForm<Energy>::Face(e, 0u);
};

// The kernel, for one mesh and one number of clusters. Owns its GPU buffers; use and
// destroy it on the context's thread, before the context.
class BoundaryDecideKernel {
 public:
  // Uploads the adjacency and the faces' points (faces.size() == adjacency.num_faces()).
  // Returns INVALID_ARGUMENT for a size mismatch, a neighbour out of range or more than
  // kMaxMeshElements faces; RESOURCE_EXHAUSTED if a buffer (BoundaryDecideMemoryBound)
  // exceeds context.max_storage_buffer_bytes() or GPU memory runs out; INTERNAL on GL
  // errors. Errors name the pass "bb decide".
  static absl::StatusOr<BoundaryDecideKernel> Create(GlContext& context,
                                                     const FaceAdjacency& adjacency,
                                                     std::span<const PointAndWeight> faces,
                                                     uint32_t num_clusters);

  // target[f] for every face (boundary_based::kNoMove: stays). labels: one per face, each
  // < num_clusters (the partition's; not checked); proxies: num_clusters. INVALID_ARGUMENT
  // for sizes that do not match; GL errors as Create. After an error the kernel uploads
  // every label again at the next call.
  absl::Status Decide(std::span<const uint32_t> labels, std::span<const PointAndWeight> proxies,
                      std::span<uint32_t> target);

 private:
  // The buffers, by binding point of bb_decide.glsl / bb_scatter_labels.glsl.
  enum Binding : uint32_t {
    kNeighbours,
    kLabels,
    kFaces,
    kProxies,
    kProposals,
    kProposalCount,
    kChanges,
    kBindings
  };

  BoundaryDecideKernel(GlContext& context, uint32_t num_faces, uint32_t num_clusters,
                       std::vector<StorageBuffer> buffers)
      : context_(&context),
        num_faces_(num_faces),
        num_clusters_(num_clusters),
        buffers_(std::move(buffers)) {}

  // Brings the labels on the GPU to `labels` (the changes, or all of them).
  absl::Status UpdateLabels(std::span<const uint32_t> labels);

  GlContext* context_;
  uint32_t num_faces_;
  uint32_t num_clusters_;
  std::vector<StorageBuffer> buffers_;
  std::vector<uint32_t> labels_on_gpu_;  // empty: unknown, upload all
  std::vector<std::array<uint32_t, 2>> changes_, proposals_;
};

// bb_decide.glsl's buffers, by its bindings 0-5.
struct BoundaryDecideBuffers {
  StorageBuffer* neighbours;  // 3 per face
  StorageBuffer* labels;      // 1 per face
  StorageBuffer* faces;       // point and mass per face
  StorageBuffer* proxies;     // point and weight per cluster id
  StorageBuffer* proposals;   // (face, cluster), one per face at most
  StorageBuffer* count;       // the proposals' count
};

// One decide over `num_faces` faces (shared by BoundaryDecideKernel and PmlLevelsGpu's "pml
// bb decide"): the count zeroed, bb_decide.glsl dispatched on `buffers`, the count and as
// many (face, cluster) proposals read back, then the GL error check of `pass`; INTERNAL
// where the count exceeds num_faces or a face or cluster is out of range.
absl::Status DispatchBoundaryDecide(GlContext& context, const char* pass,
                                    const BoundaryDecideBuffers& buffers, uint32_t num_faces,
                                    uint32_t num_clusters,
                                    std::vector<std::array<uint32_t, 2>>& proposals);

// Changed labels a sweep uploads as (face, label) pairs at most; more, and all labels go.
inline uint64_t BoundaryDecideMaxChanges(uint64_t num_faces) { return num_faces / 8 + 1; }

// The GPU memory BoundaryDecideKernel holds: 61 bytes per face (adjacency 12, labels 4,
// points 32, proposals 8, changes 1), 32 per cluster, and a few bytes.
uint64_t BoundaryDecideMemoryBound(uint64_t num_faces, uint64_t num_clusters);

// The decide stage for Energy on the GPU, in the shape RunBoundaryBased calls:
//   absl::Status operator()(labels, proxies, target)
template <typename Energy>
class GpuBoundaryDecider {
 public:
  static absl::StatusOr<GpuBoundaryDecider> Create(GlContext& context, const Energy& energy,
                                                   const FaceAdjacency& adjacency,
                                                   uint32_t num_clusters) {
    std::vector<PointAndWeight> faces(adjacency.num_faces());
    for (uint32_t f = 0; f < faces.size(); ++f) faces[f] = ProxyPointForm<Energy>::Face(energy, f);
    MLCLUST_ASSIGN_OR_RETURN(BoundaryDecideKernel kernel,
                             BoundaryDecideKernel::Create(context, adjacency, faces, num_clusters));
    return GpuBoundaryDecider(std::move(kernel));
  }

  absl::Status operator()(std::span<const uint32_t> labels,
                          std::span<const typename Energy::Proxy> proxies,
                          std::span<uint32_t> target) {
    points_.resize(proxies.size());
    for (size_t c = 0; c < proxies.size(); ++c) {
      points_[c] = ProxyPointForm<Energy>::Proxy(proxies[c]);
    }
    return kernel_.Decide(labels, points_, target);
  }

 private:
  explicit GpuBoundaryDecider(BoundaryDecideKernel kernel) : kernel_(std::move(kernel)) {}
  BoundaryDecideKernel kernel_;
  std::vector<PointAndWeight> points_;
};

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_KERNELS_BB_DECIDE_H_
