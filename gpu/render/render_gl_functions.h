// The OpenGL entry points of the drawing pipeline (framebuffers, vertex arrays, draws),
// loaded through eglGetProcAddress like gpu/context/gl_functions.h and kept beside the
// renderer: compute kernels never need them. Internal to gpu/render.
#ifndef MLCLUST_GPU_RENDER_RENDER_GL_FUNCTIONS_H_
#define MLCLUST_GPU_RENDER_RENDER_GL_FUNCTIONS_H_

#include <GL/glcorearb.h>

#include "absl/status/statusor.h"

namespace mlclust::gpu::detail {

// X(type suffix, name): PFN<SUFFIX>PROC is the glcorearb.h pointer type of gl<Name>.
#define MLCLUST_GPU_RENDER_GL_FUNCTION_LIST(X)                    \
  X(GLCREATEFRAMEBUFFERS, CreateFramebuffers)                     \
  X(GLNAMEDFRAMEBUFFERRENDERBUFFER, NamedFramebufferRenderbuffer) \
  X(GLCHECKNAMEDFRAMEBUFFERSTATUS, CheckNamedFramebufferStatus)   \
  X(GLNAMEDFRAMEBUFFERDRAWBUFFER, NamedFramebufferDrawBuffer)     \
  X(GLNAMEDFRAMEBUFFERREADBUFFER, NamedFramebufferReadBuffer)     \
  X(GLBINDFRAMEBUFFER, BindFramebuffer)                           \
  X(GLDELETEFRAMEBUFFERS, DeleteFramebuffers)                     \
  X(GLCREATERENDERBUFFERS, CreateRenderbuffers)                   \
  X(GLNAMEDRENDERBUFFERSTORAGE, NamedRenderbufferStorage)         \
  X(GLDELETERENDERBUFFERS, DeleteRenderbuffers)                   \
  X(GLCREATEVERTEXARRAYS, CreateVertexArrays)                     \
  X(GLBINDVERTEXARRAY, BindVertexArray)                           \
  X(GLDELETEVERTEXARRAYS, DeleteVertexArrays)                     \
  X(GLVIEWPORT, Viewport)                                         \
  X(GLCLEARCOLOR, ClearColor)                                     \
  X(GLCLEARDEPTH, ClearDepth)                                     \
  X(GLCLEAR, Clear)                                               \
  X(GLENABLE, Enable)                                             \
  X(GLDISABLE, Disable)                                           \
  X(GLDEPTHFUNC, DepthFunc)                                       \
  X(GLDEPTHMASK, DepthMask)                                       \
  X(GLCOLORMASK, ColorMask)                                       \
  X(GLDRAWARRAYS, DrawArrays)                                     \
  X(GLREADPIXELS, ReadPixels)                                     \
  X(GLPIXELSTOREI, PixelStorei)                                   \
  X(GLPROGRAMUNIFORMMATRIX4FV, ProgramUniformMatrix4fv)           \
  X(GLPROGRAMUNIFORM3F, ProgramUniform3f)                         \
  X(GLPROGRAMUNIFORM1F, ProgramUniform1f)

struct RenderGlFunctions {
#define MLCLUST_GPU_DECLARE_RENDER_GL_FUNCTION(suffix, name) PFN##suffix##PROC name = nullptr;
  MLCLUST_GPU_RENDER_GL_FUNCTION_LIST(MLCLUST_GPU_DECLARE_RENDER_GL_FUNCTION)
#undef MLCLUST_GPU_DECLARE_RENDER_GL_FUNCTION
};

// Loads every entry point above; UNAVAILABLE naming those eglGetProcAddress does not find.
absl::StatusOr<RenderGlFunctions> LoadRenderGlFunctions();

}  // namespace mlclust::gpu::detail

#endif  // MLCLUST_GPU_RENDER_RENDER_GL_FUNCTIONS_H_
