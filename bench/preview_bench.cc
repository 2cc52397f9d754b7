// Times the preview's steps (gpu/render/cluster_preview.h) on a mesh and a labelling:
// colouring, the GL draw and read-back (the first one with the shader compilation, then the
// median of the repeats), and the PNG encoding.
//   preview_bench MESH LABELS [WIDTHxHEIGHT] [REPEATS]
// LABELS: one cluster per line per face, as `mlclust mesh ... --labels` writes.
#include <algorithm>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "bench/bench_util.h"
#include "core/io/mesh_io.h"
#include "core/mesh/mesh.h"
#include "gpu/context/gl_context.h"
#include "gpu/render/cluster_preview.h"
#include "gpu/render/png_codec.h"

namespace {

int Fail(const std::string& what) {
  std::fprintf(stderr, "preview_bench: %s\n", what.c_str());
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace mlclust;  // NOLINT(google-build-using-namespace): a benchmark's main
  bench::Args args(argc, argv, "usage: preview_bench MESH LABELS [WIDTHxHEIGHT] [REPEATS]");
  const std::string mesh_path = args.Positional(0);
  const std::string labels_path = args.Positional(1);
  const std::string size = args.Positional(2, std::string());
  const int repeats = args.Positional<int>(3, 5);
  if (!args.Done()) return 1;
  gpu::ClusterPreviewOptions options;
  if (!size.empty()) {
    const size_t x = size.find('x');
    if (x == std::string::npos || !absl::SimpleAtoi(size.substr(0, x), &options.width) ||
        !absl::SimpleAtoi(size.substr(x + 1), &options.height)) {
      return Fail("size: give WIDTHxHEIGHT");
    }
  }
  if (repeats < 1) return Fail("repeats: give a positive integer");
  absl::StatusOr<TriangleMesh> mesh = ReadMeshFile(mesh_path);
  if (!mesh.ok()) return Fail(std::string(mesh.status().message()));
  absl::StatusOr<FaceAdjacency> adjacency = BuildFaceAdjacency(*mesh);
  if (!adjacency.ok()) return Fail(std::string(adjacency.status().message()));
  std::vector<ClusterId> labels;
  std::ifstream in(labels_path);
  for (uint32_t label; in >> label;) labels.push_back(ClusterId(label));

  bench::Stopwatch watch;
  absl::StatusOr<std::unique_ptr<gpu::GlContext>> context = gpu::GlContext::Create();
  if (!context.ok()) return Fail(std::string(context.status().message()));
  const double context_seconds = watch.Seconds();

  watch.Restart();
  absl::StatusOr<gpu::ClusterPreviewColours> colours = gpu::ColourClusters(*adjacency, labels);
  if (!colours.ok()) return Fail(std::string(colours.status().message()));
  const double colour_seconds = watch.Seconds();

  watch.Restart();
  absl::StatusOr<gpu::RgbaImage> image =
      gpu::RenderClusterPreview(**context, *mesh, *adjacency, labels, options);
  if (!image.ok()) return Fail(std::string(image.status().message()));
  const double first_seconds = watch.Seconds();
  std::vector<double> render, encode;
  size_t png_bytes = 0;
  for (int r = 0; r < repeats; ++r) {
    watch.Restart();
    image = gpu::RenderClusterPreview(**context, *mesh, *adjacency, labels, options);
    if (!image.ok()) return Fail(std::string(image.status().message()));
    render.push_back(watch.Seconds());
    watch.Restart();
    absl::StatusOr<std::string> png = gpu::EncodePng(*image);
    if (!png.ok()) return Fail(std::string(png.status().message()));
    encode.push_back(watch.Seconds());
    png_bytes = png->size();
  }
  std::sort(render.begin(), render.end());
  std::sort(encode.begin(), encode.end());
  std::printf(
      "%s: %zu faces, %u clusters, %ux%u on %s\n"
      "  context %.3f s; colours %.4f s; first render (with shader compile) %.3f s\n"
      "  render + read-back median %.3f s (min %.3f); PNG encode median %.3f s (%zu bytes)\n",
      mesh_path.c_str(), mesh->num_faces(), colours->cluster_count, options.width, options.height,
      (*context)->renderer().c_str(), context_seconds, colour_seconds, first_seconds,
      render[render.size() / 2], render.front(), encode[encode.size() / 2], png_bytes);
  return 0;
}
