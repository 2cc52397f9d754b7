// A headless OpenGL 4.5 core context for compute, created through EGL with no window
// system and no surface.
//
// Device choice (GlContext::Create): the EGL devices of EGL_EXT_device_enumeration are
// tried in order, hardware devices first (the NVIDIA device on GPU nodes), then Mesa's
// software device (llvmpipe), then the EGL_PLATFORM_SURFACELESS_MESA platform. The first
// one that yields a working 4.5 core context wins; device_description() says which.
//
// Threading: an OpenGL context is current on at most one thread, and the server runs every
// GPU job on the thread that owns the context (DESIGN.md section 5). A GlContext must be
// created, used and destroyed on one thread; MakeCurrent() (called by every kernel before
// it touches GL) returns FAILED_PRECONDITION on any other thread.
#ifndef MLCLUST_GPU_CONTEXT_GL_CONTEXT_H_
#define MLCLUST_GPU_CONTEXT_GL_CONTEXT_H_

#include <atomic>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "absl/container/flat_hash_map.h"
#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace mlclust::gpu {

namespace detail {
struct GlFunctions;
struct EglState;
}  // namespace detail

struct GlContextOptions {
  // Accept Mesa's software rasteriser (llvmpipe) when no hardware device works. With
  // false, Create() returns UNAVAILABLE on a machine without a GPU.
  bool allow_software = true;

  // Index into the EGL device list (eglQueryDevicesEXT order) to use that device and no
  // other; -1 picks automatically as described at the top of this file.
  int device_index = -1;

  // Caps the work groups of one dispatch per grid dimension, below the driver's
  // GL_MAX_COMPUTE_WORK_GROUP_COUNT. For tests: a small value forces the 2-D grid split
  // with small inputs. Must be >= 1.
  uint32_t max_groups_per_dimension = 65535;

  // Caps the bytes of one shader storage buffer, below the driver's
  // GL_MAX_SHADER_STORAGE_BLOCK_SIZE; 0 means the driver's limit. Kernels split large
  // inputs into chunks that fit. For tests (to exercise chunking with small inputs) and to
  // bound memory use on a shared GPU.
  int64_t max_storage_buffer_bytes = 0;
};

// GPU memory our buffers hold (ours, issue 12: the server's mlclust_gpu_memory_bytes): every
// StorageBuffer adds its bytes while it lives. Read from any thread; shared, so a reader
// (the metrics page) may keep it past the context.
struct GpuMemoryGauge {
  std::atomic<uint64_t> buffer_bytes{0};       // held now
  std::atomic<uint64_t> peak_buffer_bytes{0};  // the most held at once since the start
  void Add(uint64_t bytes);
  void Remove(uint64_t bytes);
};

// The device's memory as its driver reports it.
struct DeviceMemory {
  // "GL_NVX_gpu_memory_info" (NVIDIA, and Mesa's radeonsi) or "GL_ATI_meminfo" (AMD).
  std::string source;
  // The device's dedicated memory; 0 where the source does not say (GL_ATI_meminfo).
  uint64_t total_bytes = 0;
  // Free device memory now (the driver's view: other processes' use included).
  uint64_t available_bytes = 0;
};

class GlContext {
 public:
  // Creates a context and makes it current on the calling thread. Returns
  //   UNAVAILABLE when no EGL device or platform gives an OpenGL 4.5 core context (no
  //     EGL, no device extensions, only software devices with allow_software == false, ...);
  //     the message lists what was tried and why each failed. Callers fall back to CPU.
  //   INVALID_ARGUMENT for options out of range (device_index past the device list,
  //     max_groups_per_dimension == 0, negative max_storage_buffer_bytes).
  static absl::StatusOr<std::unique_ptr<GlContext>> Create(const GlContextOptions& options = {});

  // Releases every program and the context; must run on the creating thread. Buffers that
  // kernels made with this context must be gone before it.
  ~GlContext();

  GlContext(const GlContext&) = delete;
  GlContext& operator=(const GlContext&) = delete;

  // GL_RENDERER, GL_VENDOR and GL_VERSION as reported by the driver, e.g. "llvmpipe (LLVM
  // 15.0.6, 256 bits)", "Mesa", "4.5 (Core Profile) Mesa 22.3.6".
  const std::string& renderer() const { return renderer_; }
  const std::string& vendor() const { return vendor_; }
  const std::string& version() const { return version_; }
  // The context's OpenGL version (at least 4.5).
  int major_version() const { return major_version_; }
  int minor_version() const { return minor_version_; }
  // True for Mesa's software devices and renderers (llvmpipe, softpipe, swrast).
  bool is_software() const { return is_software_; }
  // Which EGL device or platform was chosen, e.g. "EGL device 1 of 2 (software,
  // extensions: EGL_MESA_device_software)" or "EGL_PLATFORM_SURFACELESS_MESA".
  const std::string& device_description() const { return device_description_; }

  // Makes this context current on the calling thread if it is not already. Returns
  // FAILED_PRECONDITION on a thread other than the creating one, INTERNAL if EGL refuses.
  absl::Status MakeCurrent();

  // Limits that kernels size their dispatches and buffers by, after the options' caps.
  // max_work_groups(d) is GL_MAX_COMPUTE_WORK_GROUP_COUNT[d] capped by
  // max_groups_per_dimension, for d = 0 (x) and 1 (y).
  uint32_t max_work_groups(int dimension) const { return max_work_groups_[dimension]; }
  // GL_MAX_SHADER_STORAGE_BLOCK_SIZE capped by max_storage_buffer_bytes.
  int64_t max_storage_buffer_bytes() const { return max_storage_buffer_bytes_; }

  // The buffers this context holds (StorageBuffer counts itself here).
  const std::shared_ptr<GpuMemoryGauge>& memory_gauge() const { return memory_gauge_; }

  // The device's total and free memory where the driver exposes them
  // (GL_NVX_gpu_memory_info, else GL_ATI_meminfo); nullopt on drivers with neither (Mesa's
  // llvmpipe: "not exposed"). Queries GL: call on the context's thread.
  std::optional<DeviceMemory> QueryDeviceMemory();

  // The GL entry points (gpu/context/gl_functions.h); for kernels in gpu/kernels/.
  const detail::GlFunctions& gl() const { return *gl_; }

  // Compiled programs by name, owned by the context and deleted with it. Kernels reach it
  // through GetComputeProgram (gpu/context/compute.h).
  absl::flat_hash_map<std::string, uint32_t>& program_cache() { return programs_; }

 private:
  GlContext();
  // Initialises EGL on `display` (an EGLDisplay), creates the context, makes it current
  // and loads the GL functions and limits. On error the destructor cleans up what exists.
  absl::Status Initialize(void* display, const GlContextOptions& options);

  std::unique_ptr<detail::EglState> egl_;
  std::unique_ptr<detail::GlFunctions> gl_;
  std::thread::id owner_thread_;
  std::string renderer_;
  std::string vendor_;
  std::string version_;
  std::string device_description_;
  int major_version_ = 0;
  int minor_version_ = 0;
  bool is_software_ = false;
  uint32_t max_work_groups_[2] = {0, 0};
  int64_t max_storage_buffer_bytes_ = 0;
  absl::flat_hash_map<std::string, uint32_t> programs_;
  std::shared_ptr<GpuMemoryGauge> memory_gauge_ = std::make_shared<GpuMemoryGauge>();
  bool has_nvx_memory_info_ = false;
  bool has_ati_meminfo_ = false;
};

}  // namespace mlclust::gpu

#endif  // MLCLUST_GPU_CONTEXT_GL_CONTEXT_H_
