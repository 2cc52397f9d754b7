// Moved to gpu/context/gl_context.h; this forward stays until server/ includes the new path.
#ifndef MLCLUST_GPU_GL_CONTEXT_H_
#define MLCLUST_GPU_GL_CONTEXT_H_

#include "gpu/context/gl_context.h"

#endif  // MLCLUST_GPU_GL_CONTEXT_H_
