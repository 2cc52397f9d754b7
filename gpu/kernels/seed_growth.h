// The initial growth from seeds on the GPU (section 5.2, Fig. 5.9, l. 2172-2185): labels
// and face adjacency resident for one growth (uploaded by each call: a seeding that grows
// several times, e.g. with add-seeds, uploads them each time), one dispatch per round
// (seed_growth.glsl). In round r every
// free face with an edge-neighbour in a cluster joins the neighbouring cluster with the
// smallest id, reading the labels of round r - 1 (two label buffers, swapped each round:
// Jacobi rounds). The text ends the growth when an occlusion query counts no new face;
// here a counter of the faces assigned so far is read back after every round, and a round
// that leaves it unchanged ends it. The result equals core's SeedOptions::Growth::kRounds
// (core/cluster/mesh_clustering.h) exactly.
//
// Pass (errors and MLCLUST_GPU_FAIL_PASS): "initial growth".
//
// Memory (SeedGrowthMemoryBound): 12 bytes per face of adjacency + 2 x 4 bytes of labels
// + 4 bytes of counter: 20 n + 4 bytes, 20 MB for 10^6 faces. The adjacency is one
// buffer (neighbours reach anywhere), so 12 n bytes must fit
// context.max_storage_buffer_bytes() (RESOURCE_EXHAUSTED otherwise).
#ifndef MLCLUST_GPU_KERNELS_SEED_GROWTH_H_
#define MLCLUST_GPU_KERNELS_SEED_GROWTH_H_

#include <atomic>
#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/statusor.h"
#include "core/mesh/mesh.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

inline constexpr char kSeedGrowthPass[] = "initial growth";

struct SeedGrowthGpuResult {
  // Per face: the cluster i of seeds[i] it joined; 0xFFFFFFFF where no seed reaches it
  // (a connected component without a seed), as core's kRounds leaves it.
  std::vector<uint32_t> labels;
  uint32_t rounds = 0;  // rounds that assigned a face (the last, empty, one not counted)
};

// The bytes GrowSeedsInRoundsGpu allocates for `num_faces` faces.
uint64_t SeedGrowthMemoryBound(uint64_t num_faces);

// Grows `seeds` (distinct faces; cluster i from seeds[i]) over `adjacency` in rounds on
// `context` (current thread: its owner); distinct seeds are the caller's promise (core
// checks them: CheckSeedFaces). INVALID_ARGUMENT for a seed out of range, a neighbour id neither
// FaceId::Invalid() nor < num_faces (CheckNeighboursInRange), or more faces than
// kMaxElementsPerChunk (gpu/context/compute.h); RESOURCE_EXHAUSTED where the adjacency (12 bytes
// per face) exceeds context.max_storage_buffer_bytes() or GPU memory runs out; CANCELLED once
// `cancel` is set (checked between rounds). Errors other than CANCELLED name the pass.
absl::StatusOr<SeedGrowthGpuResult> GrowSeedsInRoundsGpu(GlContext& context,
                                                         const FaceAdjacency& adjacency,
                                                         std::span<const uint32_t> seeds,
                                                         const std::atomic<bool>* cancel = nullptr);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_KERNELS_SEED_GROWTH_H_
