#include "gpu/kernels/cluster_sums.h"

#include <algorithm>
#include <cassert>

#include "absl/strings/str_cat.h"
#include "gpu/context/compute.h"
#include "gpu/context/gl_functions.h"
#include "gpu/context/pass.h"
#include "gpu/kernels/cluster_sums_chunks_glsl.h"    // kClusterSumsChunksGlsl, generated
#include "gpu/kernels/cluster_sums_clusters_glsl.h"  // kClusterSumsClustersGlsl, generated

namespace mlclust::gpu {
namespace {

constexpr char kPass[] = "cluster sums";

uint64_t Chunks(uint64_t num_elements) {
  return (num_elements + kClusterSumsChunk - 1) / kClusterSumsChunk;
}

absl::Status CheckInputs(std::span<const double> values, uint32_t values_per_element,
                         std::span<const uint32_t> labels, uint32_t num_clusters) {
  if (values_per_element == 0 || values_per_element > kMaxValuesPerElement) {
    return absl::InvalidArgumentError(absl::StrCat("values_per_element: ", values_per_element,
                                                   " is not in [1, ", kMaxValuesPerElement, "]"));
  }
  if (values.size() != labels.size() * values_per_element) {
    return absl::InvalidArgumentError(absl::StrCat("values has ", values.size(), " entries for ",
                                                   labels.size(), " elements of ",
                                                   values_per_element, " values"));
  }
  // Shader indices (element * D, cluster * D, chunk * D) are 32-bit.
  const uint64_t limit = uint64_t{1} << 31;
  if (labels.size() >= limit || uint64_t{num_clusters} * values_per_element >= limit ||
      values.size() >= limit) {
    return absl::InvalidArgumentError(absl::StrCat(labels.size(), " elements and ", num_clusters,
                                                   " clusters exceed the 32-bit indices"));
  }
  for (size_t i = 0; i < labels.size(); ++i) {
    if (labels[i] >= num_clusters) {
      return absl::InvalidArgumentError(absl::StrCat("element ", i, " has label ", labels[i],
                                                     " but there are ", num_clusters, " clusters"));
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<double>> Run(GlContext& context, std::span<const double> values,
                                        uint32_t d, std::span<const uint32_t> labels, uint32_t k) {
  MLCLUST_RETURN_IF_ERROR(BeginPass(context, kPass));
  const uint64_t n = labels.size();
  std::vector<double> sums(size_t{k} * d, 0.0);
  if (n == 0 || k == 0) {
    MLCLUST_RETURN_IF_ERROR(CheckGlError(context, kPass));
    return sums;
  }
  // 1. Counting sort by label (stable: elements of a cluster stay in element order).
  std::vector<uint32_t> cluster_begin(size_t{k} + 1, 0);
  for (uint32_t label : labels) ++cluster_begin[label + 1];
  for (uint32_t c = 0; c < k; ++c) cluster_begin[c + 1] += cluster_begin[c];
  std::vector<uint32_t> order(n), sorted_labels(n);
  {
    std::vector<uint32_t> next(cluster_begin.begin(), cluster_begin.end() - 1);
    for (uint32_t i = 0; i < n; ++i) {
      const uint32_t at = next[labels[i]]++;
      order[at] = i;
      sorted_labels[at] = labels[i];
    }
  }

  const uint64_t chunks = Chunks(n);
  MLCLUST_ASSIGN_OR_RETURN(
      const uint32_t chunk_program,
      GetComputeProgram(context, "cluster_sums_chunks",
                        absl::StrCat(kComputeShaderPrelude, kClusterSumsChunksGlsl)));
  MLCLUST_ASSIGN_OR_RETURN(
      const uint32_t cluster_program,
      GetComputeProgram(context, "cluster_sums_clusters",
                        absl::StrCat(kComputeShaderPrelude, kClusterSumsClustersGlsl)));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer values_buffer,
                           StorageBuffer::Create(context, values.size_bytes()));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer order_buffer, StorageBuffer::Create(context, n * 4));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer sorted_buffer, StorageBuffer::Create(context, n * 4));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer begin_buffer,
                           StorageBuffer::Create(context, (uint64_t{k} + 1) * 4));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer sums_buffer,
                           StorageBuffer::Create(context, uint64_t{k} * d * 8));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer heads_buffer,
                           StorageBuffer::Create(context, chunks * d * 8));
  MLCLUST_ASSIGN_OR_RETURN(StorageBuffer tails_buffer,
                           StorageBuffer::Create(context, chunks * d * 8));
  MLCLUST_RETURN_IF_ERROR(values_buffer.Upload(values));
  MLCLUST_RETURN_IF_ERROR(order_buffer.Upload(std::span<const uint32_t>(order)));
  MLCLUST_RETURN_IF_ERROR(sorted_buffer.Upload(std::span<const uint32_t>(sorted_labels)));
  MLCLUST_RETURN_IF_ERROR(begin_buffer.Upload(std::span<const uint32_t>(cluster_begin)));

  const detail::GlFunctions& gl = context.gl();
  values_buffer.Bind(0);
  order_buffer.Bind(1);
  sorted_buffer.Bind(2);
  begin_buffer.Bind(3);
  sums_buffer.Bind(4);
  heads_buffer.Bind(5);
  tails_buffer.Bind(6);
  // 2. Chunks.
  gl.UseProgram(chunk_program);
  gl.ProgramUniform1ui(chunk_program, 0, static_cast<GLuint>(n));
  gl.ProgramUniform1ui(chunk_program, 1, d);
  MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, chunks));
  gl.MemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
  // 3. Clusters.
  gl.UseProgram(cluster_program);
  gl.ProgramUniform1ui(cluster_program, 0, k);
  gl.ProgramUniform1ui(cluster_program, 1, d);
  MLCLUST_RETURN_IF_ERROR(DispatchLinear(context, k));
  gl.UseProgram(0);
  MLCLUST_RETURN_IF_ERROR(sums_buffer.Download(std::span<double>(sums)));
  MLCLUST_RETURN_IF_ERROR(CheckGlError(context, kPass));
  return sums;
}

}  // namespace

uint64_t ClusterSumsMemoryBound(uint64_t num_elements, uint32_t values_per_element,
                                uint32_t num_clusters) {
  const uint64_t d = values_per_element;
  return num_elements * (8 * d + 8) + (uint64_t{num_clusters} + 1) * 4 +
         uint64_t{num_clusters} * d * 8 + 2 * Chunks(num_elements) * d * 8;
}

std::vector<double> SumByClusterCpu(std::span<const double> values, uint32_t values_per_element,
                                    std::span<const uint32_t> labels, uint32_t num_clusters) {
  assert(values.size() == labels.size() * values_per_element);
  std::vector<double> sums(size_t{num_clusters} * values_per_element, 0.0);
  for (size_t i = 0; i < labels.size(); ++i) {
    assert(labels[i] < num_clusters);
    for (uint32_t j = 0; j < values_per_element; ++j) {
      sums[size_t{labels[i]} * values_per_element + j] += values[i * values_per_element + j];
    }
  }
  return sums;
}

absl::StatusOr<std::vector<double>> SumByCluster(GlContext& context, std::span<const double> values,
                                                 uint32_t values_per_element,
                                                 std::span<const uint32_t> labels,
                                                 uint32_t num_clusters) {
  MLCLUST_RETURN_IF_ERROR(CheckInputs(values, values_per_element, labels, num_clusters));
  absl::StatusOr<std::vector<double>> sums =
      Run(context, values, values_per_element, labels, num_clusters);
  if (!sums.ok()) return PassError(kPass, sums.status());
  return sums;
}

}  // namespace mlclust::gpu
