// Times single-level mesh clustering: initial clusters, then EMLO or BB.
//   mesh_bench MESH --k K [--energy cvd] [--init lneigh|random] [--algo emlo|bb]
//              [--threads T] [--repeats R] [--seed S] [--header]
//              [--guard ring|alg32|off] [--growth flood|free] [--reduce merge|reseed]
//              [--level L] [--add-seeds] [--runs N] [--rho-new R] [--ply OUT.ply]
// --runs N: one row per seed S, S+1, ..., S+N-1 (the mesh read once).
// --k 0 with --level L: k = the number of l-neighbourhood seeds of L (Table 3.1's way).
// --rho-new R: rho^new of the density's linear mapping (mwcvd-*; 0: the energy's default).
// --ply OUT.ply: the last run's clustering, faces coloured by cluster (bench/render_ply.py).
// --truth FILE: instead of clustering, print "truth,CLUSTERS,ENERGY" for the labels in FILE
// (one cluster id per face and line, e.g. bench/experiments/sphere_models.py's .truth).
// Prints one CSV row (best of R): mesh,faces,k,energy,init,algo,threads,init_s,opt_s,
// total_s,initial_energy,final_energy,moves,iterations
#include <algorithm>
#include <array>
#include <cstdio>
#include <string>

#include "bench/bench_util.h"
#include "bench/experiments/clustered_ply.h"
#include "core/cluster/mesh_clustering.h"
#include "core/io/mesh_io.h"

int main(int argc, char** argv) {
  using namespace mlclust;
  bench::Args args(argc, argv,
                   "usage: mesh_bench MESH --k K [--energy E] [--init lneigh|random] "
                   "[--algo emlo|bb] [--threads T] [--repeats R] [--seed S] [--header] "
                   "[--guard ring|alg32|off] [--growth flood|free] [--reduce merge|reseed] "
                   "[--level L] [--add-seeds] [--runs N] [--rho-new R] [--ply OUT.ply]");
  const bool header = args.Flag("header");
  const bool add_seeds = args.Flag("add-seeds");
  const std::string path = args.num_positional() > 0 ? args.Positional(0) : "";
  uint32_t k = args.Get<uint32_t>("k", 1000);
  const std::string energy_name = args.Get<std::string>("energy", "cvd");
  const std::string init = args.Get<std::string>("init", "lneigh");
  const std::string algo = args.Get<std::string>("algo", "emlo");
  const uint32_t threads = args.Get<uint32_t>("threads", 0);
  const uint32_t repeats = args.Get<uint32_t>("repeats", 3);
  const uint64_t seed = args.Get<uint64_t>("seed", 1);
  const std::string guard_name = args.Get<std::string>("guard", "ring");
  const std::string growth = args.Get<std::string>("growth", "flood");
  const std::string reduce = args.Get<std::string>("reduce", "merge");
  const uint32_t level = args.Get<uint32_t>("level", 0);
  const uint32_t runs = args.Get<uint32_t>("runs", 1);
  const double rho_new = args.Get<double>("rho-new", 0);
  const std::string ply = args.Get<std::string>("ply", "");
  const std::string truth = args.Get<std::string>("truth", "");
  if (!args.Done()) return 2;
  const ConnectivityGuardKind guard = guard_name == "alg32"
                                          ? ConnectivityGuardKind::kVertexBoundaryEdgeCount
                                      : guard_name == "off" ? ConnectivityGuardKind::kOff
                                                            : ConnectivityGuardKind::kRingTest;
  if (header) {
    std::printf(
        "mesh,faces,k,energy,init,algo,threads,init_s,opt_s,total_s,initial_energy,"
        "final_energy,moves,iterations\n");
  }
  if (path.empty()) return 0;  // --header alone
  absl::StatusOr<MeshEnergyKind> kind = ParseMeshEnergyKind(energy_name);
  if (!kind.ok()) {
    std::fprintf(stderr, "%s\n", kind.status().ToString().c_str());
    return 2;
  }
  const PreparedMesh prepared = bench::PrepareOrDie(path);
  MeshEnergyOptions energy;
  energy.kind = *kind;
  energy.density.rho_max = rho_new;
  if (k == 0) k = static_cast<uint32_t>(LNeighbourhoodSeeds(prepared.adjacency, level).size());
  if (!truth.empty()) {
    std::FILE* in = std::fopen(truth.c_str(), "r");
    std::vector<ClusterId> labels;
    uint32_t id = 0, largest = 0;
    while (in != nullptr && std::fscanf(in, "%u", &id) == 1) {
      labels.push_back(ClusterId(id));
      largest = std::max(largest, id);
    }
    if (in != nullptr) std::fclose(in);
    if (labels.size() != prepared.mesh.num_faces()) {
      std::fprintf(stderr, "%s: %zu labels for %zu faces\n", truth.c_str(), labels.size(),
                   prepared.mesh.num_faces());
      return 1;
    }
    std::printf("truth,%u,%.10g\n", largest + 1, MeshEnergyOfLabels(energy, prepared.mesh, labels));
    return 0;
  }
  const MeshProblem problem = MakeMeshProblem(prepared, energy);
  for (uint64_t run_seed = seed; run_seed < seed + runs; ++run_seed) {
    SeedOptions seeds;
    seeds.clusters = k;
    seeds.seed = run_seed;
    seeds.method =
        init == "random" ? SeedOptions::Method::kRandom : SeedOptions::Method::kLNeighbourhood;
    seeds.level = level;
    seeds.add_seeds = add_seeds;
    seeds.growth =
        growth == "free" ? SeedOptions::Growth::kEnergyFree : SeedOptions::Growth::kEnergyOrdered;
    seeds.reduction = reduce == "reseed" ? SeedOptions::Reduction::kReseedAndRegrow
                                         : SeedOptions::Reduction::kMergeRegions;
    double best_total = 1e30, best_init = 0, best_opt = 0;
    OptimizeResult best_result;
    for (uint32_t r = 0; r < repeats; ++r) {
      bench::Stopwatch watch;
      absl::StatusOr<std::vector<ClusterId>> labels = InitialClusters(problem, seeds);
      if (!labels.ok()) {
        std::fprintf(stderr, "%s\n", labels.status().ToString().c_str());
        return 1;
      }
      const double init_s = watch.Seconds();
      absl::StatusOr<OptimizeResult> result;
      if (algo == "bb") {
        BoundaryBasedOptions options;
        options.threads = static_cast<int>(threads);
        options.guard = guard;
        result = OptimizeBoundaryBased(problem, *labels, options);
      } else {
        EmloOptions options;
        options.guard = guard;
        result = OptimizeEmlo(problem, *labels, options);
      }
      if (!result.ok()) return 1;
      const double total = watch.Seconds();
      if (!ply.empty() && !bench::WriteClusteredPly(ply, prepared.mesh, *labels)) return 1;
      if (total < best_total) {
        best_total = total;
        best_init = init_s;
        best_opt = total - init_s;
        best_result = *result;
      }
    }
    std::printf("%s,%zu,%u,%s,%s,%s,%u,%.4f,%.4f,%.4f,%.10g,%.10g,%llu,%u\n",
                bench::BaseName(path).c_str(), prepared.mesh.num_faces(), k, energy_name.c_str(),
                init.c_str(), algo.c_str(), threads, best_init, best_opt, best_total,
                best_result.initial_energy, best_result.energy,
                static_cast<unsigned long long>(best_result.moves), best_result.iterations);
  }
  return 0;
}
