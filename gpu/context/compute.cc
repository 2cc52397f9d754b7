#include "gpu/context/compute.h"

#include <string>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "core/base/status_macros.h"
#include "gpu/context/gl_functions.h"

namespace mlclust::gpu {
namespace {

std::string ShaderLog(const detail::GlFunctions& gl, GLuint shader) {
  GLint length = 0;
  gl.GetShaderiv(shader, GL_INFO_LOG_LENGTH, &length);
  std::string log(static_cast<size_t>(std::max(length, 1)), '\0');
  GLsizei written = 0;
  gl.GetShaderInfoLog(shader, static_cast<GLsizei>(log.size()), &written, log.data());
  log.resize(static_cast<size_t>(written));
  return log;
}

std::string ProgramLog(const detail::GlFunctions& gl, GLuint program) {
  GLint length = 0;
  gl.GetProgramiv(program, GL_INFO_LOG_LENGTH, &length);
  std::string log(static_cast<size_t>(std::max(length, 1)), '\0');
  GLsizei written = 0;
  gl.GetProgramInfoLog(program, static_cast<GLsizei>(log.size()), &written, log.data());
  log.resize(static_cast<size_t>(written));
  return log;
}

const char* GlErrorName(GLenum error) {
  switch (error) {
    case GL_INVALID_ENUM:
      return "GL_INVALID_ENUM";
    case GL_INVALID_VALUE:
      return "GL_INVALID_VALUE";
    case GL_INVALID_OPERATION:
      return "GL_INVALID_OPERATION";
    case GL_INVALID_FRAMEBUFFER_OPERATION:
      return "GL_INVALID_FRAMEBUFFER_OPERATION";
    case GL_OUT_OF_MEMORY:
      return "GL_OUT_OF_MEMORY";
    case GL_STACK_UNDERFLOW:
      return "GL_STACK_UNDERFLOW";
    case GL_STACK_OVERFLOW:
      return "GL_STACK_OVERFLOW";
    default:
      return "unknown GL error";
  }
}

}  // namespace

absl::StatusOr<uint32_t> CompileComputeProgram(GlContext& context, absl::string_view source) {
  const detail::GlFunctions& gl = context.gl();
  const GLuint shader = gl.CreateShader(GL_COMPUTE_SHADER);
  if (shader == 0) return CheckGlError(context, "glCreateShader(GL_COMPUTE_SHADER)");
  MLCLUST_RETURN_IF_ERROR(CompileShaderSource(gl, shader, source, "compute"));
  const GLuint program = gl.CreateProgram();
  gl.AttachShader(program, shader);
  gl.LinkProgram(program);
  gl.DetachShader(program, shader);
  gl.DeleteShader(shader);
  MLCLUST_RETURN_IF_ERROR(CheckProgramLinked(gl, program, "compute program"));
  return program;
}

absl::Status CompileShaderSource(const detail::GlFunctions& gl, uint32_t shader,
                                 absl::string_view source, absl::string_view what) {
  const GLchar* text = source.data();
  const GLint length = static_cast<GLint>(source.size());
  gl.ShaderSource(shader, 1, &text, &length);
  gl.CompileShader(shader);
  GLint compiled = GL_FALSE;
  gl.GetShaderiv(shader, GL_COMPILE_STATUS, &compiled);
  if (compiled == GL_TRUE) return absl::OkStatus();
  std::string log = ShaderLog(gl, shader);
  gl.DeleteShader(shader);
  return absl::InternalError(absl::StrCat(what, " shader does not compile: ", log));
}

absl::Status CheckProgramLinked(const detail::GlFunctions& gl, uint32_t program,
                                absl::string_view what) {
  GLint linked = GL_FALSE;
  gl.GetProgramiv(program, GL_LINK_STATUS, &linked);
  if (linked == GL_TRUE) return absl::OkStatus();
  std::string log = ProgramLog(gl, program);
  gl.DeleteProgram(program);
  return absl::InternalError(absl::StrCat(what, " does not link: ", log));
}

absl::StatusOr<uint32_t> GetComputeProgram(GlContext& context, absl::string_view name,
                                           absl::string_view source) {
  auto& cache = context.program_cache();
  if (auto it = cache.find(name); it != cache.end()) return it->second;
  absl::StatusOr<uint32_t> program = CompileComputeProgram(context, source);
  if (!program.ok()) {
    return absl::Status(program.status().code(),
                        absl::StrCat("kernel '", name, "': ", program.status().message()));
  }
  cache.emplace(std::string(name), *program);
  return *program;
}

absl::StatusOr<DispatchGrid> PlanDispatch(uint64_t invocations, uint32_t max_groups_x,
                                          uint32_t max_groups_y) {
  if (max_groups_x == 0 || max_groups_y == 0) {
    return absl::InvalidArgumentError("work group limits must be >= 1");
  }
  DispatchGrid grid;
  if (invocations == 0) return grid;
  const uint64_t groups = (invocations + kLocalSize - 1) / kLocalSize;
  const uint64_t groups_x = std::min<uint64_t>(groups, max_groups_x);
  const uint64_t groups_y = (groups + groups_x - 1) / groups_x;
  if (groups_y > max_groups_y) {
    return absl::OutOfRangeError(absl::StrCat(invocations, " invocations need ", groups_y,
                                              " rows of ", groups_x, " work groups; the limit is ",
                                              max_groups_y));
  }
  // LinearInvocationIndex() is a 32-bit uint; past 2^32 padded invocations it would wrap
  // and alias real elements.
  if (groups_x * groups_y * kLocalSize > (uint64_t{1} << 32)) {
    return absl::OutOfRangeError(
        absl::StrCat(invocations, " invocations exceed one dispatch's 32-bit index range"));
  }
  grid.groups_x = static_cast<uint32_t>(groups_x);
  grid.groups_y = static_cast<uint32_t>(groups_y);
  return grid;
}

uint64_t MaxInvocationsPerDispatch(const GlContext& context) {
  const uint64_t groups = uint64_t{context.max_work_groups(0)} * context.max_work_groups(1);
  return std::min(groups * kLocalSize, uint64_t{1} << 32);
}

absl::Status DispatchLinear(GlContext& context, uint64_t invocations) {
  if (invocations == 0) return absl::OkStatus();
  absl::StatusOr<DispatchGrid> grid =
      PlanDispatch(invocations, context.max_work_groups(0), context.max_work_groups(1));
  if (!grid.ok()) return grid.status();
  context.gl().DispatchCompute(grid->groups_x, grid->groups_y, 1);
  return CheckGlError(context, "glDispatchCompute");
}

absl::Status CheckGlError(GlContext& context, absl::string_view what) {
  const GLenum first = context.gl().GetError();
  if (first == GL_NO_ERROR) return absl::OkStatus();
  // Errors queue up (one flag per kind); drain them so the next check starts clean.
  for (int i = 0; i < 16 && context.gl().GetError() != GL_NO_ERROR; ++i) {
  }
  const std::string message = absl::StrCat(what, " failed: ", GlErrorName(first));
  if (first == GL_OUT_OF_MEMORY) return absl::ResourceExhaustedError(message);
  return absl::InternalError(message);
}

uint64_t MaxElementsPerBuffer(const GlContext& context, uint64_t bytes_per_element) {
  return static_cast<uint64_t>(context.max_storage_buffer_bytes()) / bytes_per_element;
}

absl::StatusOr<std::vector<StorageBuffer>> CreateStorageBuffers(GlContext& context,
                                                                std::span<const uint64_t> bytes) {
  std::vector<StorageBuffer> buffers;
  buffers.reserve(bytes.size());
  for (const uint64_t size : bytes) {
    MLCLUST_ASSIGN_OR_RETURN(StorageBuffer buffer, StorageBuffer::Create(context, size));
    buffers.push_back(std::move(buffer));
  }
  return buffers;
}

absl::StatusOr<StorageBuffer> StorageBuffer::Create(GlContext& context, uint64_t bytes) {
  if (bytes == 0) return absl::InvalidArgumentError("a storage buffer needs at least 1 byte");
  if (bytes > static_cast<uint64_t>(context.max_storage_buffer_bytes())) {
    return absl::ResourceExhaustedError(absl::StrCat("storage buffer of ", bytes,
                                                     " bytes exceeds the limit of ",
                                                     context.max_storage_buffer_bytes(), " bytes"));
  }
  const detail::GlFunctions& gl = context.gl();
  GLuint id = 0;
  gl.CreateBuffers(1, &id);
  StorageBuffer buffer(&context, id, 0);  // deletes `id` on the error paths below
  absl::Status status = CheckGlError(context, "glCreateBuffers");
  if (!status.ok()) return status;
  // Dynamic storage: uploads go through glNamedBufferSubData.
  gl.NamedBufferStorage(id, static_cast<GLsizeiptr>(bytes), nullptr, GL_DYNAMIC_STORAGE_BIT);
  status = CheckGlError(context, absl::StrCat("glNamedBufferStorage(", bytes, " bytes)"));
  if (!status.ok()) return status;
  // Allocated: counted in the context's gauge until the buffer is deleted.
  buffer.bytes_ = bytes;
  context.memory_gauge()->Add(bytes);
  return buffer;
}

StorageBuffer::StorageBuffer(StorageBuffer&& other) noexcept
    : context_(std::exchange(other.context_, nullptr)),
      id_(std::exchange(other.id_, 0)),
      bytes_(std::exchange(other.bytes_, 0)) {}

StorageBuffer& StorageBuffer::operator=(StorageBuffer&& other) noexcept {
  if (this != &other) {
    Release();
    context_ = std::exchange(other.context_, nullptr);
    id_ = std::exchange(other.id_, 0);
    bytes_ = std::exchange(other.bytes_, 0);
  }
  return *this;
}

StorageBuffer::~StorageBuffer() { Release(); }

void StorageBuffer::Release() {
  if (id_ == 0) return;
  context_->gl().DeleteBuffers(1, &id_);
  context_->memory_gauge()->Remove(bytes_);
  id_ = 0;
  bytes_ = 0;
}

absl::Status StorageBuffer::Upload(uint64_t offset, const void* data, uint64_t size) {
  if (offset > bytes_ || size > bytes_ - offset) {
    return absl::OutOfRangeError(
        absl::StrCat("upload of ", size, " bytes at ", offset, " overruns a buffer of ", bytes_));
  }
  if (size == 0) return absl::OkStatus();
  context_->gl().NamedBufferSubData(id_, static_cast<GLintptr>(offset),
                                    static_cast<GLsizeiptr>(size), data);
  return CheckGlError(*context_, "glNamedBufferSubData");
}

absl::Status StorageBuffer::Download(uint64_t offset, void* data, uint64_t size) {
  if (offset > bytes_ || size > bytes_ - offset) {
    return absl::OutOfRangeError(
        absl::StrCat("download of ", size, " bytes at ", offset, " overruns a buffer of ", bytes_));
  }
  if (size == 0) return absl::OkStatus();
  // Shader writes to storage buffers are incoherent: without this barrier a readback may
  // see stale data (GL 4.5, 7.12.2).
  context_->gl().MemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  context_->gl().GetNamedBufferSubData(id_, static_cast<GLintptr>(offset),
                                       static_cast<GLsizeiptr>(size), data);
  return CheckGlError(*context_, "glGetNamedBufferSubData");
}

void StorageBuffer::Bind(uint32_t binding) const {
  context_->gl().BindBufferBase(GL_SHADER_STORAGE_BUFFER, binding, id_);
}

}  // namespace mlclust::gpu
