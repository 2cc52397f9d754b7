// ComputeFaceMeasuresGpu (face_measures_gpu.h): the body of the compute shader, after the
// prelude of gpu/context/compute.h (#version, work group size, LinearInvocationIndex()).
// Embedded in the library at build time (gpu/kernels/CMakeLists.txt).
//
// Outputs are plain double arrays, not dvec3: std430 aligns a dvec3 array element to 32
// bytes, which would not match Vec3's 24. Every expression mirrors ComputeFaceMeasures
// (core/mesh/face_measures.cc) term by term, and `precise` forbids fusing multiply-adds or
// reordering, so a driver with IEEE doubles reproduces the CPU bit for bit.
layout(std430, binding = 0) readonly buffer Positions { float positions[]; };  // 3 per vertex
layout(std430, binding = 1) readonly buffer Indices { uint indices[]; };       // 3 per chunk face
layout(std430, binding = 2) writeonly buffer Areas { double areas[]; };        // 1 per chunk face
layout(std430, binding = 3) writeonly buffer Centroids { double centroids[]; };  // 3 per chunk face
layout(std430, binding = 4) writeonly buffer Normals { double normals[]; };    // 3 per chunk face
layout(location = 0) uniform uint u_face_count;  // faces in the chunk

dvec3 Position(uint vertex) {
  return dvec3(double(positions[3u * vertex]), double(positions[3u * vertex + 1u]),
               double(positions[3u * vertex + 2u]));
}

void main() {
  uint face = LinearInvocationIndex();
  if (face >= u_face_count) return;
  dvec3 a = Position(indices[3u * face]);
  dvec3 b = Position(indices[3u * face + 1u]);
  dvec3 c = Position(indices[3u * face + 2u]);
  // "centroid" is a GLSL keyword and cross() a built-in: hence mean and product.
  precise dvec3 u = b - a;
  precise dvec3 v = c - a;
  precise dvec3 product = dvec3(u.y * v.z - u.z * v.y, u.z * v.x - u.x * v.z, u.x * v.y - u.y * v.x);
  precise double twice_area = sqrt(product.x * product.x + product.y * product.y + product.z * product.z);
  precise dvec3 mean = (a + b + c) * (1.0LF / 3.0LF);
  // Vec3 operator/ multiplies by the reciprocal; do the same.
  precise dvec3 normal = twice_area > 0.0LF ? product * (1.0LF / twice_area) : dvec3(0.0LF);
  areas[face] = 0.5LF * twice_area;
  centroids[3u * face] = mean.x;
  centroids[3u * face + 1u] = mean.y;
  centroids[3u * face + 2u] = mean.z;
  normals[3u * face] = normal.x;
  normals[3u * face + 1u] = normal.y;
  normals[3u * face + 2u] = normal.z;
}
