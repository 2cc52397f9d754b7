// The OpenGL entry points the gpu library uses, loaded through eglGetProcAddress.
//
// Internal to gpu/: kernels reach them through GlContext::gl(). Nothing here links against
// libGL or libOpenGL; every pointer comes from EGL (EGL_KHR_get_all_proc_addresses lets
// eglGetProcAddress return core functions too), so the same binary runs on Mesa and on the
// NVIDIA EGL driver through libglvnd. To use a new GL function, add it to the list below.
#ifndef MLCLUST_GPU_CONTEXT_GL_FUNCTIONS_H_
#define MLCLUST_GPU_CONTEXT_GL_FUNCTIONS_H_

#include <GL/glcorearb.h>

namespace mlclust::gpu::detail {

// X(type suffix, name): PFN<SUFFIX>PROC is the glcorearb.h pointer type of gl<Name>.
#define MLCLUST_GPU_GL_FUNCTION_LIST(X)             \
  X(GLGETSTRING, GetString)                         \
  X(GLGETSTRINGI, GetStringi)                       \
  X(GLGETERROR, GetError)                           \
  X(GLGETINTEGERV, GetIntegerv)                     \
  X(GLGETINTEGERI_V, GetIntegeri_v)                 \
  X(GLGETINTEGER64V, GetInteger64v)                 \
  X(GLCREATESHADER, CreateShader)                   \
  X(GLSHADERSOURCE, ShaderSource)                   \
  X(GLCOMPILESHADER, CompileShader)                 \
  X(GLGETSHADERIV, GetShaderiv)                     \
  X(GLGETSHADERINFOLOG, GetShaderInfoLog)           \
  X(GLDELETESHADER, DeleteShader)                   \
  X(GLCREATEPROGRAM, CreateProgram)                 \
  X(GLATTACHSHADER, AttachShader)                   \
  X(GLDETACHSHADER, DetachShader)                   \
  X(GLLINKPROGRAM, LinkProgram)                     \
  X(GLGETPROGRAMIV, GetProgramiv)                   \
  X(GLGETPROGRAMINFOLOG, GetProgramInfoLog)         \
  X(GLDELETEPROGRAM, DeleteProgram)                 \
  X(GLUSEPROGRAM, UseProgram)                       \
  X(GLPROGRAMUNIFORM1UI, ProgramUniform1ui)         \
  X(GLCREATEBUFFERS, CreateBuffers)                 \
  X(GLNAMEDBUFFERSTORAGE, NamedBufferStorage)       \
  X(GLNAMEDBUFFERSUBDATA, NamedBufferSubData)       \
  X(GLGETNAMEDBUFFERSUBDATA, GetNamedBufferSubData) \
  X(GLDELETEBUFFERS, DeleteBuffers)                 \
  X(GLBINDBUFFERBASE, BindBufferBase)               \
  X(GLBINDBUFFERRANGE, BindBufferRange)             \
  X(GLDISPATCHCOMPUTE, DispatchCompute)             \
  X(GLMEMORYBARRIER, MemoryBarrier)                 \
  X(GLFINISH, Finish)

struct GlFunctions {
#define MLCLUST_GPU_DECLARE_GL_FUNCTION(suffix, name) PFN##suffix##PROC name = nullptr;
  MLCLUST_GPU_GL_FUNCTION_LIST(MLCLUST_GPU_DECLARE_GL_FUNCTION)
#undef MLCLUST_GPU_DECLARE_GL_FUNCTION
};

}  // namespace mlclust::gpu::detail

#endif  // MLCLUST_GPU_CONTEXT_GL_FUNCTIONS_H_
