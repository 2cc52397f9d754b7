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
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include "absl/strings/numbers.h"
#include "absl/strings/str_split.h"
#include "absl/time/clock.h"
#include "bench/cancel_timer.h"
#include "bench/curve_sink.h"
#include "core/cluster/multilevel.h"
#include "core/io/mesh_io.h"

namespace {

using CurveSink = mlclust::bench::CurveSink;

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: ml_bench MESH [options]; see the source\n");
    return 2;
  }
  std::string path = argv[1], algo = "ml", energy_name = "cvd", optimizer = "emlo", curve,
              pml_pairs, p_rule;
  std::vector<uint32_t> at = {1000, 200};
  double p_percent = 0;
  uint32_t pml_until = 0, repeats = 1;
  double cancel_after = -1;
  int threads = 0;
  bool header = false;
  for (int i = 2; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--header") {
      header = true;
      continue;
    }
    if (i + 1 >= argc) return 2;
    const std::string value = argv[++i];
    bool ok = true;
    if (arg == "--algo")
      algo = value;
    else if (arg == "--energy")
      energy_name = value;
    else if (arg == "--optimizer")
      optimizer = value;
    else if (arg == "--p-percent")
      ok = absl::SimpleAtod(value, &p_percent);
    else if (arg == "--pml-until")
      ok = absl::SimpleAtoi(value, &pml_until);
    else if (arg == "--p-rule")
      ok = (p_rule = value) == "sweep" || value == "hc-first";
    else if (arg == "--pml-pairs")
      ok = (pml_pairs = value) == "all" || value == "cheaper-half";
    else if (arg == "--threads")
      ok = absl::SimpleAtoi(value, &threads);
    else if (arg == "--repeats")
      ok = absl::SimpleAtoi(value, &repeats);
    else if (arg == "--cancel-after")
      ok = absl::SimpleAtod(value, &cancel_after);
    else if (arg == "--curve")
      curve = value;
    else if (arg == "--at") {
      at.clear();
      for (absl::string_view part : absl::StrSplit(value, ',')) {
        uint32_t k;
        ok = ok && absl::SimpleAtoi(part, &k);
        at.push_back(k);
      }
    } else
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
  const char* name = std::strrchr(path.c_str(), '/');
  name = name ? name + 1 : path.c_str();
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
    std::printf("%s,%zu,%s,%s,%s,%g,%u,%d,%.4f,%zu,%u,%.10g\n", name, mesh->num_faces(),
                algo.c_str(), energy_name.c_str(), optimizer.c_str(), p_percent, pml_until, threads,
                best, best_sink.counts.size(), got, e);
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
