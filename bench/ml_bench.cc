// Times the multilevel engine over a whole hierarchy and reports energies at given k.
//   ml_bench MESH [--algo ml|pml|hc] [--energy cvd] [--optimizer emlo|bb|none]
//            [--p-percent P] [--p-rule sweep|hc-first] [--pml-until K]
//            [--pml-pairs all|cheaper-half] [--threads T]
//            [--at K1,K2,...] [--repeats R] [--cancel-after S]
// --cancel-after S sets options.cancel S seconds into the run and reports on stderr how long
// the engine took to return after it (then exits).
//            [--curve FILE]   (writes clusters,energy for every level)
// Prints one CSV row per requested k (best time of R): mesh,faces,algo,energy,optimizer,
// p_percent,pml_until,threads,seconds,levels,k,energy_at_k
#include <cstdio>
#include <string>
#include <vector>

#include "absl/time/clock.h"
#include "bench/bench_util.h"
#include "bench/cancel_timer.h"
#include "bench/curve_sink.h"
#include "core/cluster/multilevel.h"

namespace {

using CurveSink = mlclust::bench::CurveSink;

}  // namespace

int main(int argc, char** argv) {
  mlclust::bench::Args args(
      argc, argv,
      "usage: ml_bench MESH [--algo ml|pml|hc] [--energy cvd] [--optimizer emlo|bb|none]\n"
      "  [--p-percent P] [--p-rule sweep|hc-first] [--pml-until K]\n"
      "  [--pml-pairs all|cheaper-half] [--threads T] [--at K1,K2,...] [--repeats R]\n"
      "  [--cancel-after S] [--curve FILE] [--header]");
  const bool header = args.Flag("header");
  const std::string path = args.Positional(0);
  const std::string algo = args.Get<std::string>("algo", "ml");
  const std::string energy_name = args.Get<std::string>("energy", "cvd");
  const std::string optimizer = args.Get<std::string>("optimizer", "emlo");
  const std::string curve = args.Get<std::string>("curve", "");
  const std::string pml_pairs = args.Get<std::string>("pml-pairs", "");
  const std::string p_rule = args.Get<std::string>("p-rule", "");
  const double p_percent = args.Get<double>("p-percent", 0);
  const uint32_t pml_until = args.Get<uint32_t>("pml-until", 0);
  const uint32_t repeats = args.Get<uint32_t>("repeats", 1);
  const double cancel_after = args.Get<double>("cancel-after", -1);
  const int threads = args.Get<int>("threads", 0);
  const std::vector<uint32_t> at = args.GetList<uint32_t>("at", "1000,200");
  if (!args.Done()) return 2;
  if ((!p_rule.empty() && p_rule != "sweep" && p_rule != "hc-first") ||
      (!pml_pairs.empty() && pml_pairs != "all" && pml_pairs != "cheaper-half")) {
    std::fprintf(stderr, "--p-rule is sweep or hc-first, --pml-pairs all or cheaper-half\n");
    return 2;
  }
  const mlclust::PreparedMesh prepared = mlclust::bench::PrepareOrDie(path);
  absl::StatusOr<mlclust::MeshEnergyKind> kind = mlclust::ParseMeshEnergyKind(energy_name);
  if (!kind.ok()) return 2;
  mlclust::MeshEnergyOptions energy;
  energy.kind = *kind;
  const mlclust::MeshProblem problem = mlclust::MakeMeshProblem(prepared, energy);
  mlclust::MultilevelOptions options;
  options.optimizer = optimizer == "bb"     ? mlclust::MultilevelOptions::Optimizer::kBoundaryBased
                      : optimizer == "none" ? mlclust::MultilevelOptions::Optimizer::kNone
                                            : mlclust::MultilevelOptions::Optimizer::kEmlo;
  if (algo == "hc") options.optimizer = mlclust::MultilevelOptions::Optimizer::kNone;
  options.parallel = algo == "pml";
  options.pml_until = pml_until;
  if (pml_pairs == "all") options.pml_pairs = mlclust::PmlPairRule::kAll;
  if (pml_pairs == "cheaper-half") options.pml_pairs = mlclust::PmlPairRule::kCheaperHalf;
  options.p_percent = p_percent;
  if (p_rule == "hc-first") {
    options.p_percent_rule = mlclust::MultilevelOptions::PPercentRule::kHcFirst;
  }
  options.threads = threads;
  double best = 1e30;
  CurveSink best_sink;
  for (uint32_t r = 0; r < repeats; ++r) {
    CurveSink sink;
    const absl::Time start = absl::Now();
    mlclust::bench::CancelTimer cancel(cancel_after);
    options.cancel = cancel.flag();
    absl::StatusOr<mlclust::MultilevelSummary> summary =
        mlclust::RunMultilevel(problem, options, sink);
    if (cancel_after >= 0) {
      cancel.Report(summary.status(), "RunMultilevel");
      return 0;
    }
    const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
    if (!summary.ok()) {
      std::fprintf(stderr, "%s\n", summary.status().ToString().c_str());
      return 1;
    }
    std::fprintf(stderr,
                 "run %u: %.3f s, %u levels, %llu triplets, %llu optimiser moves, %llu "
                 "evaluations\n",
                 r, seconds, summary->levels, static_cast<unsigned long long>(summary->moves),
                 static_cast<unsigned long long>(summary->optimisation_moves),
                 static_cast<unsigned long long>(summary->evaluations));
    if (seconds < best) {
      best = seconds;
      best_sink = sink;
    }
  }
  const std::string name = mlclust::bench::BaseName(path);
  if (header) {
    std::printf(
        "mesh,faces,algo,energy,optimizer,p_percent,pml_until,threads,seconds,levels,"
        "k,energy_at_k\n");
  }
  for (uint32_t k : at) {
    // The first level with at most k clusters (PML skips counts).
    double e = -1;
    uint32_t got = 0;
    for (size_t l = 0; l < best_sink.counts.size(); ++l) {
      if (best_sink.counts[l] <= k) {
        e = best_sink.energies[l];
        got = best_sink.counts[l];
        break;
      }
    }
    std::printf("%s,%zu,%s,%s,%s,%g,%u,%d,%.4f,%zu,%u,%.10g\n", name.c_str(),
                prepared.mesh.num_faces(), algo.c_str(), energy_name.c_str(), optimizer.c_str(),
                p_percent, pml_until, threads, best, best_sink.counts.size(), got, e);
  }
  if (!curve.empty()) {
    std::FILE* out = std::fopen(curve.c_str(), "w");
    if (out == nullptr) return 1;
    std::fprintf(out, "clusters,energy\n");
    for (size_t l = 0; l < best_sink.counts.size(); ++l) {
      std::fprintf(out, "%u,%.12g\n", best_sink.counts[l], best_sink.energies[l]);
    }
    std::fclose(out);
  }
  return 0;
}
