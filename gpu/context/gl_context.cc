#include "gpu/context/gl_context.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <algorithm>
#include <cassert>
#include <cstdio>
#include <cstring>
#include <mutex>
#include <optional>
#include <utility>
#include <vector>

#include "absl/strings/match.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "absl/strings/str_split.h"
#include "gpu/context/gl_functions.h"

namespace mlclust::gpu {
namespace detail {

struct EglState {
  EGLDisplay display = EGL_NO_DISPLAY;
  EGLContext context = EGL_NO_CONTEXT;
};

}  // namespace detail

namespace {

constexpr int kRequiredMajor = 4;
constexpr int kRequiredMinor = 5;

const char* EglErrorName(EGLint error) {
  switch (error) {
    case EGL_SUCCESS:
      return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED:
      return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS:
      return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC:
      return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE:
      return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONTEXT:
      return "EGL_BAD_CONTEXT";
    case EGL_BAD_CONFIG:
      return "EGL_BAD_CONFIG";
    case EGL_BAD_CURRENT_SURFACE:
      return "EGL_BAD_CURRENT_SURFACE";
    case EGL_BAD_DISPLAY:
      return "EGL_BAD_DISPLAY";
    case EGL_BAD_SURFACE:
      return "EGL_BAD_SURFACE";
    case EGL_BAD_MATCH:
      return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER:
      return "EGL_BAD_PARAMETER";
    case EGL_BAD_NATIVE_PIXMAP:
      return "EGL_BAD_NATIVE_PIXMAP";
    case EGL_BAD_NATIVE_WINDOW:
      return "EGL_BAD_NATIVE_WINDOW";
    case EGL_CONTEXT_LOST:
      return "EGL_CONTEXT_LOST";
    default:
      return "unknown EGL error";
  }
}

std::string EglError(absl::string_view what) {
  return absl::StrCat(what, " failed (", EglErrorName(eglGetError()), ")");
}

bool HasExtension(const char* extensions, absl::string_view name) {
  if (extensions == nullptr) return false;
  for (absl::string_view token : absl::StrSplit(extensions, ' ', absl::SkipEmpty())) {
    if (token == name) return true;
  }
  return false;
}

// eglInitialize and eglTerminate are not reference counted (EGL 1.5, 3.2): a display is
// one object per device per process, so terminating it under a second GlContext on the
// same device would destroy that context too. Count our own users and terminate only
// when the last one goes.
class DisplayRefCounts {
 public:
  static DisplayRefCounts& Get() {
    static DisplayRefCounts* counts = new DisplayRefCounts;
    return *counts;
  }
  bool Acquire(EGLDisplay display) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto& [d, count] : counts_) {
      if (d == display) {
        ++count;
        return eglQueryString(display, EGL_VERSION) != nullptr;
      }
    }
    if (!eglInitialize(display, nullptr, nullptr)) return false;
    counts_.emplace_back(display, 1);
    return true;
  }
  void Release(EGLDisplay display) {
    std::lock_guard<std::mutex> lock(mutex_);
    for (auto it = counts_.begin(); it != counts_.end(); ++it) {
      if (it->first != display) continue;
      if (--it->second == 0) {
        eglTerminate(display);
        counts_.erase(it);
      }
      return;
    }
  }

 private:
  std::mutex mutex_;
  std::vector<std::pair<EGLDisplay, int>> counts_;
};

bool LooksLikeSoftwareRenderer(absl::string_view renderer) {
  return absl::StrContains(renderer, "llvmpipe") || absl::StrContains(renderer, "softpipe") ||
         absl::StrContains(renderer, "swrast") ||
         absl::StrContains(renderer, "Software Rasterizer");
}

// One way to get a display: an EGL device, or the surfaceless platform.
struct Candidate {
  EGLDisplay display = EGL_NO_DISPLAY;
  std::string description;
  bool software_device = false;  // EGL_MESA_device_software
  bool hardware_device = false;  // any other EGL device
};

struct EglClient {
  PFNEGLQUERYDEVICESEXTPROC query_devices = nullptr;
  PFNEGLQUERYDEVICESTRINGEXTPROC query_device_string = nullptr;
  PFNEGLGETPLATFORMDISPLAYEXTPROC get_platform_display = nullptr;
  bool has_device_platform = false;
  bool has_surfaceless_platform = false;
};

EglClient LoadEglClient(std::vector<std::string>& notes) {
  EglClient client;
  // Client extensions are queried on EGL_NO_DISPLAY (EGL_EXT_client_extensions).
  const char* extensions = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  if (extensions == nullptr) {
    notes.push_back("EGL has no client extensions (EGL_EXT_client_extensions missing)");
    return client;
  }
  const bool platform_base = HasExtension(extensions, "EGL_EXT_platform_base");
  if (platform_base) {
    client.get_platform_display = reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(
        eglGetProcAddress("eglGetPlatformDisplayEXT"));
  } else {
    notes.push_back("EGL_EXT_platform_base missing");
  }
  if (HasExtension(extensions, "EGL_EXT_device_enumeration") ||
      HasExtension(extensions, "EGL_EXT_device_base")) {
    client.query_devices =
        reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
    client.query_device_string = reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(
        eglGetProcAddress("eglQueryDeviceStringEXT"));
  } else {
    notes.push_back("EGL_EXT_device_enumeration missing");
  }
  client.has_device_platform =
      client.get_platform_display != nullptr && HasExtension(extensions, "EGL_EXT_platform_device");
  client.has_surfaceless_platform = client.get_platform_display != nullptr &&
                                    HasExtension(extensions, "EGL_MESA_platform_surfaceless");
  return client;
}

std::string DescribeDevice(const EglClient& client, EGLDeviceEXT device, int index, int count,
                           bool software) {
  const char* extensions = client.query_device_string(device, EGL_EXTENSIONS);
  std::string description =
      absl::StrCat("EGL device ", index, " of ", count, " (", software ? "software" : "hardware");
  if (HasExtension(extensions, "EGL_EXT_device_drm")) {
    if (const char* file = client.query_device_string(device, EGL_DRM_DEVICE_FILE_EXT)) {
      absl::StrAppend(&description, ", ", file);
    }
  }
  absl::StrAppend(&description, ", extensions: ",
                  extensions != nullptr && *extensions != '\0' ? extensions : "none", ")");
  return description;
}

}  // namespace

GlContext::GlContext()
    : egl_(std::make_unique<detail::EglState>()),
      gl_(std::make_unique<detail::GlFunctions>()),
      owner_thread_(std::this_thread::get_id()) {}

GlContext::~GlContext() {
  assert(std::this_thread::get_id() == owner_thread_ &&
         "a GlContext must be destroyed on the thread that created it");
  if (egl_->context != EGL_NO_CONTEXT) {
    // Programs go with the context anyway (it shares no objects), but deleting them while
    // current keeps the order explicit and drivers' leak checkers quiet.
    if (MakeCurrent().ok()) {
      for (const auto& [name, program] : programs_) gl_->DeleteProgram(program);
      gl_->Finish();
    }
    if (eglGetCurrentContext() == egl_->context) {
      eglMakeCurrent(egl_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    }
    eglDestroyContext(egl_->display, egl_->context);
  }
  if (egl_->display != EGL_NO_DISPLAY) DisplayRefCounts::Get().Release(egl_->display);
}

absl::Status GlContext::Initialize(void* display_handle, const GlContextOptions& options) {
  const EGLDisplay display = static_cast<EGLDisplay>(display_handle);
  if (!DisplayRefCounts::Get().Acquire(display)) {
    return absl::UnavailableError(EglError("eglInitialize"));
  }
  egl_->display = display;

  const char* extensions = eglQueryString(display, EGL_EXTENSIONS);
  // No window system and no pbuffer: the context is made current with no surface at all.
  if (!HasExtension(extensions, "EGL_KHR_surfaceless_context")) {
    return absl::UnavailableError("EGL_KHR_surfaceless_context missing");
  }
  // Context version and profile attributes are EGL 1.5 core or EGL_KHR_create_context.
  int egl_major = 0, egl_minor = 0;
  const char* egl_version = eglQueryString(display, EGL_VERSION);
  if (egl_version == nullptr || std::sscanf(egl_version, "%d.%d", &egl_major, &egl_minor) != 2) {
    return absl::UnavailableError("EGL_VERSION unreadable");
  }
  if ((egl_major == 1 && egl_minor < 5) && !HasExtension(extensions, "EGL_KHR_create_context")) {
    return absl::UnavailableError(absl::StrCat("EGL ", egl_version,
                                               " without EGL_KHR_create_context cannot ask "
                                               "for an OpenGL 4.5 core context"));
  }
  if (!eglBindAPI(EGL_OPENGL_API)) {
    return absl::UnavailableError(EglError("eglBindAPI(EGL_OPENGL_API)"));
  }
  // A config only describes surfaces, which we never create; without
  // EGL_KHR_no_config_context any config that can render OpenGL will do.
  EGLConfig config = EGL_NO_CONFIG_KHR;
  if (!HasExtension(extensions, "EGL_KHR_no_config_context")) {
    const EGLint config_attributes[] = {EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint num_configs = 0;
    if (!eglChooseConfig(display, config_attributes, &config, 1, &num_configs) || num_configs < 1) {
      return absl::UnavailableError("no EGL config renders OpenGL");
    }
  }
  const EGLint context_attributes[] = {EGL_CONTEXT_MAJOR_VERSION,
                                       kRequiredMajor,
                                       EGL_CONTEXT_MINOR_VERSION,
                                       kRequiredMinor,
                                       EGL_CONTEXT_OPENGL_PROFILE_MASK,
                                       EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                                       EGL_NONE};
  egl_->context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attributes);
  if (egl_->context == EGL_NO_CONTEXT) {
    return absl::UnavailableError(EglError("eglCreateContext(OpenGL 4.5 core)"));
  }
  if (!eglMakeCurrent(display, EGL_NO_SURFACE, EGL_NO_SURFACE, egl_->context)) {
    return absl::UnavailableError(EglError("eglMakeCurrent(no surface)"));
  }

  std::vector<std::string> missing;
#define MLCLUST_GPU_LOAD_GL_FUNCTION(suffix, name)                                \
  gl_->name = reinterpret_cast<PFN##suffix##PROC>(eglGetProcAddress("gl" #name)); \
  if (gl_->name == nullptr) missing.push_back("gl" #name);
  MLCLUST_GPU_GL_FUNCTION_LIST(MLCLUST_GPU_LOAD_GL_FUNCTION)
#undef MLCLUST_GPU_LOAD_GL_FUNCTION
  if (!missing.empty()) {
    return absl::UnavailableError(
        absl::StrCat("eglGetProcAddress found no ", absl::StrJoin(missing, ", ")));
  }

  const auto gl_string = [this](GLenum name) {
    const GLubyte* value = gl_->GetString(name);
    return value == nullptr ? std::string() : std::string(reinterpret_cast<const char*>(value));
  };
  renderer_ = gl_string(GL_RENDERER);
  vendor_ = gl_string(GL_VENDOR);
  version_ = gl_string(GL_VERSION);
  GLint major = 0, minor = 0;
  gl_->GetIntegerv(GL_MAJOR_VERSION, &major);
  gl_->GetIntegerv(GL_MINOR_VERSION, &minor);
  major_version_ = major;
  minor_version_ = minor;
  if (major < kRequiredMajor || (major == kRequiredMajor && minor < kRequiredMinor)) {
    return absl::UnavailableError(
        absl::StrCat("context is OpenGL ", major, ".", minor, " ('", version_, "')"));
  }

  // Dispatch limits. GL 4.3 guarantees 65535 groups per dimension; NVIDIA allows 2^31 - 1
  // in x. The cap is for tests (see GlContextOptions).
  for (int dimension = 0; dimension < 2; ++dimension) {
    GLint groups = 0;
    gl_->GetIntegeri_v(GL_MAX_COMPUTE_WORK_GROUP_COUNT, dimension, &groups);
    max_work_groups_[dimension] = std::min<uint32_t>(static_cast<uint32_t>(std::max(groups, 1)),
                                                     options.max_groups_per_dimension);
  }
  GLint64 block_bytes = 0;
  gl_->GetInteger64v(GL_MAX_SHADER_STORAGE_BLOCK_SIZE, &block_bytes);
  // The spec minimum is 2^24 bytes; a driver reporting less is broken.
  max_storage_buffer_bytes_ = std::max<int64_t>(block_bytes, int64_t{1} << 24);
  if (options.max_storage_buffer_bytes > 0) {
    max_storage_buffer_bytes_ =
        std::min<int64_t>(max_storage_buffer_bytes_, options.max_storage_buffer_bytes);
  }
  // Memory information extensions (QueryDeviceMemory).
  GLint extension_count = 0;
  gl_->GetIntegerv(GL_NUM_EXTENSIONS, &extension_count);
  for (GLint i = 0; i < extension_count; ++i) {
    const GLubyte* name = gl_->GetStringi(GL_EXTENSIONS, static_cast<GLuint>(i));
    if (name == nullptr) continue;
    const absl::string_view extension(reinterpret_cast<const char*>(name));
    has_nvx_memory_info_ = has_nvx_memory_info_ || extension == "GL_NVX_gpu_memory_info";
    has_ati_meminfo_ = has_ati_meminfo_ || extension == "GL_ATI_meminfo";
  }
  if (const GLenum error = gl_->GetError(); error != GL_NO_ERROR) {
    return absl::UnavailableError(
        absl::StrCat("GL error 0x", absl::Hex(error), " while querying the context"));
  }
  return absl::OkStatus();
}

void GpuMemoryGauge::Add(uint64_t bytes) {
  const uint64_t now = buffer_bytes.fetch_add(bytes, std::memory_order_relaxed) + bytes;
  uint64_t peak = peak_buffer_bytes.load(std::memory_order_relaxed);
  while (now > peak &&
         !peak_buffer_bytes.compare_exchange_weak(peak, now, std::memory_order_relaxed)) {
  }
}

void GpuMemoryGauge::Remove(uint64_t bytes) {
  buffer_bytes.fetch_sub(bytes, std::memory_order_relaxed);
}

std::optional<DeviceMemory> GlContext::QueryDeviceMemory() {
  // The extensions' enums (registry: GL_NVX_gpu_memory_info, GL_ATI_meminfo); in kB.
  constexpr GLenum kNvxDedicatedVideoMemory = 0x9047;
  constexpr GLenum kNvxCurrentAvailableVideoMemory = 0x9049;
  constexpr GLenum kAtiVboFreeMemory = 0x87FB;
  if (!MakeCurrent().ok()) return std::nullopt;
  while (gl_->GetError() != GL_NO_ERROR) {
  }
  DeviceMemory memory;
  if (has_nvx_memory_info_) {
    GLint total_kb = 0, available_kb = 0;
    gl_->GetIntegerv(kNvxDedicatedVideoMemory, &total_kb);
    gl_->GetIntegerv(kNvxCurrentAvailableVideoMemory, &available_kb);
    if (gl_->GetError() == GL_NO_ERROR && total_kb > 0) {
      memory.source = "GL_NVX_gpu_memory_info";
      memory.total_bytes = uint64_t{1024} * static_cast<uint64_t>(total_kb);
      memory.available_bytes = uint64_t{1024} * static_cast<uint64_t>(std::max(available_kb, 0));
      return memory;
    }
  }
  if (has_ati_meminfo_) {
    // Free memory of the pool, the largest free block, and the same for auxiliary memory.
    GLint free_kb[4] = {0, 0, 0, 0};
    gl_->GetIntegerv(kAtiVboFreeMemory, free_kb);
    if (gl_->GetError() == GL_NO_ERROR) {
      memory.source = "GL_ATI_meminfo";
      memory.available_bytes = uint64_t{1024} * static_cast<uint64_t>(std::max(free_kb[0], 0));
      return memory;
    }
  }
  return std::nullopt;
}

absl::Status GlContext::MakeCurrent() {
  if (std::this_thread::get_id() != owner_thread_) {
    return absl::FailedPreconditionError(
        "the GL context is used on a thread other than the one that created it; GPU work "
        "must run on the context's owner thread");
  }
  // The current context is tracked per client API; another library on this thread may
  // have bound OpenGL ES.
  if (eglQueryAPI() != EGL_OPENGL_API && !eglBindAPI(EGL_OPENGL_API)) {
    return absl::InternalError(EglError("eglBindAPI(EGL_OPENGL_API)"));
  }
  if (eglGetCurrentContext() == egl_->context) return absl::OkStatus();
  if (!eglMakeCurrent(egl_->display, EGL_NO_SURFACE, EGL_NO_SURFACE, egl_->context)) {
    return absl::InternalError(EglError("eglMakeCurrent"));
  }
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<GlContext>> GlContext::Create(const GlContextOptions& options) {
  if (options.max_groups_per_dimension == 0) {
    return absl::InvalidArgumentError("GlContextOptions::max_groups_per_dimension must be >= 1");
  }
  if (options.max_storage_buffer_bytes < 0) {
    return absl::InvalidArgumentError(
        "GlContextOptions::max_storage_buffer_bytes must be >= 0 (0: the driver's limit)");
  }

  std::vector<std::string> notes;  // why each way failed, for the UNAVAILABLE message
  const EglClient client = LoadEglClient(notes);

  // Hardware devices first, then software ones, then the surfaceless platform.
  std::vector<Candidate> candidates;
  if (client.query_devices != nullptr && client.has_device_platform) {
    EGLint count = 0;
    if (!client.query_devices(0, nullptr, &count)) {
      notes.push_back(EglError("eglQueryDevicesEXT"));
      count = 0;
    }
    std::vector<EGLDeviceEXT> devices(count);
    if (count > 0 && !client.query_devices(count, devices.data(), &count)) {
      notes.push_back(EglError("eglQueryDevicesEXT"));
      count = 0;
    }
    devices.resize(count);
    if (options.device_index >= 0 && options.device_index >= count) {
      return absl::InvalidArgumentError(absl::StrCat("GlContextOptions::device_index is ",
                                                     options.device_index, " but EGL lists ", count,
                                                     " devices"));
    }
    std::vector<Candidate> hardware, software;
    for (int i = 0; i < count; ++i) {
      if (options.device_index >= 0 && i != options.device_index) continue;
      const char* extensions = client.query_device_string(devices[i], EGL_EXTENSIONS);
      Candidate candidate;
      // Mesa marks its llvmpipe device this way; NVIDIA's devices carry EGL_NV_device_cuda
      // and Mesa's DRM devices EGL_EXT_device_drm instead.
      candidate.software_device = HasExtension(extensions, "EGL_MESA_device_software");
      candidate.hardware_device = !candidate.software_device;
      candidate.description =
          DescribeDevice(client, devices[i], i, count, candidate.software_device);
      candidate.display = client.get_platform_display(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
      if (candidate.display == EGL_NO_DISPLAY) {
        notes.push_back(
            absl::StrCat(candidate.description, ": ", EglError("eglGetPlatformDisplayEXT")));
        continue;
      }
      (candidate.software_device ? software : hardware).push_back(std::move(candidate));
    }
    candidates = std::move(hardware);
    if (options.allow_software) {
      candidates.insert(candidates.end(), software.begin(), software.end());
    } else {
      for (const Candidate& c : software) {
        notes.push_back(absl::StrCat(c.description, ": skipped, allow_software is false"));
      }
    }
  } else if (options.device_index >= 0) {
    return absl::UnavailableError(
        absl::StrCat("GlContextOptions::device_index is set but EGL cannot enumerate devices: ",
                     absl::StrJoin(notes, "; ")));
  } else {
    notes.push_back("EGL_EXT_platform_device missing; no EGL devices to try");
  }
  if (options.device_index < 0 && options.allow_software && client.has_surfaceless_platform) {
    Candidate surfaceless;
    surfaceless.description = "EGL_PLATFORM_SURFACELESS_MESA";
    surfaceless.display =
        client.get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
    if (surfaceless.display != EGL_NO_DISPLAY) {
      candidates.push_back(std::move(surfaceless));
    } else {
      notes.push_back(
          absl::StrCat("EGL_PLATFORM_SURFACELESS_MESA: ", EglError("eglGetPlatformDisplayEXT")));
    }
  }

  for (const Candidate& candidate : candidates) {
    auto attempt = std::unique_ptr<GlContext>(new GlContext());
    absl::Status status = attempt->Initialize(candidate.display, options);
    if (status.ok()) {
      attempt->is_software_ =
          candidate.software_device || LooksLikeSoftwareRenderer(attempt->renderer_);
      if (attempt->is_software_ && !options.allow_software) {
        status = absl::UnavailableError(absl::StrCat("renderer '", attempt->renderer_,
                                                     "' is software and allow_software is false"));
      } else if (attempt->is_software_ && candidate.hardware_device && options.device_index < 0) {
        // Mesa falls back to kms_swrast on a DRM device it has no driver for (for
        // example an NVIDIA card seen through Mesa): llvmpipe in disguise. Keep looking;
        // the software device, listed later, gives the same renderer honestly.
        status = absl::UnavailableError(
            absl::StrCat("hardware device gave the software renderer '", attempt->renderer_, "'"));
      }
    }
    if (status.ok()) {
      attempt->device_description_ = candidate.description;
      return attempt;
    }
    notes.push_back(absl::StrCat(candidate.description, ": ", status.message()));
  }
  return absl::UnavailableError(absl::StrCat(
      "no EGL device or platform gives an OpenGL ", kRequiredMajor, ".", kRequiredMinor,
      " core context: ", notes.empty() ? "nothing to try" : absl::StrJoin(notes, "; ")));
}

}  // namespace mlclust::gpu
