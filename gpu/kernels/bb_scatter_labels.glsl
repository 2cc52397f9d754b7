// BoundaryDecideKernel::Decide (bb_decide.h): the labels that changed since the last sweep,
// written into the labels kept on the GPU, one invocation per change. After the prelude of
// gpu/context/compute.h.
layout(std430, binding = 1) writeonly buffer Labels { uint labels[]; };  // 1 per face
layout(std430, binding = 6) readonly buffer Changes { uvec2 changes[]; };  // (face, label)
layout(location = 0) uniform uint u_change_count;

void main() {
  uint change = LinearInvocationIndex();
  if (change >= u_change_count) return;
  labels[changes[change].x] = changes[change].y;
}
