// GPU stages against the CPU's, on this machine: prints one CSV row per run.
//
//   gpu_stages_bench bb MESH --k K [--energy cvd|planar] [--threads T] [--repeats R]
//       BB (Alg. 5.1) from l-neighbourhood seeds: the decide stage alone (CPU with T
//       threads vs GPU, labels and proxies uploaded and targets read back every call),
//       best of R; then whole BB runs on each, with their sweeps and energies.
//   gpu_stages_bench lnkmeans --points M --k K [--dims D] [--threads T]
//   gpu_stages_bench kmeans --points M --k K [--dims D] [--threads T] [--iterations I]
//       M generated points around 1000 Gaussian blobs (seed 1); LN k-means (Alg. 6.1) from
//       random seeds to convergence, brute-force Lloyd from k-means++ centres for I
//       iterations (tolerance 0; seeding not timed): seconds per iteration on each.
//   gpu_stages_bench sums --elements N --k K [--values D] [--repeats R]
//       cluster sums of N random elements (D doubles each) over K clusters: GPU pass vs a
//       plain fp64 loop on one core, best of R.
//   gpu_stages_bench growth MESH --k K [--repeats R] [--bb-iterations I] [--threads T]
//       The initial growth from K spread seeds (SpreadSeeds, patches.h): section 5.2's
//       rounds on the GPU (gpu/kernels/seed_growth.h) vs the CPU's rounds (= energy-free)
//       vs the CPU's energy-ordered flood, best of R each (wall and process CPU seconds);
//       whether GPU and CPU labels are identical; the CVD energy after each growth and
//       after BB (T threads, at most I sweeps) from the rounds' and the flood's partition.
//   --header prints the CSV header first.
//
// Every row names the GL renderer; on Mesa llvmpipe the GPU figures are a software
// rasteriser on this machine's cores, not a GPU.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "bench/bench_util.h"
#include "bench/gpu_bench_util.h"
#include "core/base/renumber.h"
#include "core/cluster/boundary_based.h"
#include "core/cluster/kmeans.h"
#include "core/cluster/mesh_clustering.h"
#include "core/cluster/patches.h"
#include "core/cluster/point_clustering.h"
#include "core/energy/energies.h"
#include "gpu/context/gl_context.h"
#include "gpu/kernels/bb_decide.h"
#include "gpu/kernels/cluster_sums.h"
#include "gpu/kernels/seed_growth.h"
#include "gpu/stages/boundary_based_gpu.h"
#include "gpu/stages/point_stages_gpu.h"

namespace mlclust::bench {
namespace {

constexpr char kUsage[] =
    "usage: gpu_stages_bench bb MESH --k K [--energy cvd|planar] [--threads T] [--repeats R]\n"
    "       gpu_stages_bench lnkmeans|kmeans --points M --k K [--dims D] [--threads T]\n"
    "       gpu_stages_bench sums --elements N --k K [--values D] [--repeats R]\n"
    "       gpu_stages_bench growth MESH --k K [--repeats R] [--bb-iterations I] [--threads T]\n"
    "                        [--iterations I]\n"
    "       [--header]";

[[noreturn]] void Die(const std::string& what, const absl::Status& status) {
  std::fprintf(stderr, "%s: %s\n", what.c_str(), status.ToString().c_str());
  std::exit(1);
}

template <typename Energy>
int DecideTimes(gpu::GlContext& context, const Energy& energy, const PreparedMesh& mesh,
                std::span<const ClusterId> seeds, int threads, int repeats, double& cpu_seconds,
                double& gpu_seconds) {
  const Renumbering<ClusterId> compact = RenumberByFirstAppearance(seeds);
  Partition<Energy> partition(energy, compact.dense, compact.size());
  std::vector<typename Energy::Proxy> proxies;
  boundary_based::FitProxies(partition, proxies);
  std::vector<uint32_t> target(mesh.mesh.num_faces());
  const boundary_based::StageThreads stage_threads(threads);
  const boundary_based::CpuBoundaryDecider<Energy> cpu(energy, mesh.adjacency, stage_threads);
  cpu_seconds = BestOf(repeats, [&] { return cpu(partition.labels(), proxies, target).ok(); });
  absl::StatusOr<gpu::GpuBoundaryDecider<Energy>> decider =
      gpu::GpuBoundaryDecider<Energy>::Create(context, energy, mesh.adjacency, compact.size());
  if (!decider.ok()) Die("GPU decider", decider.status());
  (void)(*decider)(partition.labels(), proxies, target);  // compiles the program
  gpu_seconds =
      BestOf(repeats, [&] { return (*decider)(partition.labels(), proxies, target).ok(); });
  size_t moves = 0;
  for (uint32_t t : target) moves += t != boundary_based::kNoMove;
  return static_cast<int>(moves);
}

int RunBb(gpu::GlContext& context, Args& args, bool header) {
  const uint32_t k = args.Get<uint32_t>("k", 1000);
  const std::string energy_name = args.Get<std::string>("energy", "cvd");
  const int threads = args.Get<int>("threads", 0);
  const int repeats = args.Get<int>("repeats", 5);
  const std::string path = args.Positional(1);
  if (!args.Done()) return 2;
  const PreparedMesh mesh = PrepareOrDie(path);
  MeshProblem problem{&mesh.mesh, &mesh.adjacency, &mesh.measures, {}};
  absl::StatusOr<MeshEnergyKind> kind = ParseMeshEnergyKind(energy_name);
  if (!kind.ok()) Die("--energy", kind.status());
  problem.energy.kind = *kind;
  SeedOptions seed_options;
  seed_options.clusters = k;
  absl::StatusOr<std::vector<ClusterId>> seeds = InitialClusters(problem, seed_options);
  if (!seeds.ok()) Die("seeds", seeds.status());
  double cpu_decide = 0, gpu_decide = 0;
  const int moves = WithMeshEnergy(problem.energy, mesh.mesh, mesh.measures, [&](const auto& e) {
    using Energy = std::decay_t<decltype(e)>;
    if constexpr (gpu::kHasGpuDecide<Energy>) {
      return DecideTimes(context, e, mesh, *seeds, threads, repeats, cpu_decide, gpu_decide);
    } else {
      return -1;
    }
  });
  if (moves < 0) {
    std::fprintf(stderr, "energy %s has no GPU decide stage\n", energy_name.c_str());
    return 2;
  }
  BoundaryBasedOptions options;
  options.threads = threads;
  std::vector<ClusterId> cpu_labels = *seeds, gpu_labels = *seeds;
  Stopwatch watch;
  absl::StatusOr<OptimizeResult> cpu = OptimizeBoundaryBased(problem, cpu_labels, options);
  const double cpu_run = watch.Seconds();
  if (!cpu.ok()) Die("BB on the CPU", cpu.status());
  watch.Restart();
  absl::StatusOr<OptimizeResult> gpu_run_result =
      gpu::OptimizeBoundaryBasedGpu(context, problem, gpu_labels, options);
  const double gpu_run = watch.Seconds();
  if (!gpu_run_result.ok()) Die("BB on the GPU", gpu_run_result.status());
  if (header) {
    std::printf(
        "stage,input,elements,k,cpu_threads,cpu_decide_s,gpu_decide_s,decide_speedup,first_sweep_"
        "moves,cpu_bb_s,cpu_sweeps,cpu_energy,gpu_bb_s,gpu_sweeps,gpu_energy,renderer\n");
  }
  std::printf("bb-%s,%s,%zu,%u,%d,%.6f,%.6f,%.2f,%d,%.4f,%u,%.9g,%.4f,%u,%.9g,\"%s\"\n",
              energy_name.c_str(), BaseName(path).c_str(), mesh.mesh.num_faces(), k, threads,
              cpu_decide, gpu_decide, cpu_decide / gpu_decide, moves, cpu_run, cpu->iterations,
              cpu->energy, gpu_run, gpu_run_result->iterations, gpu_run_result->energy,
              context.renderer().c_str());
  return 0;
}

PointSet Blobs(uint64_t m, uint32_t d) {
  std::mt19937 random(1);
  std::uniform_real_distribution<float> box(-100, 100);
  std::normal_distribution<float> spread(0, 1);
  const uint32_t blobs = 1000;
  std::vector<float> centres(size_t{blobs} * d);
  for (float& c : centres) c = box(random);
  PointSet points;
  points.dims = d;
  points.values.resize(m * d);
  for (uint64_t i = 0; i < m; ++i) {
    const uint32_t b = static_cast<uint32_t>(i % blobs);
    for (uint32_t j = 0; j < d; ++j) points.values[i * d + j] = centres[b * d + j] + spread(random);
  }
  return points;
}

int RunPoints(gpu::GlContext& context, Args& args, bool header, bool ln) {
  const uint64_t m = args.Get<uint64_t>("points", 100000);
  const uint32_t k = args.Get<uint32_t>("k", 1000);
  const uint32_t d = args.Get<uint32_t>("dims", 3);
  const int threads = args.Get<int>("threads", 0);
  const uint32_t iterations = args.Get<uint32_t>("iterations", 5);
  if (!args.Done()) return 2;
  const PointSet points = Blobs(m, d);
  {
    // Compiles the GPU programs (and warms the driver) outside the timings.
    PointSet few;
    few.dims = d;
    few.values.assign(points.values.begin(),
                      points.values.begin() + std::min<uint64_t>(m, 2000) * d);
    const uint32_t few_k = std::min<uint32_t>(k, 10);
    absl::StatusOr<std::vector<ClusterId>> seeds = SeedPointClusters(few, few_k, false, 1);
    absl::StatusOr<std::vector<float>> centres = RandomPointCentres(few, few_k, 1);
    if (!seeds.ok() || !centres.ok())
      Die("warm-up", seeds.ok() ? centres.status() : seeds.status());
    KmeansOptions options;
    options.max_iterations = 1;
    if (ln) {
      (void)gpu::RunLnKmeansGpu(context, few, *seeds);
    } else {
      (void)gpu::RunLloydGpu(context, few, *centres, options);
    }
  }
  double cpu_seconds = 0, gpu_seconds = 0, cpu_energy = 0, gpu_energy = 0;
  uint32_t cpu_iterations = 0, gpu_iterations = 0;
  if (ln) {
    absl::StatusOr<std::vector<ClusterId>> seeds = SeedPointClusters(points, k, false, 1, threads);
    if (!seeds.ok()) Die("seeds", seeds.status());
    LnKmeansOptions options;
    options.threads = threads;
    Stopwatch watch;
    absl::StatusOr<LnKmeansResult> cpu = RunLnKmeans(points, *seeds, options);
    cpu_seconds = watch.Seconds();
    if (!cpu.ok()) Die("LN k-means on the CPU", cpu.status());
    watch.Restart();
    absl::StatusOr<LnKmeansResult> gpu = gpu::RunLnKmeansGpu(context, points, *seeds, options);
    gpu_seconds = watch.Seconds();
    if (!gpu.ok()) Die("LN k-means on the GPU", gpu.status());
    cpu_energy = cpu->energy;
    gpu_energy = gpu->energy;
    cpu_iterations = cpu->iterations;
    gpu_iterations = gpu->iterations;
  } else {
    absl::StatusOr<std::vector<float>> centres = KmeansPlusPlusCentres(points, k, 1, threads);
    if (!centres.ok()) Die("k-means++", centres.status());
    KmeansOptions options;
    options.clusters = k;
    options.threads = threads;
    options.max_iterations = iterations;
    options.tolerance = 0;
    Stopwatch watch;
    absl::StatusOr<KmeansResult> cpu = RunLloyd(points, *centres, options);
    cpu_seconds = watch.Seconds();
    if (!cpu.ok()) Die("Lloyd on the CPU", cpu.status());
    watch.Restart();
    absl::StatusOr<KmeansResult> gpu = gpu::RunLloydGpu(context, points, *centres, options);
    gpu_seconds = watch.Seconds();
    if (!gpu.ok()) Die("Lloyd on the GPU", gpu.status());
    cpu_energy = cpu->inertia;
    gpu_energy = gpu->inertia;
    cpu_iterations = cpu->iterations;
    gpu_iterations = gpu->iterations;
  }
  if (header) {
    std::printf(
        "stage,points,dims,k,cpu_threads,cpu_s,cpu_iterations,cpu_s_per_iteration,cpu_energy,"
        "gpu_s,gpu_iterations,gpu_s_per_iteration,gpu_energy,speedup_per_iteration,renderer\n");
  }
  const double cpu_per = cpu_seconds / cpu_iterations, gpu_per = gpu_seconds / gpu_iterations;
  std::printf("%s,%llu,%u,%u,%d,%.4f,%u,%.6f,%.9g,%.4f,%u,%.6f,%.9g,%.2f,\"%s\"\n",
              ln ? "lnkmeans" : "kmeans", static_cast<unsigned long long>(m), d, k, threads,
              cpu_seconds, cpu_iterations, cpu_per, cpu_energy, gpu_seconds, gpu_iterations,
              gpu_per, gpu_energy, cpu_per / gpu_per, context.renderer().c_str());
  return 0;
}

// Cluster sums of N elements of D random doubles over K clusters (random labels): the GPU
// pass (host counting sort, uploads, two passes, read-back) against a plain fp64 loop.
int RunSums(gpu::GlContext& context, Args& args, bool header) {
  const uint32_t n = args.Get<uint32_t>("elements", 1000000);
  const uint32_t k = args.Get<uint32_t>("k", 1000);
  const uint32_t d = args.Get<uint32_t>("values", 5);
  const int repeats = args.Get<int>("repeats", 5);
  if (!args.Done()) return 2;
  std::mt19937 random(1);
  std::uniform_int_distribution<uint32_t> pick(0, k - 1);
  std::uniform_real_distribution<double> value(-1, 1);
  std::vector<uint32_t> labels(n);
  std::vector<double> values(size_t{n} * d);
  for (uint32_t& label : labels) label = pick(random);
  for (double& v : values) v = value(random);
  std::vector<double> cpu;
  const double cpu_seconds = BestOf(repeats, [&] {
    cpu = gpu::SumByClusterCpu(values, d, labels, k);
    return true;
  });
  absl::StatusOr<std::vector<double>> gpu = gpu::SumByCluster(context, values, d, labels, k);
  if (!gpu.ok()) Die("cluster sums", gpu.status());
  const double gpu_seconds = BestOf(repeats, [&] {
    gpu = gpu::SumByCluster(context, values, d, labels, k);
    return gpu.ok();
  });
  double worst = 0;
  for (size_t v = 0; v < cpu.size(); ++v) {
    worst = std::max(worst, std::abs((*gpu)[v] - cpu[v]) / std::max(std::abs(cpu[v]), 1e-300));
  }
  if (header) std::printf("stage,elements,values,k,cpu_s,gpu_s,max_relative_difference,renderer\n");
  std::printf("cluster-sums,%u,%u,%u,%.6f,%.6f,%.3g,\"%s\"\n", n, d, k, cpu_seconds, gpu_seconds,
              worst, context.renderer().c_str());
  return 0;
}

// Best of `repeats` runs of `run()` (false: failed), in wall and process CPU seconds.
template <typename Run>
std::pair<double, double> BestWallAndCpu(int repeats, Run&& run) {
  double wall = std::numeric_limits<double>::infinity(), cpu = wall;
  for (int r = 0; r < repeats; ++r) {
    const double cpu_before = ProcessCpuSeconds();
    Stopwatch watch;
    if (!run()) return {-1, -1};
    wall = std::min(wall, watch.Seconds());
    cpu = std::min(cpu, ProcessCpuSeconds() - cpu_before);
  }
  return {wall, cpu};
}

int RunGrowth(gpu::GlContext& context, Args& args, bool header) {
  const uint32_t k = args.Get<uint32_t>("k", 1000);
  const int repeats = args.Get<int>("repeats", 3);
  const uint32_t bb_iterations = args.Get<uint32_t>("bb-iterations", 200);
  const int threads = args.Get<int>("threads", 0);
  const std::string path = args.Positional(1);
  if (!args.Done()) return 2;
  const PreparedMesh mesh = PrepareOrDie(path);
  const MeshProblem problem{&mesh.mesh, &mesh.adjacency, &mesh.measures, {}};  // CVD
  const std::vector<FaceId> seeds = ValueOrDie(SpreadSeeds(problem, k));
  std::vector<uint32_t> seed_faces;
  seed_faces.reserve(seeds.size());
  for (FaceId f : seeds) seed_faces.push_back(f.value());
  // GPU: the first run compiles the program, not timed.
  absl::StatusOr<gpu::SeedGrowthGpuResult> gpu =
      GrowSeedsInRoundsGpu(context, mesh.adjacency, seed_faces);
  if (!gpu.ok()) Die("growth on the GPU", gpu.status());
  const auto [gpu_wall, gpu_cpu] = BestWallAndCpu(repeats, [&] {
    gpu = GrowSeedsInRoundsGpu(context, mesh.adjacency, seed_faces);
    return gpu.ok();
  });
  if (!gpu.ok()) Die("growth on the GPU", gpu.status());
  auto grow = [&](SeedOptions::Growth growth, std::vector<ClusterId>& labels) {
    return BestWallAndCpu(repeats, [&] {
      absl::StatusOr<std::vector<ClusterId>> grown =
          GrowClustersFromSeeds(problem, seeds, growth, nullptr);
      if (!grown.ok()) Die("growth on the CPU", grown.status());
      labels = *std::move(grown);
      return true;
    });
  };
  std::vector<ClusterId> rounds, flood;
  const auto [rounds_wall, rounds_cpu] = grow(SeedOptions::Growth::kRounds, rounds);
  const auto [flood_wall, flood_cpu] = grow(SeedOptions::Growth::kEnergyOrdered, flood);
  bool identical = gpu->labels.size() == rounds.size();
  for (size_t f = 0; identical && f < rounds.size(); ++f) {
    identical = gpu->labels[f] == rounds[f].value();
  }
  BoundaryBasedOptions options;
  options.threads = threads;
  options.max_iterations = bb_iterations;
  const OptimizeResult bb_rounds = ValueOrDie(OptimizeBoundaryBased(problem, rounds, options));
  const OptimizeResult bb_flood = ValueOrDie(OptimizeBoundaryBased(problem, flood, options));
  if (header) {
    std::printf(
        "stage,input,faces,k,rounds,gpu_s,gpu_cpu_s,cpu_rounds_s,cpu_rounds_cpu_s,cpu_flood_s,"
        "cpu_flood_cpu_s,identical,energy_rounds,energy_flood,bb_threads,bb_rounds_sweeps,"
        "bb_rounds_energy,bb_flood_sweeps,bb_flood_energy,renderer\n");
  }
  std::printf(
      "growth,%s,%zu,%u,%u,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%s,%.9g,%.9g,%d,%u,%.9g,%u,%.9g,\"%s\"\n",
      BaseName(path).c_str(), mesh.mesh.num_faces(), k, gpu->rounds, gpu_wall, gpu_cpu, rounds_wall,
      rounds_cpu, flood_wall, flood_cpu, identical ? "yes" : "NO", bb_rounds.initial_energy,
      bb_flood.initial_energy, threads, bb_rounds.iterations, bb_rounds.energy, bb_flood.iterations,
      bb_flood.energy, context.renderer().c_str());
  return identical ? 0 : 1;
}

int Main(int argc, char** argv) {
  Args args(argc, argv, kUsage);
  const bool header = args.Flag("header");
  const std::string mode = args.Positional(0);
  absl::StatusOr<std::unique_ptr<gpu::GlContext>> context = gpu::GlContext::Create();
  if (!context.ok()) Die("GL context", context.status());
  if (mode == "bb") return RunBb(**context, args, header);
  if (mode == "sums") return RunSums(**context, args, header);
  if (mode == "growth") return RunGrowth(**context, args, header);
  if (mode == "lnkmeans" || mode == "kmeans") {
    return RunPoints(**context, args, header, mode == "lnkmeans");
  }
  args.Done();
  std::fprintf(stderr, "%s\n", kUsage);
  return 2;
}

}  // namespace
}  // namespace mlclust::bench

int main(int argc, char** argv) { return mlclust::bench::Main(argc, argv); }
