// PML on the CPU's cores against ML: wall time of the whole hierarchy and to the first
// level with at most k clusters, and the energy there.
//
//   pml_cpu_bench MESH [--algo ml|pml] [--pml-until K] [--threads T] [--energy cvd|planar]
//                 [--optimizer emlo|bb|none] [--parallel-optimisation]
//                 [--independent-moves] [--at 1000] [--stop-at K]
//                 [--p-percent P] [--p-rule sweep|hc-first] [--repeats R] [--header]
//                 [--preset many-cores] [--step-stats] [--face-order-steps auto|always|never]
//
// --preset many-cores: the registry's pml preset (core/cluster/registry.cc): PML, p95
// hc-first (optimised at least below 2 pml-until clusters), pml-until max(stop-at, 1000),
// parallel rounds; it overrides those flags.
//
// Prints one CSV row (best total time of R runs; the energy is the same in every run):
// mesh,faces,algo,energy,optimizer,parallel_optimisation,p_percent,p_rule,pml_until,threads,
// seconds,seconds_to_k,levels,k,clusters_at_k,energy_at_k,cpu_seconds
// (parallel_optimisation: 0 off, 1 rounds, 2 rounds with --independent-moves)
// --step-stats: also, on stderr, what the face-order rounds ran in parallel steps (all R
// runs together; core/cluster/detail/multilevel_engine.h, FaceOrderStepsCounters).
// --face-order-steps: when those steps run (auto: on 4 threads or more; the same levels
// either way); `always` profiles them on one thread.
#include <algorithm>
#include <cstdio>
#include <ctime>
#include <limits>
#include <string>

#include "absl/time/clock.h"
#include "bench/bench_util.h"
#include "core/cluster/detail/multilevel_engine.h"
#include "core/cluster/multilevel.h"

namespace {

// Notes the time and energy at the first level with at most `k` clusters.
class AtKSink : public mlclust::LevelSink {
 public:
  AtKSink(uint32_t k, absl::Time start) : k_(k), start_(start) {}
  absl::Status OnStart(std::span<const mlclust::ClusterId> /*labels*/, uint32_t count,
                       double energy) override {
    Note(count, energy);
    return absl::OkStatus();
  }
  absl::Status OnLevel(const mlclust::LevelMoves& level) override {
    Note(level.cluster_count, level.energy);
    return absl::OkStatus();
  }
  double seconds = 0, energy = 0;
  uint32_t clusters = 0;
  bool seen = false;

 private:
  void Note(uint32_t count, double e) {
    if (seen || count > k_) return;
    seen = true;
    seconds = absl::ToDoubleSeconds(absl::Now() - start_);
    energy = e;
    clusters = count;
  }
  uint32_t k_;
  absl::Time start_;
};

}  // namespace

int main(int argc, char** argv) {
  mlclust::bench::Args args(
      argc, argv,
      "usage: pml_cpu_bench MESH [--algo ml|pml] [--pml-until K] [--threads T] "
      "[--energy cvd|planar] [--optimizer emlo|bb|none] [--parallel-optimisation] "
      "[--independent-moves] [--at K] [--stop-at K] "
      "[--p-percent P] [--p-rule sweep|hc-first] [--repeats R] [--header] "
      "[--preset many-cores] [--step-stats] [--face-order-steps auto|always|never]");
  const bool header = args.Flag("header");
  const bool parallel_optimisation = args.Flag("parallel-optimisation");
  const bool independent_moves = args.Flag("independent-moves");
  const bool step_stats = args.Flag("step-stats");
  const std::string algo = args.Get<std::string>("algo", "ml");
  const uint32_t pml_until = args.Get<uint32_t>("pml-until", 0);
  const int threads = args.Get<int>("threads", 0);
  const std::string energy_name = args.Get<std::string>("energy", "cvd");
  const std::string optimizer = args.Get<std::string>("optimizer", "emlo");
  const uint32_t k = args.Get<uint32_t>("at", 1000);
  // The lowest level to compute (min_clusters; 1 = the whole hierarchy).
  const uint32_t stop_at = args.Get<uint32_t>("stop-at", 1);
  const uint32_t repeats = args.Get<uint32_t>("repeats", 1);
  const double p_percent = args.Get<double>("p-percent", 0.0);
  const std::string p_rule = args.Get<std::string>("p-rule", "sweep");
  const std::string preset = args.Get<std::string>("preset", "none");
  const std::string face_order_steps = args.Get<std::string>("face-order-steps", "auto");
  const std::string path = args.Positional(0);
  if (!args.Done()) return 2;

  const mlclust::PreparedMesh prepared = mlclust::bench::PrepareOrDie(path);
  mlclust::MeshEnergyOptions energy;
  absl::StatusOr<mlclust::MeshEnergyKind> kind = mlclust::ParseMeshEnergyKind(energy_name);
  if (!kind.ok()) {
    std::fprintf(stderr, "%s\n", kind.status().ToString().c_str());
    return 2;
  }
  energy.kind = *kind;
  const mlclust::MeshProblem problem = mlclust::MakeMeshProblem(prepared, energy);
  mlclust::MultilevelOptions options;
  options.parallel = algo == "pml";
  options.pml_until = pml_until;
  options.threads = threads;
  options.parallel_optimisation = parallel_optimisation;
  options.independent_moves = independent_moves;
  options.min_clusters = stop_at;
  options.p_percent = p_percent;
  if (p_rule == "hc-first") {
    options.p_percent_rule = mlclust::MultilevelOptions::PPercentRule::kHcFirst;
  }
  if (preset == "many-cores") {
    options.parallel = true;
    options.p_percent = 95;
    options.p_percent_rule = mlclust::MultilevelOptions::PPercentRule::kHcFirst;
    options.pml_until = std::max<uint32_t>(stop_at, 1000);
    options.optimise_below_at_least = 2 * options.pml_until;
    options.parallel_optimisation = true;
    options.independent_moves = false;
  } else if (preset != "none") {
    std::fprintf(stderr, "pml_cpu_bench: --preset %s is not none or many-cores\n", preset.c_str());
    return 2;
  }
  if (face_order_steps == "always") {
    mlclust::detail::face_order_steps = mlclust::detail::FaceOrderSteps::kAlways;
  } else if (face_order_steps == "never") {
    mlclust::detail::face_order_steps = mlclust::detail::FaceOrderSteps::kNever;
  } else if (face_order_steps != "auto") {
    std::fprintf(stderr, "pml_cpu_bench: --face-order-steps %s is not auto, always or never\n",
                 face_order_steps.c_str());
    return 2;
  }
  if (optimizer == "bb") options.optimizer = mlclust::MultilevelOptions::Optimizer::kBoundaryBased;
  if (optimizer == "none") options.optimizer = mlclust::MultilevelOptions::Optimizer::kNone;

  double best = std::numeric_limits<double>::infinity(), best_to_k = 0, energy_at_k = 0,
         best_cpu = 0;
  uint32_t levels = 0, clusters_at_k = 0;
  for (uint32_t r = 0; r < repeats; ++r) {
    const absl::Time start = absl::Now();
    const std::clock_t cpu_start = std::clock();  // the process's CPU time, all threads
    AtKSink sink(k, start);
    absl::StatusOr<mlclust::MultilevelSummary> summary =
        mlclust::RunMultilevel(problem, options, sink);
    const double seconds = absl::ToDoubleSeconds(absl::Now() - start);
    const double cpu = static_cast<double>(std::clock() - cpu_start) / CLOCKS_PER_SEC;
    if (!summary.ok()) {
      std::fprintf(stderr, "%s\n", summary.status().ToString().c_str());
      return 1;
    }
    if (seconds < best) {
      best = seconds;
      best_to_k = sink.seconds;
      best_cpu = cpu;
    }
    energy_at_k = sink.energy;
    clusters_at_k = sink.clusters;
    levels = summary->levels;
  }
  if (header) {
    std::printf(
        "mesh,faces,algo,energy,optimizer,parallel_optimisation,p_percent,p_rule,pml_until,"
        "threads,seconds,seconds_to_k,levels,k,clusters_at_k,energy_at_k,cpu_seconds\n");
  }
  const std::string name = path.substr(path.find_last_of('/') + 1);
  std::printf(
      "%s,%zu,%s,%s,%s,%d,%g,%s,%u,%d,%.3f,%.3f,%u,%u,%u,%.10g,%.3f\n", name.c_str(),
      prepared.mesh.num_faces(), options.parallel ? "pml" : "ml", energy_name.c_str(),
      optimizer.c_str(), options.parallel_optimisation ? (options.independent_moves ? 2 : 1) : 0,
      options.p_percent,
      options.p_percent_rule == mlclust::MultilevelOptions::PPercentRule::kHcFirst ? "hc-first"
                                                                                   : "sweep",
      options.pml_until, threads, best, best_to_k, levels, k, clusters_at_k, energy_at_k, best_cpu);
  if (step_stats) {
    const mlclust::detail::FaceOrderStepsCounters& c = mlclust::detail::face_order_steps_counters;
    std::fprintf(stderr,
                 "face-order rounds in steps: %llu rounds, %llu steps, %llu candidates, %llu of "
                 "them in parallel steps, %llu moves\n",
                 static_cast<unsigned long long>(c.rounds.load()),
                 static_cast<unsigned long long>(c.steps.load()),
                 static_cast<unsigned long long>(c.candidates.load()),
                 static_cast<unsigned long long>(c.in_steps.load()),
                 static_cast<unsigned long long>(c.moves.load()));
  }
  return 0;
}
