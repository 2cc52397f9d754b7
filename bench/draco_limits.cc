// The figures behind DracoDecodeLimits (core/io/draco_codec.h): faces per payload byte of
// the most compressible meshes we can make, and what decoding allocates per face, for
// real meshes and a regular grid, with every Draco method, quantisation and speed.
//
//   build/bench/draco_limits [MESH...] [--grid N]
//
// One CSV row per payload: mesh, method, bits, speed, faces, bytes, faces per byte,
// bytes operator new handed out while decoding (ScopedAllocationBudget), per face, and
// the decoder's verdict under the default limits.
#include <cstdio>
#include <string>
#include <vector>

#include "bench/bench_util.h"
#include "core/io/allocation_budget.h"
#include "core/io/draco_codec.h"
#include "core/io/mesh_io.h"

namespace {

mlclust::TriangleMesh RegularGrid(uint32_t n) {
  mlclust::TriangleMesh mesh;
  for (uint32_t y = 0; y <= n; ++y) {
    for (uint32_t x = 0; x <= n; ++x) {
      mesh.positions.insert(mesh.positions.end(),
                            {static_cast<float>(x), static_cast<float>(y), 0.0f});
    }
  }
  auto id = [n](uint32_t x, uint32_t y) { return y * (n + 1) + x; };
  for (uint32_t y = 0; y < n; ++y) {
    for (uint32_t x = 0; x < n; ++x) {
      mesh.indices.insert(mesh.indices.end(), {id(x, y), id(x + 1, y), id(x + 1, y + 1)});
      mesh.indices.insert(mesh.indices.end(), {id(x, y), id(x + 1, y + 1), id(x, y + 1)});
    }
  }
  return mesh;
}

void Report(const std::string& name, const mlclust::TriangleMesh& mesh) {
  using mlclust::DracoMethod;
  for (DracoMethod method : {DracoMethod::kSequential, DracoMethod::kEdgebreaker}) {
    for (int bits : {0, 1, 4, 8, 14}) {
      for (int speed : {0, 3, 5, 10}) {
        mlclust::DracoEncodeOptions options;
        options.method = method;
        options.position_quantization_bits = bits;
        options.speed = speed;
        const absl::StatusOr<std::string> bytes = mlclust::EncodeMeshToDraco(mesh, options);
        if (!bytes.ok()) continue;
        size_t allocated = 0;
        std::string verdict;
        {
          mlclust::ScopedAllocationBudget watch(SIZE_MAX);
          const auto decoded = mlclust::DecodeDracoMeshWithFaceIds(*bytes);
          allocated = watch.allocated_bytes();
          verdict = decoded.ok() ? "decoded" : "refused";
        }
        const double faces = static_cast<double>(mesh.num_faces());
        std::printf("%s,%s,%d,%d,%zu,%zu,%.2f,%zu,%.0f,%s\n", name.c_str(),
                    method == DracoMethod::kSequential ? "sequential" : "edgebreaker", bits, speed,
                    mesh.num_faces(), bytes->size(), faces / bytes->size(), allocated,
                    allocated / faces, verdict.c_str());
      }
    }
  }
}

}  // namespace

int main(int argc, char** argv) {
  mlclust::bench::Args args(argc, argv, "usage: draco_limits [MESH...] [--grid N]");
  const uint32_t grid = args.Get<uint32_t>("grid", 1000);
  std::vector<std::string> paths;
  for (size_t i = 0; i < args.num_positional(); ++i) paths.push_back(args.Positional(i));
  if (!args.Done()) return 2;
  std::printf(
      "mesh,method,bits,speed,faces,bytes,faces_per_byte,decode_alloc_bytes,"
      "alloc_per_face,verdict\n");
  Report("grid" + std::to_string(grid), RegularGrid(grid));
  for (const std::string& path : paths) {
    const absl::StatusOr<mlclust::TriangleMesh> mesh = mlclust::ReadMeshFile(path);
    if (!mesh.ok()) {
      std::fprintf(stderr, "%s: %s\n", path.c_str(), std::string(mesh.status().message()).c_str());
      return 1;
    }
    Report(path.substr(path.find_last_of('/') + 1), *mesh);
  }
  return 0;
}
