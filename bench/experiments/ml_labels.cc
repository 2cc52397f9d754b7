// The clustering of an ML (or HC) hierarchy at given cluster counts, as coloured PLYs for
// bench/render_ply.py: the pictures of Figs. 4.21, 4.23 and 4.25.
//   ml_labels MESH --energy E [--algo ml|hc] --at K1,K2,... --out PREFIX
// Writes PREFIX_K.ply for each K (the last level with K clusters) and prints one line per K:
// K,level,energy.
#include <cstdio>
#include <string>
#include <vector>

#include "bench/bench_util.h"
#include "bench/experiments/clustered_ply.h"
#include "core/cluster/multilevel.h"
#include "core/hierarchy/hierarchy.h"

int main(int argc, char** argv) {
  using namespace mlclust;
  bench::Args args(argc, argv,
                   "usage: ml_labels MESH --energy E [--algo ml|hc] --at K1,K2,... --out PREFIX");
  const std::string path = args.num_positional() > 0 ? args.Positional(0) : "";
  const std::string energy_name = args.Get<std::string>("energy", "cvd");
  const std::string algo = args.Get<std::string>("algo", "ml");
  const std::vector<uint32_t> ks = args.GetList<uint32_t>("at", "");
  const std::string out = args.Get<std::string>("out", "");
  if (!args.Done() || path.empty() || ks.empty() || out.empty()) return 2;
  absl::StatusOr<MeshEnergyKind> kind = ParseMeshEnergyKind(energy_name);
  if (!kind.ok()) return 2;
  const PreparedMesh prepared = bench::PrepareOrDie(path);
  MeshEnergyOptions energy;
  energy.kind = *kind;
  const MeshProblem problem = MakeMeshProblem(prepared, energy);
  MultilevelOptions options;
  if (algo == "hc") options.optimizer = MultilevelOptions::Optimizer::kNone;
  HierarchyLog log;
  const absl::StatusOr<MultilevelSummary> summary = RunMultilevel(problem, options, log);
  if (!summary.ok()) {
    std::fprintf(stderr, "%s\n", summary.status().ToString().c_str());
    return 1;
  }
  for (uint32_t k : ks) {
    const std::optional<size_t> level = log.LastLevelWith(k);
    if (!level.has_value()) {
      std::fprintf(stderr, "no level with %u clusters\n", k);
      return 1;
    }
    absl::StatusOr<std::vector<ClusterId>> labels = log.LabelsAt(*level);
    if (!labels.ok()) return 1;
    const std::string file = out + "_" + std::to_string(k) + ".ply";
    if (!bench::WriteClusteredPly(file, prepared.mesh, *labels)) return 1;
    std::printf("%u,%zu,%.10g\n", k, *level, log.energy(*level));
  }
  return 0;
}
