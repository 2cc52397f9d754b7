// Times mlclust's VSA (core/vsa.h), the counterpart of bench/peers/cgal_vsa.cc.
//   vsa_bench MESH --k K [--seeding random|incremental|hierarchical] [--iterations N]
//             [--inner-iterations I] [--min-relative-decrease D] [--no-teleport] [--seed S]
//             [--repeats R] [--header]
// Prints one CSV row: mesh,faces,k,seeding,iterations,seconds,energy.
//   seconds: the best of R repeats of ComputeFaceMeasures + RunVsa, one thread (the face
//            measures are timed as CGAL's L21 metric, which computes normals and areas, is
//            timed by cgal_vsa; reading the file and building the adjacency are not timed,
//            as cgal_vsa does not time reading or building its Surface_mesh).
//   energy:  the planar (L2,1) energy of the labels, EnergyFromSums(PlanarEnergy, labels).
// Defaults match cgal_vsa's: hierarchical seeding, 30 iterations, 5 inner iterations.
#include <cstdio>
#include <string>

#include "bench/bench_util.h"
#include "core/cluster/vsa.h"
#include "core/energy/energies.h"
#include "core/mesh/face_measures.h"

namespace {

std::string MeshName(const std::string& path) {
  std::string name = mlclust::bench::BaseName(path);
  const size_t dot = name.rfind('.');
  if (dot != std::string::npos && dot > 0) name.resize(dot);
  return name;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace mlclust;
  bench::Args args(argc, argv,
                   "usage: vsa_bench MESH --k K [--seeding random|incremental|hierarchical]\n"
                   "         [--iterations N] [--inner-iterations I] [--min-relative-decrease D]\n"
                   "         [--no-teleport] [--seed S] [--repeats R] [--header]");
  VsaOptions options;
  const bool header = args.Flag("header");
  options.teleport = !args.Flag("no-teleport");
  const std::string path = args.Positional(0);
  options.clusters = args.Get<uint32_t>("k", 0);
  const std::string seeding_name = args.Get<std::string>("seeding", "hierarchical");
  options.iterations = args.Get<uint32_t>("iterations", options.iterations);
  options.inner_iterations = args.Get<uint32_t>("inner-iterations", options.inner_iterations);
  options.min_relative_decrease =
      args.Get<double>("min-relative-decrease", options.min_relative_decrease);
  options.seed = args.Get<uint64_t>("seed", options.seed);
  const uint32_t repeats = args.Get<uint32_t>("repeats", 3);
  if (!args.Done() || repeats < 1 || args.num_positional() != 1) return 2;
  const absl::StatusOr<VsaOptions::Seeding> seeding = ParseVsaSeeding(seeding_name);
  if (!seeding.ok()) {
    std::fprintf(stderr, "vsa_bench: %s\n", std::string(seeding.status().message()).c_str());
    return 2;
  }
  options.seeding = *seeding;

  // Reading, validation and adjacency are not timed (cgal_vsa does not time reading or
  // building its Surface_mesh); the face measures are, below.
  const PreparedMesh prepared = bench::PrepareOrDie(path);
  const TriangleMesh& mesh = prepared.mesh;

  double best_seconds = 0;
  VsaResult best;
  FaceMeasures measures;
  for (uint32_t r = 0; r < repeats; ++r) {
    bench::Stopwatch watch;
    measures = ComputeFaceMeasures(mesh);
    MeshProblem problem{&mesh, &prepared.adjacency, &measures, {}};
    problem.energy.kind = MeshEnergyKind::kPlanar;
    absl::StatusOr<VsaResult> result = RunVsa(problem, options);
    const double seconds = watch.Seconds();
    if (!result.ok()) {
      std::fprintf(stderr, "vsa_bench: %s\n", result.status().ToString().c_str());
      return 1;
    }
    std::fprintf(stderr,
                 "vsa_bench: repeat %u/%u: %.6f s, %u seeding + %u iterations (best %u, %u "
                 "teleports), energy %.9g\n",
                 r + 1, repeats, seconds, result->seeding_iterations, result->iterations,
                 result->best_iteration, result->teleports, result->energy);
    if (r > 0 && result->labels != best.labels) {
      std::fprintf(stderr, "vsa_bench: repeat %u gave other labels than repeat 1\n", r + 1);
      return 1;
    }
    if (r == 0 || seconds < best_seconds) {
      best_seconds = seconds;
      best = *std::move(result);
    }
  }
  const double energy = EnergyFromSums(PlanarEnergy(measures), best.labels);

  if (header) std::printf("mesh,faces,k,seeding,iterations,seconds,energy\n");
  std::printf("%s,%zu,%u,%s,%u,%.6f,%.9g\n", MeshName(path).c_str(), mesh.num_faces(),
              options.clusters, seeding_name.c_str(), options.iterations, best_seconds, energy);
  return 0;
}
