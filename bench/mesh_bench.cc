// Times single-level mesh clustering: initial clusters, then EMLO or BB.
//   mesh_bench MESH --k K [--energy cvd] [--init lneigh|random] [--algo emlo|bb]
//              [--threads T] [--repeats R] [--seed S]
// Prints one CSV row (best of R): mesh,faces,k,energy,init,algo,threads,init_s,opt_s,
// total_s,initial_energy,final_energy,moves,iterations
#include <cstdio>
#include <cstring>
#include <string>

#include "absl/strings/numbers.h"
#include "absl/time/clock.h"
#include "core/cluster/mesh_clustering.h"
#include "core/io/mesh_io.h"

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr,
                 "usage: mesh_bench MESH --k K [--energy E] [--init I] [--algo A] "
                 "[--threads T] [--repeats R] [--seed S] [--header]\n");
    return 2;
  }
  std::string path = argv[1], energy_name = "cvd", init = "lneigh", algo = "emlo";
  uint32_t k = 1000, threads = 0, repeats = 3;
  uint64_t seed = 1;
  for (int i = 2; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--header") {
      std::printf(
          "mesh,faces,k,energy,init,algo,threads,init_s,opt_s,total_s,initial_energy,"
          "final_energy,moves,iterations\n");
      continue;
    }
    if (i + 1 >= argc) return 2;
    const std::string value = argv[++i];
    bool ok = true;
    if (arg == "--k")
      ok = absl::SimpleAtoi(value, &k);
    else if (arg == "--energy")
      energy_name = value;
    else if (arg == "--init")
      init = value;
    else if (arg == "--algo")
      algo = value;
    else if (arg == "--threads")
      ok = absl::SimpleAtoi(value, &threads);
    else if (arg == "--repeats")
      ok = absl::SimpleAtoi(value, &repeats);
    else if (arg == "--seed")
      ok = absl::SimpleAtoi(value, &seed);
    else
      ok = false;
    if (!ok) {
      std::fprintf(stderr, "bad option %s %s\n", arg.c_str(), value.c_str());
      return 2;
    }
  }
  absl::StatusOr<mlclust::TriangleMesh> mesh = mlclust::ReadMeshFile(path);
  if (!mesh.ok() || !mlclust::ValidateMesh(*mesh).ok()) return 1;
  const mlclust::FaceAdjacency adjacency = *mlclust::BuildFaceAdjacency(*mesh);
  const mlclust::FaceMeasures measures = mlclust::ComputeFaceMeasures(*mesh);
  mlclust::MeshProblem problem{&*mesh, &adjacency, &measures, {}};
  absl::StatusOr<mlclust::MeshEnergyKind> kind = mlclust::ParseMeshEnergyKind(energy_name);
  if (!kind.ok()) return 2;
  problem.energy.kind = *kind;
  mlclust::SeedOptions seeds;
  seeds.clusters = k;
  seeds.seed = seed;
  seeds.method = init == "random" ? mlclust::SeedOptions::Method::kRandom
                                  : mlclust::SeedOptions::Method::kLNeighbourhood;
  double best_total = 1e30, best_init = 0, best_opt = 0;
  mlclust::OptimizeResult best_result;
  for (uint32_t r = 0; r < repeats; ++r) {
    const absl::Time t0 = absl::Now();
    absl::StatusOr<std::vector<mlclust::ClusterId>> labels =
        mlclust::InitialClusters(problem, seeds);
    if (!labels.ok()) {
      std::fprintf(stderr, "%s\n", labels.status().ToString().c_str());
      return 1;
    }
    const absl::Time t1 = absl::Now();
    absl::StatusOr<mlclust::OptimizeResult> result;
    if (algo == "bb") {
      mlclust::BoundaryBasedOptions options;
      options.threads = static_cast<int>(threads);
      result = mlclust::OptimizeBoundaryBased(problem, *labels, options);
    } else {
      result = mlclust::OptimizeEmlo(problem, *labels);
    }
    if (!result.ok()) return 1;
    const absl::Time t2 = absl::Now();
    const double total = absl::ToDoubleSeconds(t2 - t0);
    if (total < best_total) {
      best_total = total;
      best_init = absl::ToDoubleSeconds(t1 - t0);
      best_opt = absl::ToDoubleSeconds(t2 - t1);
      best_result = *result;
    }
  }
  const char* name = std::strrchr(path.c_str(), '/');
  std::printf("%s,%zu,%u,%s,%s,%s,%u,%.4f,%.4f,%.4f,%.10g,%.10g,%llu,%u\n",
              name ? name + 1 : path.c_str(), mesh->num_faces(), k, energy_name.c_str(),
              init.c_str(), algo.c_str(), threads, best_init, best_opt, best_total,
              best_result.initial_energy, best_result.energy,
              static_cast<unsigned long long>(best_result.moves), best_result.iterations);
  return 0;
}
