// Building blocks for GLSL compute kernels: program compilation with the GLSL info log on
// failure, shader storage buffers sized from explicit bounds, and a 1-D launch spread over
// a 2-D grid of work groups.
//
// Every kernel in gpu/kernels/ follows one pattern: the shader (NAME.glsl, embedded at
// build time) follows kComputeShaderPrelude (GLSL 4.50, local_size_x = kLocalSize,
// LinearInvocationIndex()), reads its element count from a uniform and returns early for
// indices at or past it, because the grid is padded to whole work groups and, once split
// into rows, to whole rows.
//
// All functions expect `context` current on the calling thread (GlContext::MakeCurrent).
#ifndef MLCLUST_GPU_CONTEXT_COMPUTE_H_
#define MLCLUST_GPU_CONTEXT_COMPUTE_H_

#include <cstdint>
#include <span>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "gpu/context/gl_context.h"

namespace mlclust::gpu {

// Invocations per work group in every kernel (a multiple of NVIDIA's warp of 32 and AMD's
// wave of 64; llvmpipe runs it as 256 / SIMD width loops).
inline constexpr uint32_t kLocalSize = 256;

// The most elements a kernel hands one dispatch. Shaders index per-element arrays of up to
// four 32-bit words (3 * i, 4 * i) with uint, so this keeps every index below 2^32;
// kernels split larger inputs into chunks of at most this many (and of what fits
// MaxElementsPerBuffer).
inline constexpr uint64_t kMaxElementsPerChunk = uint64_t{1} << 28;

// Source that every compute shader begins with: the #version line, the work group size
// and
//   uint LinearInvocationIndex();  // 0, 1, 2, ... across the whole 2-D grid
inline constexpr absl::string_view kComputeShaderPrelude = R"glsl(#version 450 core
layout(local_size_x = 256, local_size_y = 1, local_size_z = 1) in;
uint LinearInvocationIndex() {
  return (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * gl_WorkGroupSize.x +
         gl_LocalInvocationID.x;
}
)glsl";

// Sets `shader`'s (made by glCreateShader) source and compiles it: OK, or INTERNAL "<what>
// shader does not compile: <the GLSL log>" with the shader deleted. Shared by the compute
// programs and the preview's drawing program.
absl::Status CompileShaderSource(const detail::GlFunctions& gl, uint32_t shader,
                                 absl::string_view source, absl::string_view what);

// After glLinkProgram: OK, or INTERNAL "<what> does not link: <the log>" with the program
// deleted.
absl::Status CheckProgramLinked(const detail::GlFunctions& gl, uint32_t program,
                                absl::string_view what);

// Compiles and links a compute program from `source`. The caller owns the returned program
// name (glDeleteProgram). INTERNAL with the GLSL compile or link log on failure.
absl::StatusOr<uint32_t> CompileComputeProgram(GlContext& context, absl::string_view source);

// Like CompileComputeProgram, but compiles once per context: the program is kept in the
// context under `name` and deleted with it. `source` must be the same for a given name.
absl::StatusOr<uint32_t> GetComputeProgram(GlContext& context, absl::string_view name,
                                           absl::string_view source);

// Work groups of a dispatch: groups_x * groups_y groups of kLocalSize invocations.
struct DispatchGrid {
  uint32_t groups_x = 0;
  uint32_t groups_y = 0;
};

// The smallest grid, one row of up to max_groups_x groups and as few rows as needed, that
// covers `invocations` (a single row when it fits). Some drivers (llvmpipe) silently drop
// a dispatch past GL_MAX_COMPUTE_WORK_GROUP_COUNT, hence the split. OUT_OF_RANGE if more
// than max_groups_y rows would be needed or the padded grid exceeds 2^32 invocations (the
// range of LinearInvocationIndex()); INVALID_ARGUMENT for a zero limit.
absl::StatusOr<DispatchGrid> PlanDispatch(uint64_t invocations, uint32_t max_groups_x,
                                          uint32_t max_groups_y);

// The most invocations one DispatchLinear can cover on this context: a full grid of
// max_work_groups(0) x max_work_groups(1) groups, capped at 2^32. Kernels bound their
// chunks by it too, so a test that caps the grid also exercises chunking.
uint64_t MaxInvocationsPerDispatch(const GlContext& context);

// Dispatches the program in use (glUseProgram) over PlanDispatch(invocations, context's
// limits). Does nothing for zero invocations.
absl::Status DispatchLinear(GlContext& context, uint64_t invocations);

// Drains glGetError. INTERNAL naming `what` and the first error, RESOURCE_EXHAUSTED for
// GL_OUT_OF_MEMORY; OK if there was none.
absl::Status CheckGlError(GlContext& context, absl::string_view what);

// How many elements of `bytes_per_element` fit one storage buffer of this context
// (GlContext::max_storage_buffer_bytes()): the bound kernels size their chunks by.
uint64_t MaxElementsPerBuffer(const GlContext& context, uint64_t bytes_per_element);

// An immutable-size shader storage buffer (glNamedBufferStorage). Owned, movable; must be
// destroyed before its context, on the context's thread. Counted in the context's
// memory_gauge() while it lives.
class StorageBuffer {
 public:
  // Allocates `bytes` (uninitialised). INVALID_ARGUMENT for bytes == 0; RESOURCE_EXHAUSTED
  // if bytes exceeds context.max_storage_buffer_bytes() or the driver is out of memory.
  static absl::StatusOr<StorageBuffer> Create(GlContext& context, uint64_t bytes);

  StorageBuffer(StorageBuffer&& other) noexcept;
  StorageBuffer& operator=(StorageBuffer&& other) noexcept;
  StorageBuffer(const StorageBuffer&) = delete;
  StorageBuffer& operator=(const StorageBuffer&) = delete;
  ~StorageBuffer();

  uint64_t bytes() const { return bytes_; }
  uint32_t id() const { return id_; }

  // Copies `size` bytes from host `data` to [offset, offset + size). OUT_OF_RANGE if that
  // range is not inside the buffer.
  absl::Status Upload(uint64_t offset, const void* data, uint64_t size);
  template <typename T>
  absl::Status Upload(std::span<const T> values, uint64_t offset = 0) {
    return Upload(offset, values.data(), values.size_bytes());
  }

  // Copies [offset, offset + size) to host `data`, after the shader writes before it
  // (issues the buffer-update memory barrier, then waits for them). OUT_OF_RANGE as Upload.
  absl::Status Download(uint64_t offset, void* data, uint64_t size);
  template <typename T>
  absl::Status Download(std::span<T> values, uint64_t offset = 0) {
    return Download(offset, values.data(), values.size_bytes());
  }

  // Binds the whole buffer to shader storage binding point `binding`.
  void Bind(uint32_t binding) const;

 private:
  StorageBuffer(GlContext* context, uint32_t id, uint64_t bytes)
      : context_(context), id_(id), bytes_(bytes) {}
  // Deletes the buffer and takes its bytes off the context's GpuMemoryGauge.
  void Release();

  GlContext* context_ = nullptr;
  uint32_t id_ = 0;
  uint64_t bytes_ = 0;
};

// One StorageBuffer per entry of `bytes`, in order (errors as StorageBuffer::Create).
absl::StatusOr<std::vector<StorageBuffer>> CreateStorageBuffers(GlContext& context,
                                                                std::span<const uint64_t> bytes);

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_CONTEXT_COMPUTE_H_
