// Moved to gpu/kernels/face_measures_gpu.h; this forward stays until server/ includes the
// new path.
#ifndef MLCLUST_GPU_FACE_MEASURES_GPU_H_
#define MLCLUST_GPU_FACE_MEASURES_GPU_H_

#include "gpu/kernels/face_measures_gpu.h"

#endif  // MLCLUST_GPU_FACE_MEASURES_GPU_H_
