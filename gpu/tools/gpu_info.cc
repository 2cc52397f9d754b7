// mlclust-gpu-info: which EGL device and OpenGL driver the gpu library picks here, and how
// long its kernels take against the CPU on a generated 1M-face grid.
//
//   mlclust-gpu-info [--no-software] [--device=N] [--rows=N] [--repeats=N]
//
// Each kernel is run once to warm up (shader compile) and then `repeats` times; the
// minimum is reported, for GPU (upload + dispatch + readback) and CPU alike.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <string_view>

#include "core/mesh/face_measures.h"
#include "core/mesh/mesh.h"
#include "gpu/context/gl_context.h"
#include "gpu/kernels/boundary_faces.h"
#include "gpu/kernels/face_measures_gpu.h"
#include "gpu/tools/test_meshes.h"

namespace mlclust::gpu {
namespace {

double MinSeconds(int repeats, const std::function<bool()>& run) {
  double best = 1e300;
  for (int i = 0; i < repeats; ++i) {
    const auto start = std::chrono::steady_clock::now();
    if (!run()) return -1;
    const std::chrono::duration<double> elapsed = std::chrono::steady_clock::now() - start;
    best = std::min(best, elapsed.count());
  }
  return best;
}

int Main(int argc, char** argv) {
  GlContextOptions options;
  uint32_t rows = 708;  // 2 * 708 * 708 = 1,002,528 faces
  int repeats = 5;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (arg == "--no-software") {
      options.allow_software = false;
    } else if (arg.starts_with("--device=")) {
      options.device_index = std::atoi(argv[i] + 9);
    } else if (arg.starts_with("--rows=")) {
      rows = static_cast<uint32_t>(std::max(1, std::atoi(argv[i] + 7)));
    } else if (arg.starts_with("--repeats=")) {
      repeats = std::max(1, std::atoi(argv[i] + 10));
    } else {
      std::fprintf(stderr, "usage: %s [--no-software] [--device=N] [--rows=N] [--repeats=N]\n",
                   argv[0]);
      return 2;
    }
  }

  absl::StatusOr<std::unique_ptr<GlContext>> context = GlContext::Create(options);
  if (!context.ok()) {
    std::fprintf(stderr, "no GL context: %s\n", context.status().ToString().c_str());
    return 1;
  }
  GlContext& gl = **context;
  std::printf("device:    %s\n", gl.device_description().c_str());
  std::printf("vendor:    %s\n", gl.vendor().c_str());
  std::printf("renderer:  %s%s\n", gl.renderer().c_str(), gl.is_software() ? " (software)" : "");
  std::printf("version:   %s\n", gl.version().c_str());
  std::printf("limits:    %u x %u work groups, %lld-byte storage buffers\n", gl.max_work_groups(0),
              gl.max_work_groups(1), static_cast<long long>(gl.max_storage_buffer_bytes()));

  const TriangleMesh mesh = testing::MakeJitteredGrid(rows, rows, 0.3f);
  absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(mesh);
  if (!adjacency.ok()) {
    std::fprintf(stderr, "adjacency: %s\n", adjacency.status().ToString().c_str());
    return 1;
  }
  const std::vector<ClusterId> labels = testing::GridBlockLabels(rows, rows, 16);
  std::printf("mesh:      %zu faces, %zu vertices (jittered grid), labels in 16x16 blocks\n",
              mesh.num_faces(), mesh.num_vertices());

  // Warm-up runs compile the shaders and check the results before anything is timed.
  absl::StatusOr<std::vector<uint8_t>> flags = FlagBoundaryFaces(gl, *adjacency, labels);
  absl::StatusOr<FaceMeasures> measures = ComputeFaceMeasuresGpu(gl, mesh);
  if (!flags.ok() || !measures.ok()) {
    std::fprintf(stderr, "kernel failed: %s %s\n", flags.status().ToString().c_str(),
                 measures.status().ToString().c_str());
    return 1;
  }
  const bool flags_match = *flags == FlagBoundaryFacesCpu(*adjacency, labels);
  const FaceMeasures cpu = ComputeFaceMeasures(mesh);
  const bool measures_match = measures->area == cpu.area &&
                              std::memcmp(measures->centroid.data(), cpu.centroid.data(),
                                          cpu.centroid.size() * sizeof(Vec3)) == 0 &&
                              std::memcmp(measures->unit_normal.data(), cpu.unit_normal.data(),
                                          cpu.unit_normal.size() * sizeof(Vec3)) == 0;

  const double boundary_gpu =
      MinSeconds(repeats, [&] { return FlagBoundaryFaces(gl, *adjacency, labels).ok(); });
  const double boundary_cpu =
      MinSeconds(repeats, [&] { return !FlagBoundaryFacesCpu(*adjacency, labels).empty(); });
  const double measures_gpu =
      MinSeconds(repeats, [&] { return ComputeFaceMeasuresGpu(gl, mesh).ok(); });
  const double measures_cpu =
      MinSeconds(repeats, [&] { return ComputeFaceMeasures(mesh).num_faces() > 0; });

  std::printf("%-22s %10s %10s  %s\n", "kernel (min of runs)", "GPU ms", "CPU ms", "GPU == CPU");
  std::printf("%-22s %10.2f %10.2f  %s\n", "FlagBoundaryFaces", 1e3 * boundary_gpu,
              1e3 * boundary_cpu, flags_match ? "identical" : "DIFFERENT");
  std::printf("%-22s %10.2f %10.2f  %s\n", "ComputeFaceMeasures", 1e3 * measures_gpu,
              1e3 * measures_cpu, measures_match ? "bit-identical" : "differs (see tests)");
  return flags_match ? 0 : 1;
}

}  // namespace
}  // namespace mlclust::gpu

int main(int argc, char** argv) { return mlclust::gpu::Main(argc, argv); }
